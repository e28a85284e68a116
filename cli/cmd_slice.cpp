// `duplexfit slice`: a saved field in, the layers of a 3D print out: slices.cli (Common Layer Interface,
// ASCII), slices.svg, slices.json and optional PNG masks. Outputs are staged in a temporary folder inside
// the output folder and moved into place only when everything succeeded.
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iomanip>
#include <iostream>
#include <limits>
#include <sstream>

#include <unistd.h>

#include <nlohmann/json.hpp>

#include "commands.hpp"
#include "options.hpp"
#include "timer.hpp"
#include "duplexfit/atomic_file.hpp"
#include "duplexfit/error.hpp"
#include "duplexfit/field.hpp"
#include "duplexfit/image.hpp"
#include "duplexfit/slice.hpp"

namespace duplexfit::cli {

const char* const kSliceHelp = R"(  slice FIELD        cut a saved field into print layers: contours of {f >= 0} (or of the shell between
                     the surface and its offset) as closed, oriented, nested loops; adaptive layer
                     thickness from the cusp height (docs/method.md §10) or uniform layers
      --cusp T         cusp height tau (adaptive slicing; required unless --layer)
      --min-layer A    thinnest layer (default tau/4)     --max-layer B   thickest layer (default 5 tau)
      --layer H        uniform layers of thickness H instead of adaptive ones
      --grid G         plane sampling step (default: largest side of the box / 200)
      --mode zero|shell  the solid (default) or the shell between f = 0 and f = delta
      --offset-index K which of the field's offsets bounds the shell (default 0, the first)
      --cusp-rule geometric|paper  convex/concave by the centre of curvature (default; keeps every
                       cusp within tau) or by the sign of the curvature alone (the paper's counts)
      --axis x|y|z     build direction (default z); plane axes (y,z), (z,x), (x,y)
      -o DIR           output folder: slices.cli, slices.svg, slices.json (default: current folder)
      --units U        millimetres per CLI unit (default 1: field units are mm)
      --svg-per-layer  svg/layer_00001.svg, ... instead of one slices.svg
      --png-xy PX      also masks/layer_00001.png, ...: white inside, pixel size PX
      --device SPEC, --precision float|double, --refine-steps N, --quiet, --json (summary on stdout)
)";

namespace {

namespace fs = std::filesystem;

std::string layerName(std::size_t i, const char* ext) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "layer_%05zu.%s", i + 1, ext);
  return buf;
}

}  // namespace

