// Mesh input: a triangle mesh (an STL, OBJ or PLY part) turned into the oriented cloud a fit needs,
// area-uniform samples with the exact normal of the face each lies on, together with a report of what is
// wrong with the mesh (open, non-manifold, inconsistently oriented, inside out, degenerate faces).
// docs/method.md, "Mesh input", gives the sampling rule and the checks.
//
//     const duplexfit::Mesh mesh = duplexfit::readMesh("part.stl");
//     duplexfit::MeshSampleResult s = duplexfit::sampleMeshCloud(mesh, {}, "part.stl");
//     for (const std::string& w : s.report.warnings) std::cerr << "warning: " << w << "\n";
//     duplexfit::FitResult fitted = duplexfit::fit(device, s.points, fitOptions);
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "duplexfit/mesh.hpp"
#include "duplexfit/point_set.hpp"
#include "duplexfit/resources.hpp"

namespace duplexfit {

/// What sampleMeshCloud does with a mesh whose faces are not consistently oriented (two faces traverse
/// a shared edge in the same direction): its face normals then disagree, so no single choice of sign is
/// right for all of them.
enum class MeshOrientation {
  Require,   ///< an InvalidArgument naming the first such pair of faces (the default)
  Reorient,  ///< orient the faces consistently across manifold edges, then each component outward
             ///< (positive signed volume); the report counts the faces flipped
  Keep,      ///< sample the faces as they are (for callers that re-estimate the normals afterwards)
};

/// "require", "reorient" or "keep".
const char* meshOrientationName(MeshOrientation orientation) noexcept;

/// Options of sampleMeshCloud. The number of samples is `points` when given, else ⌈area / spacing²⌉ when
/// `spacing` is given, else the default rule: spacing = defaultSpacingFraction × the largest side of the
/// mesh's bounding box, with the count clamped to [minPoints, maxPoints].
struct MeshSampleOptions {
  std::size_t points = 0;  ///< total samples (> 0), or 0
  double spacing = 0.0;    ///< mean sample spacing h in mesh units (> 0), or 0
  /// The default spacing as a fraction of the largest bounding-box side: 1/150 gives a unit-box part of
  /// area 2.2 (fandisk) about 50,000 samples, the density of the shared fandisk_50k cloud.
  double defaultSpacingFraction = 1.0 / 150.0;
  std::size_t minPoints = 1000;       ///< lower bound of the default rule
  std::size_t maxPoints = 2'000'000;  ///< upper bound of the default rule
  std::uint64_t seed = 1;             ///< the same mesh, options and seed give the same samples
  MeshOrientation orientation = MeshOrientation::Require;
  /// Open (boundary edges) or non-manifold meshes are an InvalidArgument instead of a warning.
  bool strict = false;
  /// The memory budget, checked once the sample count is known (about 100 bytes a sample).
  ResourceLimits limits{};
};

/// What sampleMeshCloud found and did. Counts of edges are those of analyzeTopology on the mesh as given.
struct MeshSampleReport {
  std::string source;      ///< the name used in messages (the file name)
  MeshTopology topology;   ///< of the mesh as given (before any re-orientation)
  double area = 0.0;       ///< total area of the faces that were sampled
  double largestSide = 0.0;  ///< of the bounding box of the referenced vertices
  /// Faces that got no samples: a repeated vertex index or zero area (|ab × ac| ≤ 1e-12 · longest edge²,
  /// validateMesh's rule).
  std::size_t degenerateFaces = 0;
  std::int64_t firstBoundaryFace = -1;  ///< a face on a boundary edge (−1: none)
  std::int64_t firstNonManifoldFace = -1;
  /// The first two faces that traverse a shared edge in the same direction (−1: none).
  std::int64_t firstInconsistentFaces[2] = {-1, -1};
  MeshOrientation orientation = MeshOrientation::Require;  ///< the policy applied
  std::size_t reorientedFaces = 0;  ///< Reorient: faces flipped to agree with their neighbours or outward
  std::size_t inconsistentAfter = 0;  ///< Reorient: edges still inconsistent (a non-orientable surface)
  /// Signed volume of the sampled faces, as given (after Reorient when that ran) — negative: inside out.
  double signedVolume = 0.0;
  /// The mesh was inside out (signedVolume < 0): every normal was flipped to point outward.
  bool flipped = false;
  /// How the count was chosen: "points" (MeshSampleOptions::points), "spacing" or "default".
  std::string densityRule;
  double requestedSpacing = 0.0;  ///< the spacing behind the count (0 for "points")
  bool clamped = false;           ///< the default rule's count was clamped to [minPoints, maxPoints]
  std::size_t samples = 0;
  double spacing = 0.0;  ///< √(area / samples): the mean spacing of the samples
  double seconds = 0.0;
  /// One line per problem (open, non-manifold, inside out, degenerate faces, re-oriented, clamped), each
  /// starting with the source name; empty for a clean closed mesh.
  std::vector<std::string> warnings;
  bool open() const noexcept { return topology.boundaryEdges > 0; }
};

/// The oriented cloud of a mesh and its report.
struct MeshSampleResult {
  PointSet points;                  ///< positions on the faces, unit outward face normals
  std::vector<std::int64_t> faces;  ///< per point, the index of the face it lies on (in the mesh given)
  MeshSampleReport report;
};

/// Samples a triangle mesh into an oriented cloud: the count from the options (see MeshSampleOptions),
/// spread over the faces in proportion to their area by systematic sampling (one random offset along the
/// faces' cumulative area, so the total is exact and each face gets ⌊expected⌋ or ⌈expected⌉ samples);
/// inside a face a randomly shifted 2D low-discrepancy (R2) sequence mapped area-uniformly to the
/// triangle. Every normal is its face's unit normal, flipped when the mesh's signed volume is negative.
/// @param source the name used in messages (typically the file name)
/// @throws InvalidArgument whose message starts with `source`: no faces, zero total area, an index out of
/// range, a non-finite vertex, bad options (points and spacing both given, a spacing that is not a
/// positive number, or more than 100 million samples), inconsistent orientation with MeshOrientation::Require (naming
/// the faces; the message says how to proceed), and with `strict` an open or non-manifold mesh.
MeshSampleResult sampleMeshCloud(const Mesh& mesh, const MeshSampleOptions& options = {},
                                 const std::string& source = "mesh");

}  // namespace duplexfit
