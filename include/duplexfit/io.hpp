// File input and output: oriented point clouds (PLY in all three encodings, XYZ text) and triangle
// meshes (PLY, Wavefront OBJ, STL). Writers go through AtomicFile; every reader error is an IoError
// whose message starts with the file name and says where (line, element index or byte offset).
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "duplexfit/atomic_file.hpp"
#include "duplexfit/mesh.hpp"
#include "duplexfit/point_set.hpp"

namespace duplexfit {

/// Point cloud file formats.
enum class PointFormat {
  Auto,  ///< from the extension: .ply → Ply; .xyz, .txt, .pts → Xyz
  Ply,   ///< PLY: ascii, binary_little_endian or binary_big_endian
  Xyz,   ///< text, one point a line: "x y z nx ny nz" (blanks or commas between values); '#' starts
         ///< a comment; blank lines allowed; a lone integer before the data (a count) is skipped
};

/// The body encoding of a PLY file.
enum class PlyEncoding { Ascii, BinaryLittleEndian, BinaryBigEndian };

/// "auto", "ply" or "xyz".
const char* pointFormatName(PointFormat format) noexcept;
/// "ascii", "binary_little_endian" or "binary_big_endian" (the PLY header spelling).
const char* plyEncodingName(PlyEncoding encoding) noexcept;

/// Options of readPointCloud.
struct PointReadOptions {
  /// Format of the file; Auto picks it from the extension (case-insensitive).
  PointFormat format = PointFormat::Auto;
  /// When true (the default) a file without normals is an IoError (fitting needs oriented normals).
  /// When false such a file reads with zero normals (e.g. reference points for measurements).
  bool requireNormals = true;
};

/// What readPointCloud found in the file.
struct PointReadReport {
  PointFormat format = PointFormat::Auto;     ///< Ply or Xyz
  PlyEncoding encoding = PlyEncoding::Ascii;  ///< PLY only
  std::size_t points = 0;                     ///< points read
  std::vector<std::string> properties;        ///< vertex properties in file order (PLY), or
                                              ///< the column names (XYZ)
  bool normals = false;                       ///< whether the file carried normals
  std::vector<std::string> comments;          ///< PLY "comment"/"obj_info" lines (text only)
};

/// A point cloud together with the report of reading it.
struct PointCloudFile {
  PointSet points;
  PointReadReport report;
};

/// Reads an oriented point cloud; normals are normalised (PointSet), never flipped.
/// PLY: vertex properties x, y, z and nx, ny, nz (or normal_x, normal_y, normal_z) of any PLY
/// scalar type; other vertex properties (lists too) and other elements are skipped.
/// @throws InvalidArgument on an unknown extension (with format Auto); IoError naming the file and
/// the line, vertex or byte offset: cannot open, empty, malformed header, truncated body, junk
/// text, NaN/Inf values, missing coordinates or normals.
PointSet readPointCloud(const std::string& path, const PointReadOptions& options = {});

/// readPointCloud, also returning what was read.
PointCloudFile readPointCloudWithReport(const std::string& path,
                                        const PointReadOptions& options = {});

/// The row count of a PLY file's vertex element (from its header). @throws IoError naming the file.
std::int64_t plyVertexCount(const std::string& path);

/// Rows [first, first + count) of a PLY cloud's vertex element, read as readPointCloud reads the whole
/// cloud (report.points = count). Binary rows before `first` are skipped by seeking, so each rank of a
/// distributed fit reads only its own byte range. @throws IoError naming the file when the range is not
/// inside the element (and as readPointCloud), InvalidArgument for count < 0.
PointCloudFile readPlyVertexRows(const std::string& path, std::int64_t first, std::int64_t count,
                                 const PointReadOptions& options = {});

/// Writes binary little-endian PLY with float x y z nx ny nz (the layout of the shared clouds),
/// atomically. @throws InvalidArgument when a value does not fit in a float; IoError on write
/// errors.
void writePointCloud(const std::string& path, const PointSet& points);

/// Mesh file formats.
enum class MeshFormat {
  Auto,  ///< from the extension (case-insensitive): .ply or none → Ply, .obj → Obj, .stl → Stl, .3mf → ThreeMf
  Ply,   ///< binary little-endian PLY: float x y z; faces "list uchar int vertex_indices"
  Obj,   ///< Wavefront OBJ text: "v x y z" and "f i j k" (1-based), coordinates round-trip exactly
  Stl,   ///< binary STL: float normal (computed per face) and corners, no attributes
  /// 3MF core (through lib3mf, an optional build component: mesh3mfAvailable()): one mesh object and one
  /// build item, unit millimetre (coordinates written as they are), float32 vertices; UUIDs derived
  /// from the content, so equal meshes give equal files.
  ThreeMf,
};

/// True when this build reads and writes 3MF (it was built with lib3mf, Debian: lib3mf-dev).
bool mesh3mfAvailable() noexcept;
/// "auto", "ply", "obj", "stl" or "3mf".
const char* meshFormatName(MeshFormat format) noexcept;

/// The mesh format of a path by its extension, as readMesh and writeMesh pick it (Auto for any other
/// extension, where they throw).
MeshFormat meshFormatOf(const std::string& path);

/// What an input file holds: an oriented point cloud or a triangle mesh.
enum class InputKind {
  Auto,   ///< decide from the file (detectInputKind)
  Cloud,  ///< readPointCloud
  Mesh,   ///< readMesh
};

/// "auto", "cloud" or "mesh".
const char* inputKindName(InputKind kind) noexcept;

/// Cloud or Mesh: .stl and .obj files are meshes; a .ply file is a mesh when its header declares a face
/// element with at least one face (only the header is read); anything else is a cloud.
/// @throws IoError when a .ply file cannot be opened or its header is malformed.
InputKind detectInputKind(const std::string& path);

/// Writes a mesh atomically in `format` (Auto: by extension).
/// @throws InvalidArgument on an unknown extension, an out-of-range face index (naming the face) or
/// a vertex that does not fit in a float (PLY/STL); IoError on write errors.
void writeMesh(const std::string& path, const Mesh& mesh, MeshFormat format = MeshFormat::Auto);

/// Reads a triangle mesh: PLY (any encoding and scalar types; faces as a list "vertex_indices" or
/// "vertex_index" of any integer type; polygons are fan-triangulated), OBJ ("v" and "f" lines with
/// v, v/vt, v/vt/vn, v//vn and negative indices; polygons fan-triangulated; other lines ignored) or
/// STL (binary or ascii; corners with identical coordinates are welded into one vertex).
/// @throws InvalidArgument on an unknown extension; IoError naming the file and the face, vertex or
/// line (out-of-range index, NaN vertex, malformed or truncated content).
Mesh readMesh(const std::string& path, MeshFormat format = MeshFormat::Auto);

}  // namespace duplexfit