int cmdSlice(int argc, char** argv) {
  const Timer start;
  CLI::App app("cut a saved field into print layers", "slice");
  bool quiet = false, json = false, svgPerLayer = false, svg = false;
  DeviceOptions deviceOptions;
  SliceOptions options;
  std::string input, mode = "zero", rule = "geometric", axis = "z", output = ".";
  // Numbers: NaN marks "not given".
  const double nan = std::numeric_limits<double>::quiet_NaN();
  double units = 1.0, pixel = 0.0, cusp = nan, minLayer = nan, maxLayer = nan, layer = nan, grid = nan;
  app.add_option("FIELD", input, "a field file (.dpxf)");
  app.add_option("-o,--output", output, "output folder (default: current folder)")->type_name("DIR");
  addNumber(app, "cusp", cusp, "cusp height of the adaptive layers");
  addNumber(app, "min-layer", minLayer, "thinnest adaptive layer");
  addNumber(app, "max-layer", maxLayer, "thickest adaptive layer");
  addNumber(app, "layer", layer, "uniform layer thickness instead of --cusp");
  addNumber(app, "grid", grid, "contouring grid spacing");
  app.add_option("--mode", mode, "zero (the solid, default) or shell");
  app.add_option("--cusp-rule", rule, "the cusp-height rule (default geometric)");
  app.add_option("--axis", axis, "build direction x, y or z (default z)");
  addInteger(app, "offset-index", options.offsetIndex, "the offset of --mode shell (default 0)");
  addInteger(app, "refine-steps", options.refineSteps, "contour refinement steps (0..64)");
  addNumber(app, "units", units, "output units per input unit (default 1)");
  addNumber(app, "png-xy", pixel, "PNG masks with this pixel size");
  app.add_flag("--svg", svg, "slices.svg (always written; accepted for clarity)");
  app.add_flag("--svg-per-layer", svgPerLayer, "one SVG per layer as well");
  addDeviceOptions(app, deviceOptions);
  addQuiet(app, quiet);
  addJson(app, json);
  if (parse(app, argc, argv)) return 0;
  auto log = [quiet](const std::string& s) {
    if (!quiet) std::cerr << s << std::endl;
  };
  options.mode = parseSliceMode(mode);
  options.rule = parseCuspRule(rule);
  options.axis = parseAxis(axis);
  options.precision = deviceOptions.precision;
  const bool pngGiven = pixel != 0.0;
  const fs::path outDir = output;
  const std::string deviceSpec = deviceOptions.spec;
  if (input.empty()) throw UsageError("slice needs a field file: duplexfit slice FIELD --cusp T -o DIR");
  if (std::isnan(layer) && std::isnan(cusp)) throw UsageError("slice needs --cusp T (adaptive) or --layer H (uniform)");
  if (!std::isnan(cusp) && !(cusp > 0.0)) throw UsageError("--cusp must be > 0 (got " + std::to_string(cusp) + ")");
  if (!std::isnan(layer) && !(layer > 0.0)) throw UsageError("--layer must be > 0 (got " + std::to_string(layer) + ")");
  if (!std::isnan(minLayer) && !(minLayer > 0.0)) throw UsageError("--min-layer must be > 0");
  if (!std::isnan(maxLayer) && !(maxLayer > 0.0)) throw UsageError("--max-layer must be > 0");
  if (!std::isnan(minLayer) && !std::isnan(maxLayer) && minLayer > maxLayer) {
    throw UsageError("--min-layer " + std::to_string(minLayer) + " exceeds --max-layer " + std::to_string(maxLayer));
  }
  if (!std::isnan(grid) && !(grid > 0.0)) throw UsageError("--grid must be > 0 (got " + std::to_string(grid) + ")");
  if (!(units > 0.0)) throw UsageError("--units must be > 0");
  if (pngGiven && !(pixel > 0.0)) throw UsageError("--png-xy must be > 0");
  if (options.refineSteps < 0 || options.refineSteps > 64) throw UsageError("--refine-steps must be in 0..64");
  options.cusp = std::isnan(cusp) ? 0.0 : cusp;
  options.layer = std::isnan(layer) ? 0.0 : layer;
  options.minLayer = std::isnan(minLayer) ? 0.0 : minLayer;
  options.maxLayer = std::isnan(maxLayer) ? 0.0 : maxLayer;
  options.grid = std::isnan(grid) ? 0.0 : grid;

  const ImplicitField field = ImplicitField::load(input);
  const Device device = deviceSpec.empty() ? Device::openDefault() : Device::open(deviceSpec);
  log("device: " + device.description());
  const Slicer slicer(device, field, options);  // validates the options against the field
  const SliceOptions& used = slicer.options();
  if (pngGiven) {
    // Fail before slicing when the masks cannot be made.
    const Eigen::Vector3d size = slicer.bounds().sizes();
    const double w = (size[(used.axis + 1) % 3] + 4 * used.grid) / pixel;
    const double h = (size[(used.axis + 2) % 3] + 4 * used.grid) / pixel;
    if (w > 65536.0 || h > 65536.0) throw UsageError("--png-xy " + std::to_string(pixel) + " gives masks larger than 65536 pixels a side");
  }
  StagedFolder staging(outDir);  // fails early, before slicing, if the folder is unusable
  log(std::string("slicing ") + input + " along " + "xyz"[used.axis] + ", mode " + sliceModeName(used.mode) +
      (used.layer > 0.0 ? ", uniform layers " + std::to_string(used.layer)
                        : ", cusp " + std::to_string(used.cusp) + ", layers " + std::to_string(used.minLayer) + " to " +
                              std::to_string(used.maxLayer)) +
      ", grid " + std::to_string(used.grid) + ", heights " + std::to_string(used.start) + " to " +
      std::to_string(used.end));

  Timer t;
  const SliceResult result = slicer.run([&](const SliceProgress& p) {
    if (!quiet) {
      std::cerr << "  layer " << p.layer << "  height " << std::setprecision(6) << p.height << "  thickness "
                << p.thickness << "  loops " << p.loops << "  (" << std::setprecision(3) << 100.0 * p.fraction
                << "%)\n";
    }
    return true;
  });
  const double sliceSeconds = t.seconds();
  std::size_t touching = 0;
  for (const SliceLayer& l : result.layers) touching += l.touchesBoundary ? 1 : 0;
  if (touching > 0) {
    log("warning: in " + std::to_string(touching) + " layer(s) a level set reached the padded grid border; loops were closed there");
  }

  t.restart();
  writeCli(staging.path("slices.cli"), result, units);
  if (svgPerLayer) {
    const std::string dir = staging.path("svg", true);
    for (std::size_t i = 0; i < result.layers.size(); ++i) {
      writeSliceSvg((fs::path(dir) / layerName(i, "svg")).string(), result, static_cast<int>(i));
    }
  } else {
    writeSliceSvg(staging.path("slices.svg"), result);
  }
  std::vector<double> maskArea;
  if (pngGiven) {
    const std::string dir = staging.path("masks", true);
    const Eigen::AlignedBox2d box = planeBox(result);
    for (std::size_t i = 0; i < result.layers.size(); ++i) {
      const Image img = rasterizeLayer(result.layers[i], box, pixel);
      std::size_t white = 0;
      for (std::uint8_t p : img.pixels) white += p != 0 ? 1 : 0;
      maskArea.push_back(static_cast<double>(white) * pixel * pixel);
      writePng((fs::path(dir) / layerName(i, "png")).string(), img);
    }
  }
  const double writeSeconds = t.seconds();

  // Summary statistics.
  double tMin = std::numeric_limits<double>::infinity(), tMax = 0.0, tSum = 0.0;
  std::size_t loops = 0;
  for (const SliceLayer& l : result.layers) {
    tMin = std::min(tMin, l.thickness);
    tMax = std::max(tMax, l.thickness);
    tSum += l.thickness;
    loops += l.loops.size();
  }
  const std::size_t n = result.layers.size();
  const double tMean = n > 0 ? tSum / static_cast<double>(n) : 0.0;
  if (n == 0) tMin = 0.0;

  using Json = nlohmann::ordered_json;
  Json heights = Json::array(), areas = Json::array(), loopsPerLayer = Json::array(), layers = Json::array();
  for (const SliceLayer& l : result.layers) {
    heights.push_back(l.height);
    areas.push_back(l.area);
    loopsPerLayer.push_back(l.loops.size());
  }
  for (std::size_t i = 0; i < n; ++i) {
    const SliceLayer& l = result.layers[i];
    std::size_t outer = 0;
    for (const SliceLoop& p : l.loops) outer += p.outer() ? 1 : 0;
    Json j{{"index", i + 1},
           {"height", l.height},
           {"thickness", l.thickness},
           {"raw_thickness", l.rawThickness},
           {"area", l.area},
           {"loops", l.loops.size()},
           {"outer_loops", outer},
           {"holes", l.loops.size() - outer},
           {"vertices", l.vertexCount()}};
    if (pngGiven) j["mask_area"] = maskArea[i];
    if (l.touchesBoundary) j["touches_border"] = true;
    layers.push_back(std::move(j));
  }
  const Json summary{
      {"input", input},
      {"device", device.info().spec},
      {"mode", sliceModeName(result.mode)},
      {"axis", std::string(1, "xyz"[result.axis])},
      {"adaptive", result.adaptive},
      {"cusp_rule", cuspRuleName(result.rule)},
      {"cusp", result.cusp},
      {"min_layer", result.minLayer},
      {"max_layer", result.maxLayer},
      {"uniform_layer", result.layer},
      {"grid", result.grid},
      {"units_mm", units},
      {"levels", result.levels},
      {"start", result.start},
      {"end", result.end},
      {"layer_count", n},
      {"thickness", {{"min", tMin}, {"mean", tMean}, {"max", tMax}}},
      {"loops", loops},
      {"vertices", result.vertices},
      {"samples", result.samples},
      {"refine_evaluations", result.refineEvaluations},
      {"layers_touching_border", touching},
      {"heights", std::move(heights)},
      {"areas", std::move(areas)},
      {"loops_per_layer", std::move(loopsPerLayer)},
      {"layers", std::move(layers)},
      {"seconds", {{"slice", sliceSeconds}, {"write", writeSeconds}, {"total", start.seconds()}}},
      {"layers_per_second", sliceSeconds > 0 ? static_cast<double>(n) / sliceSeconds : 0.0},
      {"vertices_per_second", sliceSeconds > 0 ? static_cast<double>(result.vertices) / sliceSeconds : 0.0}};
  const std::string js = summary.dump(2, ' ', false, Json::error_handler_t::replace) + "\n";
  {
    AtomicFile f(staging.path("slices.json"));
    f.write(js);
    f.commit();
  }
  staging.commit();

  if (json) {
    std::cout << js;
  } else {
    std::cout << std::setprecision(5) << "slice " << input << ": " << n << " layers (" << sliceModeName(result.mode)
              << ", " << (result.adaptive ? "adaptive" : "uniform") << "), thickness " << tMin << " to " << tMax
              << " (mean " << tMean << "), " << loops << " loops, " << result.vertices << " vertices, " << sliceSeconds
              << " s\n  " << (outDir / "slices.cli").string() << ", "
              << (outDir / (svgPerLayer ? "svg/" : "slices.svg")).string() << ", "
              << (outDir / "slices.json").string() << (pngGiven ? ", " + (outDir / "masks/").string() : "") << "\n";
  }
  return 0;
}

}  // namespace duplexfit::cli
