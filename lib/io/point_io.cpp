// Point cloud reading (PLY in any encoding, XYZ text) and writing (binary little-endian PLY with
// float x y z nx ny nz, the layout of the shared test clouds).
#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <string>
#include <vector>

#include "byte_reader.hpp"
#include "duplexfit/error.hpp"
#include "duplexfit/io.hpp"
#include "ply.hpp"

namespace duplexfit {

namespace {

const char* const kNormalsHelp =
    "duplexfit needs oriented normals: run 'duplexfit normals IN -o OUT' or 'duplexfit fit --estimate-normals' "
    "to estimate and orient them";

/// Growing row-major storage for positions and normals before the PointSet is built.
struct PointBuffer {
  std::vector<double> positions, normals;
  void reserve(std::uint64_t n) {
    positions.reserve(static_cast<std::size_t>(3 * n));
    normals.reserve(static_cast<std::size_t>(3 * n));
  }
  PointSet toPointSet() const {
    const auto n = static_cast<Eigen::Index>(positions.size() / 3);
    Points p(n, 3), q(n, 3);
    if (n > 0) {
      std::copy(positions.begin(), positions.end(), p.data());
      std::copy(normals.begin(), normals.end(), q.data());
    }
    return PointSet(std::move(p), std::move(q));
  }
};

std::string describeValues(const double* v) {
  return "(" + std::to_string(v[0]) + ", " + std::to_string(v[1]) + ", " + std::to_string(v[2]) +
         ")";
}

std::string joinNames(const std::vector<std::string>& names) {
  std::string out;
  for (const std::string& n : names) out += (out.empty() ? "" : " ") + n;
  return out.empty() ? "(none)" : out;
}

// Rows [first, first + count) of the vertex element (count < 0: to the end).
PointCloudFile readPly(const std::string& path, const PointReadOptions& options, std::int64_t first = 0,
                       std::int64_t count = -1) {
  io::PlyReader ply(path);
  PointCloudFile result;
  PointReadReport& report = result.report;
  report.format = PointFormat::Ply;
  report.encoding = ply.encoding();
  report.comments = ply.comments();

  const int vertexIndex = ply.findElement("vertex");
  if (vertexIndex < 0) ply.fail("the PLY header declares no 'vertex' element");
  const io::PlyElement& vertex = ply.elements()[static_cast<std::size_t>(vertexIndex)];
  for (const io::PlyProperty& p : vertex.properties) report.properties.push_back(p.name);
  const std::string names = joinNames(report.properties);

  auto scalar = [&](const char* name) {
    const int i = vertex.find(name);
    if (i >= 0 && vertex.properties[static_cast<std::size_t>(i)].list) {
      ply.fail(std::string("vertex property '") + name + "' is a list, expected a scalar");
    }
    return i;
  };
  int columns[6];
  for (int k = 0; k < 3; ++k) {
    const char* name = k == 0 ? "x" : k == 1 ? "y" : "z";
    columns[k] = scalar(name);
    if (columns[k] < 0) {
      ply.fail(std::string("the vertex element has no property '") + name +
               "' (vertex properties: " + names + ")");
    }
  }
  const char* const shortNames[3] = {"nx", "ny", "nz"};
  const char* const longNames[3] = {"normal_x", "normal_y", "normal_z"};
  int found = 0;
  for (const auto* set : {shortNames, longNames}) {
    int here = 0;
    for (int k = 0; k < 3; ++k) here += scalar(set[k]) >= 0 ? 1 : 0;
    if (here == 3) {
      for (int k = 0; k < 3; ++k) columns[3 + k] = scalar(set[k]);
      found = 3;
      break;
    }
    if (here > 0) {
      ply.fail(std::string("the vertex element has only some of the normal properties ") + set[0] +
               " " + set[1] + " " + set[2] + " (vertex properties: " + names + ")");
    }
  }
  report.normals = found == 3;
  if (!report.normals && options.requireNormals) {
    const std::string what = "no normals: the vertex element has no nx ny nz (or normal_x normal_y "
                             "normal_z) properties (vertex properties: " + names + "); ";
    ply.fail(what + kNormalsHelp);
  }

  if (first < 0 || first > vertex.count || (count >= 0 && count > vertex.count - first)) {
    ply.fail("vertex rows " + std::to_string(first) + " .. " + std::to_string(first + std::max<std::int64_t>(count, 0)) +
             " requested, but the vertex element has " + std::to_string(vertex.count) + " rows");
  }
  const std::int64_t rows = count < 0 ? vertex.count - first : count;
  ply.beginElement(static_cast<std::size_t>(vertexIndex));
  ply.skipElementRows(first);
  // Reserve no more than the bytes left could hold (every value takes at least one byte).
  PointBuffer buffer;
  const std::uint64_t minRow = std::max<std::uint64_t>(1, vertex.properties.size());
  buffer.reserve(std::min(static_cast<std::uint64_t>(rows), ply.remainingBytes() / minRow));
  std::vector<double> values, unusedList;
  for (std::int64_t i = 0; i < rows; ++i) {
    ply.readRow(values, -1, unusedList);
    double row[6] = {0, 0, 0, 0, 0, 0};
    for (int k = 0; k < (report.normals ? 6 : 3); ++k) {
      row[k] = values[static_cast<std::size_t>(columns[k])];
    }
    if (!std::isfinite(row[0]) || !std::isfinite(row[1]) || !std::isfinite(row[2])) {
      ply.fail("non-finite coordinates " + describeValues(row) + " at " + ply.where());
    }
    if (!std::isfinite(row[3]) || !std::isfinite(row[4]) || !std::isfinite(row[5])) {
      ply.fail("non-finite normal " + describeValues(row + 3) + " at " + ply.where());
    }
    buffer.positions.insert(buffer.positions.end(), row, row + 3);
    buffer.normals.insert(buffer.normals.end(), row + 3, row + 6);
  }
  result.points = buffer.toPointSet();
  report.points = result.points.size();
  return result;
}

PointCloudFile readXyz(const std::string& path, const PointReadOptions& options) {
  io::ByteReader reader(path);
  PointCloudFile result;
  PointReadReport& report = result.report;
  report.format = PointFormat::Xyz;
  PointBuffer buffer;
  std::string line;
  std::vector<std::string_view> tokens;
  std::size_t columns = 0;  // fixed by the first data line: 6, or 3 without normals
  bool skippedCount = false;
  for (;;) {
    const auto status = reader.readLine(line, std::size_t{1} << 16);
    if (status == io::ByteReader::LineStatus::EndOfFile) break;
    const std::string at = " at line " + std::to_string(reader.line() + 1);
    if (status == io::ByteReader::LineStatus::TooLong) {
      reader.fail("line longer than 64 KiB" + at + " (not a text point file?)");
    }
    const std::string here = " at line " + std::to_string(reader.line());
    // '#' starts a comment; commas (CSV-like exports) separate values like blanks.
    line.erase(std::min(line.find('#'), line.size()));
    std::replace(line.begin(), line.end(), ',', ' ');
    io::splitWhitespace(line, tokens);
    if (tokens.empty()) continue;
    std::int64_t count = 0;
    if (columns == 0 && !skippedCount && tokens.size() == 1 && io::parseCount(tokens[0], count)) {
      skippedCount = true;  // a point count before the data (Leica .pts style)
      continue;
    }
    if (columns == 0) {
      if (tokens.size() == 3 && options.requireNormals) {
        reader.fail("no normals: line " + std::to_string(reader.line()) +
                    " has 3 values (x y z), expected 6 (x y z nx ny nz); " + kNormalsHelp);
      }
      if (tokens.size() != 6 && tokens.size() != 3) {
        reader.fail("expected 6 values (x y z nx ny nz) per line, found " +
                    std::to_string(tokens.size()) + here);
      }
      columns = tokens.size();
    }
    if (tokens.size() != columns) {
      reader.fail("expected " + std::to_string(columns) + " values per line (as on the first " +
                  "line), found " + std::to_string(tokens.size()) + here);
    }
    double row[6] = {0, 0, 0, 0, 0, 0};
    for (std::size_t k = 0; k < columns; ++k) {
      if (!io::parseNumber(tokens[k], row[k])) {
        reader.fail("non-numeric value " + io::quoted(tokens[k]) + here);
      }
    }
    if (!std::isfinite(row[0]) || !std::isfinite(row[1]) || !std::isfinite(row[2])) {
      reader.fail("non-finite coordinates " + describeValues(row) + here + " (point " +
                  std::to_string(buffer.positions.size() / 3) + ")");
    }
    if (!std::isfinite(row[3]) || !std::isfinite(row[4]) || !std::isfinite(row[5])) {
      reader.fail("non-finite normal " + describeValues(row + 3) + here + " (point " +
                  std::to_string(buffer.positions.size() / 3) + ")");
    }
    buffer.positions.insert(buffer.positions.end(), row, row + 3);
    buffer.normals.insert(buffer.normals.end(), row + 3, row + 6);
  }
  if (columns == 0) reader.fail("no points (only blank or comment lines)");
  report.normals = columns == 6;
  report.properties = {"x", "y", "z"};
  if (report.normals) report.properties.insert(report.properties.end(), {"nx", "ny", "nz"});
  result.points = buffer.toPointSet();
  report.points = result.points.size();
  return result;
}

}  // namespace

const char* pointFormatName(PointFormat format) noexcept {
  switch (format) {
    case PointFormat::Ply:
      return "ply";
    case PointFormat::Xyz:
      return "xyz";
    case PointFormat::Auto:
      break;
  }
  return "auto";
}

std::int64_t plyVertexCount(const std::string& path) {
  io::PlyReader ply(path);
  const int vertexIndex = ply.findElement("vertex");
  if (vertexIndex < 0) ply.fail("the PLY header declares no 'vertex' element");
  return ply.elements()[static_cast<std::size_t>(vertexIndex)].count;
}

PointCloudFile readPlyVertexRows(const std::string& path, std::int64_t first, std::int64_t count,
                                 const PointReadOptions& options) {
  if (count < 0) throw InvalidArgument(path + ": a negative row count (" + std::to_string(count) + ")");
  return readPly(path, options, first, count);
}

const char* plyEncodingName(PlyEncoding encoding) noexcept {
  switch (encoding) {
    case PlyEncoding::BinaryLittleEndian:
      return "binary_little_endian";
    case PlyEncoding::BinaryBigEndian:
      return "binary_big_endian";
    case PlyEncoding::Ascii:
      break;
  }
  return "ascii";
}

PointCloudFile readPointCloudWithReport(const std::string& path, const PointReadOptions& options) {
  PointFormat format = options.format;
  if (format == PointFormat::Auto) {
    const std::string ext = io::lowerExtension(path);
    if (ext == ".ply") {
      format = PointFormat::Ply;
    } else if (ext == ".xyz" || ext == ".txt" || ext == ".pts") {
      format = PointFormat::Xyz;
    } else {
      throw InvalidArgument(path + ": unknown point cloud extension '" + ext +
                            "' (expected .ply, .xyz, .txt or .pts, or give the format explicitly)");
    }
  }
  return format == PointFormat::Ply ? readPly(path, options) : readXyz(path, options);
}

PointSet readPointCloud(const std::string& path, const PointReadOptions& options) {
  return readPointCloudWithReport(path, options).points;
}

void writePointCloud(const std::string& path, const PointSet& points) {
  const std::size_t n = points.size();
  const Points& p = points.positions();
  const Points& q = points.normals();
  const double limit = static_cast<double>(std::numeric_limits<float>::max());
  for (Eigen::Index i = 0; i < p.rows(); ++i) {
    if (p.row(i).cwiseAbs().maxCoeff() > limit) {
      throw InvalidArgument("writePointCloud: point " + std::to_string(i) +
                            " does not fit in float (" + path + ")");
    }
  }
  const std::string header =
      "ply\nformat binary_little_endian 1.0\ncomment written by duplexfit\n"
      "element vertex " +
      std::to_string(n) +
      "\nproperty float x\nproperty float y\nproperty float z\n"
      "property float nx\nproperty float ny\nproperty float nz\n"
      "end_header\n";
  AtomicFile file(path);
  file.write(header);
  const bool swap = !io::hostIsLittleEndian();
  std::vector<unsigned char> block;
  block.reserve(24 * 4096);
  for (Eigen::Index i = 0; i < p.rows(); ++i) {
    const float row[6] = {static_cast<float>(p(i, 0)), static_cast<float>(p(i, 1)),
                          static_cast<float>(p(i, 2)), static_cast<float>(q(i, 0)),
                          static_cast<float>(q(i, 1)), static_cast<float>(q(i, 2))};
    unsigned char bytes[24];
    std::memcpy(bytes, row, sizeof bytes);
    if (swap) {
      for (int k = 0; k < 6; ++k) std::reverse(bytes + 4 * k, bytes + 4 * k + 4);
    }
    block.insert(block.end(), bytes, bytes + 24);
    if (block.size() >= 24 * 4096) {
      file.write(block.data(), block.size());
      block.clear();
    }
  }
  file.write(block.data(), block.size());
  file.commit();
}

}  // namespace duplexfit
