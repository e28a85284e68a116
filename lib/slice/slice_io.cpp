// Slice outputs: the Common Layer Interface (ASCII CLI 2.0: $$POLYLINE/id,dir,n,p1x,p1y,… with dir 0 =
// clockwise/internal, 1 = counter-clockwise/external, 2 = open), an SVG of the layers and raster masks.
#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <sstream>
#include <string>

#include "duplexfit/atomic_file.hpp"
#include "duplexfit/error.hpp"
#include "duplexfit/slice.hpp"

namespace duplexfit {

// Here rather than in slice.cpp: the writers below use it, and the CLI-file reader's fuzz target links
// this file without the slicer.
const char* sliceModeName(SliceMode mode) noexcept { return mode == SliceMode::Zero ? "zero" : "shell"; }

namespace {

void appendFixed(std::string& out, double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.7f", v == 0.0 ? 0.0 : v);  // no "-0.0000000"
  out += buf;
}

std::string trim(const std::string& s) {
  std::size_t b = 0, e = s.size();
  while (b < e && std::isspace(static_cast<unsigned char>(s[b]))) ++b;
  while (e > b && std::isspace(static_cast<unsigned char>(s[e - 1]))) --e;
  return s.substr(b, e - b);
}

}  // namespace

Eigen::AlignedBox2d planeBox(const SliceResult& result) {
  const int u = (result.axis + 1) % 3, v = (result.axis + 2) % 3;
  const Eigen::Vector2d m(2.0 * result.grid, 2.0 * result.grid);
  return {Eigen::Vector2d(result.bounds.min()[u], result.bounds.min()[v]) - m,
          Eigen::Vector2d(result.bounds.max()[u], result.bounds.max()[v]) + m};
}

void writeCli(const std::string& path, const SliceResult& result, double units, double resultUnits) {
  if (!(units > 0.0) || !std::isfinite(units)) {
    throw InvalidArgument("CLI units must be a positive number of millimetres, got " + std::to_string(units));
  }
  if (!(resultUnits > 0.0) || !std::isfinite(resultUnits)) {
    throw InvalidArgument("CLI: the result's units must be a positive number of millimetres, got " +
                          std::to_string(resultUnits));
  }
  const double k = resultUnits == units ? 1.0 : resultUnits / units;
  const int u = (result.axis + 1) % 3, v = (result.axis + 2) % 3;
  std::string out;
  out += "$$HEADERSTART\n$$ASCII\n$$UNITS/";
  appendFixed(out, units);
  out += "\n$$VERSION/200\n$$LABEL/1,duplexfit\n$$DIMENSION/";
  const Eigen::Vector3d lo = result.bounds.min(), hi = result.bounds.max();
  const double dims[6] = {lo[u], lo[v], lo[result.axis], hi[u], hi[v], hi[result.axis]};
  for (int i = 0; i < 6; ++i) {
    if (i) out += ',';
    appendFixed(out, dims[i] * k);
  }
  char count[32];
  std::snprintf(count, sizeof count, "%06zu", result.layers.size());
  out += "\n$$LAYERS/";
  out += count;
  out += "\n$$HEADEREND\n$$GEOMETRYSTART\n";
  AtomicFile file(path);
  for (const SliceLayer& layer : result.layers) {
    out += "$$LAYER/";  // CLI 2.0: the layer's upper boundary
    appendFixed(out, (layer.height + layer.thickness) * k);
    out += '\n';
    for (const SliceLoop& loop : layer.loops) {
      const Eigen::Index n = loop.points.rows();
      out += "$$POLYLINE/1,";
      out += loop.outer() ? '1' : '0';
      out += ',';
      out += std::to_string(n + 1);
      for (Eigen::Index i = 0; i <= n; ++i) {
        const Eigen::Index j = i % n;
        out += ',';
        appendFixed(out, loop.points(j, 0) * k);
        out += ',';
        appendFixed(out, loop.points(j, 1) * k);
      }
      out += '\n';
    }
    if (out.size() > (std::size_t{1} << 20)) {
      file.write(out);
      out.clear();
    }
  }
  out += "$$GEOMETRYEND\n";
  file.write(out);
  file.commit();
}

CliFile readCli(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw IoError(path + ": cannot open the CLI file");
  CliFile file;
  std::string raw;
  long lineNo = 0;
  enum { Before, Header, Geometry, Done } state = Before;
  auto fail = [&](const std::string& what) -> IoError {
    return IoError(path + ":" + std::to_string(lineNo) + ": " + what);
  };
  auto parseNumbers = [&](const std::string& text, const char* command) {
    std::vector<double> values;
    std::stringstream ss(text);
    std::string item;
    while (std::getline(ss, item, ',')) {
      item = trim(item);
      char* end = nullptr;
      const double d = std::strtod(item.c_str(), &end);
      if (item.empty() || end == item.c_str() || *end != '\0' || !std::isfinite(d)) {
        throw fail(std::string(command) + ": '" + item + "' is not a number");
      }
      values.push_back(d);
    }
    return values;
  };
  while (std::getline(in, raw)) {
    ++lineNo;
    // Comments run from "//" to the end of the line (or to a closing "//").
    std::string line = raw;
    const auto comment = line.find("//");
    if (comment != std::string::npos) line = line.substr(0, comment);
    line = trim(line);
    if (line.empty()) continue;
    if (state == Done) continue;
    if (state == Before && line.rfind("$$HEADERSTART", 0) != 0) throw fail("not a CLI file (no $$HEADERSTART)");
    if (line.rfind("$$", 0) != 0) throw fail("expected a $$ command, got '" + line.substr(0, 40) + "'");
    const auto slash = line.find('/');
    const std::string cmd = line.substr(0, slash);
    const std::string args = slash == std::string::npos ? std::string() : line.substr(slash + 1);
    if (state == Before) {
      if (cmd != "$$HEADERSTART") throw fail("not a CLI file (no $$HEADERSTART)");
      state = Header;
    } else if (state == Header) {
      if (cmd == "$$BINARY") throw fail("binary CLI files are not supported (only $$ASCII)");
      if (cmd == "$$UNITS") {
        const auto v = parseNumbers(args, "$$UNITS");
        if (v.size() != 1 || !(v[0] > 0.0)) throw fail("$$UNITS needs one positive number");
        file.units = v[0];
      } else if (cmd == "$$VERSION") {
        const auto v = parseNumbers(args, "$$VERSION");
        if (v.size() != 1 || std::abs(v[0]) > 1e9) throw fail("$$VERSION needs one number");
        file.version = static_cast<int>(v[0]);
      } else if (cmd == "$$LAYERS") {
        const auto v = parseNumbers(args, "$$LAYERS");
        if (v.size() != 1 || v[0] < 0 || v[0] > 1e12 || v[0] != std::floor(v[0])) throw fail("$$LAYERS needs one count");
        file.declaredLayers = static_cast<long>(v[0]);
      } else if (cmd == "$$HEADEREND") {
        state = Geometry;
      }
      // $$ASCII, $$LABEL, $$DATE, $$DIMENSION, $$USERDATA and others: nothing to keep.
    } else if (state == Geometry) {
      if (cmd == "$$GEOMETRYSTART") continue;
      if (cmd == "$$GEOMETRYEND") {
        state = Done;
        continue;
      }
      if (cmd == "$$LAYER") {
        const auto v = parseNumbers(args, "$$LAYER");
        if (v.size() != 1) throw fail("$$LAYER needs one height");
        CliLayer layer;
        layer.height = v[0] * file.units;
        if (!file.layers.empty() && layer.height < file.layers.back().height) {
          throw fail("$$LAYER heights must not decrease");
        }
        layer.bottom = file.layers.empty() ? 0.0 : file.layers.back().height;
        file.layers.push_back(std::move(layer));
      } else if (cmd == "$$POLYLINE") {
        if (file.layers.empty()) throw fail("$$POLYLINE before the first $$LAYER");
        const auto v = parseNumbers(args, "$$POLYLINE");
        if (v.size() < 3) throw fail("$$POLYLINE needs id, dir and n");
        const double n = v[2];
        if (n < 0 || n > 1e12 || n != std::floor(n) || v.size() != 3 + 2 * static_cast<std::size_t>(n)) {
          char msg[160];
          std::snprintf(msg, sizeof msg, "$$POLYLINE declares %g points but has %zu coordinates", n, v.size() - 3);
          throw fail(msg);
        }
        if (v[1] != 0 && v[1] != 1 && v[1] != 2) throw fail("$$POLYLINE dir must be 0, 1 or 2");
        if (std::abs(v[0]) > 2e9 || v[0] != std::floor(v[0])) throw fail("$$POLYLINE id must be an integer");
        CliPolyline p;
        p.id = static_cast<int>(v[0]);
        p.dir = static_cast<int>(v[1]);
        auto count = static_cast<Eigen::Index>(n);
        p.closed = p.dir != 2 && count >= 2 && v[3] == v[3 + 2 * (count - 1)] && v[4] == v[4 + 2 * (count - 1)];
        if (p.closed) --count;
        p.points.resize(count, 2);
        for (Eigen::Index i = 0; i < count; ++i) {
          p.points(i, 0) = v[3 + 2 * static_cast<std::size_t>(i)] * file.units;
          p.points(i, 1) = v[4 + 2 * static_cast<std::size_t>(i)] * file.units;
        }
        file.layers.back().polylines.push_back(std::move(p));
      } else if (cmd == "$$HATCHES") {
        const auto v = parseNumbers(args, "$$HATCHES");
        if (v.size() < 2 || v[1] < 0 || v[1] > 1e12 || v.size() != 2 + 4 * static_cast<std::size_t>(v[1])) {
          throw fail("$$HATCHES count does not match its coordinates");
        }
      } else {
        throw fail("unknown geometry command " + cmd);
      }
    }
  }
  if (state == Before) throw IoError(path + ": empty file, not a CLI file");
  if (state == Header) throw IoError(path + ": the header never ends ($$HEADEREND missing)");
  if (state == Geometry) throw IoError(path + ": truncated ($$GEOMETRYEND missing)");
  if (file.declaredLayers >= 0 && static_cast<std::size_t>(file.declaredLayers) != file.layers.size()) {
    throw IoError(path + ": $$LAYERS declares " + std::to_string(file.declaredLayers) + " layers but the file has " +
                  std::to_string(file.layers.size()));
  }
  return file;
}

void writeSliceSvg(const std::string& path, const SliceResult& result, int layerIndex) {
  if (layerIndex >= static_cast<int>(result.layers.size())) {
    throw InvalidArgument("SVG: layer " + std::to_string(layerIndex) + " does not exist (" +
                          std::to_string(result.layers.size()) + " layers)");
  }
  const Eigen::AlignedBox2d box = planeBox(result);
  const Eigen::Vector2d size = box.sizes();
  std::string out;
  char buf[256];
  std::snprintf(buf, sizeof buf,
                "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n"
                "<svg xmlns=\"http://www.w3.org/2000/svg\" viewBox=\"%.7f %.7f %.7f %.7f\" width=\"800\" "
                "height=\"%.0f\">\n",
                box.min().x(), -box.max().y(), size.x(), size.y(), 800.0 * size.y() / std::max(size.x(), 1e-300));
  out += buf;
  std::snprintf(buf, sizeof buf, "<!-- duplexfit slices: mode %s, axis %c, %zu layers; v points up -->\n",
                sliceModeName(result.mode), "xyz"[result.axis], result.layers.size());
  out += buf;
  const double stroke = std::max(size.x(), size.y()) / 800.0;
  for (std::size_t li = 0; li < result.layers.size(); ++li) {
    if (layerIndex >= 0 && li != static_cast<std::size_t>(layerIndex)) continue;
    const SliceLayer& layer = result.layers[li];
    std::snprintf(buf, sizeof buf,
                  "<g id=\"layer_%05zu\" data-height=\"%.7f\" data-thickness=\"%.7f\" fill=\"#1f77b4\" "
                  "fill-opacity=\"0.15\" stroke=\"#1f77b4\" stroke-width=\"%.7f\">\n",
                  li + 1, layer.height, layer.thickness, stroke);
    out += buf;
    if (!layer.loops.empty()) {
      out += "<path fill-rule=\"evenodd\" d=\"";
      for (const SliceLoop& loop : layer.loops) {
        for (Eigen::Index i = 0; i < loop.points.rows(); ++i) {
          std::snprintf(buf, sizeof buf, "%c%.6f %.6f ", i == 0 ? 'M' : 'L', loop.points(i, 0), -loop.points(i, 1));
          out += buf;
        }
        out += "Z ";
      }
      out += "\"/>\n";
    }
    out += "</g>\n";
  }
  out += "</svg>\n";
  AtomicFile file(path);
  file.write(out);
  file.commit();
}

Eigen::Vector2d maskPixels(const Eigen::AlignedBox2d& area, double pixel) {
  const Eigen::Vector2d size = area.sizes() / pixel;
  return {std::ceil(size.x() - 1e-6), std::ceil(size.y() - 1e-6)};
}

Image rasterizeLayer(const SliceLayer& layer, const Eigen::AlignedBox2d& area, double pixel) {
  if (!(pixel > 0.0) || !std::isfinite(pixel)) {
    throw InvalidArgument("mask pixel size must be positive, got " + std::to_string(pixel));
  }
  const Eigen::Vector2d count = maskPixels(area, pixel);
  const double w = count.x(), h = count.y();
  if (!(w >= 1.0 && h >= 1.0) || w > 65536.0 || h > 65536.0) {
    throw InvalidArgument("mask pixel size " + std::to_string(pixel) + " gives a " + std::to_string(w) + " x " +
                          std::to_string(h) + " image (1 to 65536 pixels a side)");
  }
  Image img(static_cast<int>(w), static_cast<int>(h), 1, 0);
  // Edges with their v range, for a scanline even-odd fill at pixel centres.
  struct Edge {
    double u0, v0, u1, v1;
  };
  std::vector<Edge> edges;
  for (const SliceLoop& loop : layer.loops) {
    const Eigen::Index n = loop.points.rows();
    for (Eigen::Index i = 0, j = n - 1; i < n; j = i++) {
      edges.push_back({loop.points(j, 0), loop.points(j, 1), loop.points(i, 0), loop.points(i, 1)});
    }
  }
  std::vector<double> xs;
  for (int row = 0; row < img.height; ++row) {
    const double y = area.max().y() - (row + 0.5) * pixel;
    xs.clear();
    for (const Edge& e : edges) {
      if ((e.v0 > y) != (e.v1 > y)) xs.push_back(e.u0 + (y - e.v0) * (e.u1 - e.u0) / (e.v1 - e.v0));
    }
    std::sort(xs.begin(), xs.end());
    for (std::size_t k = 0; k + 1 < xs.size(); k += 2) {
      // Pixels whose centre u = min + (c + 0.5)·pixel lies in [xs[k], xs[k+1]).
      const double c0 = std::ceil((xs[k] - area.min().x()) / pixel - 0.5);
      const double c1 = std::ceil((xs[k + 1] - area.min().x()) / pixel - 0.5) - 1.0;
      const int a = static_cast<int>(std::max(0.0, c0)), b = static_cast<int>(std::min(w - 1.0, c1));
      for (int c = a; c <= b; ++c) *img.at(c, row) = 255;
    }
  }
  return img;
}

}  // namespace duplexfit
