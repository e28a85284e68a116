// The self-check of a fit's meshes: every component of the zero-level mesh must carry input points, and
// every component of an offset mesh must lie at ≈ |δ| from the zero-level mesh. Components that fail are
// listed (size, box, why) so that a spurious sheet is reported instead of shipped silently. Small
// components can be dropped first (dropSmallComponents).
#pragma once

#include <cstddef>
#include <limits>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "duplexfit/mesh.hpp"
#include "duplexfit/types.hpp"

namespace duplexfit {

/// A component of one of the meshes that failed the self-check.
struct ComponentIssue {
  enum class Why {
    NoInputPoints,  ///< a zero-level component with no input point within SelfCheckReport::pointTolerance
    OffOffset,      ///< an offset component whose vertices are not at ≈ |δ| from the zero-level mesh
  };
  int surface = 0;             ///< 0: the zero-level mesh, j ≥ 1: offset j (meshes[j])
  double iso = 0.0;            ///< the mesh's level (0, or δ_j)
  std::size_t component = 0;   ///< its label in faceComponents() order of that mesh
  std::size_t faces = 0, vertices = 0;
  double area = 0.0;
  double areaFraction = 0.0;   ///< area / the whole mesh's area
  Eigen::AlignedBox3d box;     ///< bounds of its vertices
  Why why = Why::NoInputPoints;
  /// OffOffset: mean dist(vertex, zero-level mesh) and mean |dist − |δ|| (the rule: meanDeviation > |δ|/2,
  /// as `measure --offset-of`); NaN for NoInputPoints.
  double meanDistance = std::numeric_limits<double>::quiet_NaN();
  double meanDeviation = std::numeric_limits<double>::quiet_NaN();
  /// NoInputPoints: the distance from its nearest vertex to the nearest input point; NaN for OffOffset.
  double nearestInputPoint = std::numeric_limits<double>::quiet_NaN();
};

/// "no_input_points" or "off_offset".
const char* componentIssueName(ComponentIssue::Why why) noexcept;

/// What dropSmallComponents removed from one mesh.
struct DroppedComponents {
  std::size_t components = 0, faces = 0, vertices = 0;
  double area = 0.0;          ///< total area removed
  double areaFraction = 0.0;  ///< area / the mesh's area before dropping
  double minAreaFraction = 0.0;  ///< the threshold applied (0: nothing was dropped on purpose)
};

/// The mesh without its connected components (faceComponents) whose area is below minAreaFraction × the
/// mesh's total area; the largest component is always kept. Vertices no remaining face uses are removed;
/// the remaining vertices and faces keep their order. minAreaFraction = 0 drops nothing (and returns the
/// mesh unchanged, unused vertices included), and so does a mesh without faces.
/// @throws InvalidArgument when minAreaFraction is not in [0, 1), or an index is out of range.
struct DropResult {
  Mesh mesh;                    ///< what remains
  DroppedComponents dropped;    ///< what was removed
};
DropResult dropSmallComponents(const Mesh& mesh, double minAreaFraction);

/// A component of a zero-level mesh with no input point near it (emptyZeroLevelComponents).
struct EmptyComponent {
  std::size_t component = 0;       ///< its label in faceComponents() order
  std::size_t faces = 0;
  double area = 0.0;
  Eigen::AlignedBox3d box;         ///< bounds of its vertices
  double nearestInputPoint = 0.0;  ///< from its nearest vertex to the nearest input point
  std::vector<Index> faceList;     ///< its faces (ascending)
  std::vector<Index> vertexList;   ///< its vertices (in the order its faces first use them)
};

struct SelfCheckOptions {
  /// An input point "lands on" a zero-level component when its distance to the component is at most this
  /// (input units); 0: pointToleranceEdges × the mean edge length of the zero-level mesh.
  double pointTolerance = 0.0;
  double pointToleranceEdges = 2.0;
  /// Vertices measured per offset component: every k-th of a larger component, so that about this many
  /// are (offsetComponents' maxVertices; a fit's true offset deviates by ~1% of |δ|, the rule's threshold
  /// is 50%); 0: all.
  std::size_t offsetVertexSamples = 20000;
  /// Area fraction below which cleanAndSelfCheck drops a component before checking (0: none).
  double minAreaFraction = 0.0;
  /// The same for the offset meshes only (the larger of the two applies there): slivers of the δ level
  /// where a part is almost exactly 2δ thick.
  double minOffsetAreaFraction = 0.0;
  /// Also list (SelfCheckReport::emptyComponents) the zero-level components with no input point within
  /// this many mean edge lengths, the phantom repair's candidates (0: not asked). At one edge, half the
  /// check's default, a phantom beside a real surface that the check lets pass is among them.
  double candidateEdges = 0.0;
  /// When candidateEdges lists components, stop after the zero level (SelfCheckReport::offsetsChecked
  /// false): for a caller that changes the meshes for them and checks again (the pipeline's phantom repair),
  /// so that the offsets are measured once.
  bool candidatesFirst = false;
};

/// One mesh's part of the check.
struct SurfaceSelfCheck {
  int surface = 0;
  double iso = 0.0;
  std::size_t faces = 0;
  std::size_t components = 0;  ///< after dropping
  double area = 0.0;           ///< after dropping
  std::size_t issues = 0;      ///< components that failed
  DroppedComponents dropped;   ///< by cleanAndSelfCheck (zero for selfCheck)
  /// Offset meshes: the smallest distance from a measured vertex (see offsetVertexSamples) to the zero-level
  /// mesh, and that vertex: the thinnest wall of the shell between the two surfaces, which should be about
  /// |δ| (a δ level pulled onto the surface makes it much less). NaN for the zero level, for a mesh without
  /// faces and when the zero-level mesh has none.
  double thinnestWall = std::numeric_limits<double>::quiet_NaN();
  Eigen::Vector3d thinnestWallAt = Eigen::Vector3d::Constant(std::numeric_limits<double>::quiet_NaN());
};

struct SelfCheckReport {
  std::vector<ComponentIssue> issues;     ///< by surface, then component label
  std::vector<SurfaceSelfCheck> surfaces;  ///< one per mesh
  /// With SelfCheckOptions::candidateEdges: the zero-level components without input points within that
  /// tolerance (within the check's own where that is the smaller), with their faces (label order).
  std::vector<EmptyComponent> emptyComponents;
  double pointTolerance = 0.0;            ///< the tolerance used (input units; 0 when not checked)
  bool pointsChecked = false;             ///< input points were given, so NoInputPoints was tested
  bool offsetsChecked = true;             ///< the offset meshes were checked (see candidatesFirst)
  double minAreaFraction = 0.0;           ///< as given to cleanAndSelfCheck
  double minOffsetAreaFraction = 0.0;     ///< as given to cleanAndSelfCheck
  double seconds = 0.0;
  bool ok() const noexcept { return issues.empty(); }
};

/// Checks the meshes of one fit: meshes[0] is the zero-level mesh, meshes[j] (j ≥ 1) the offset surface
/// at isos[j] = δ_j (signed, input units). A zero-level component is an issue when no input point lies
/// within the point tolerance of its triangles (skipped when inputPoints is empty); an offset component is
/// an issue when the mean over its vertices (see offsetVertexSamples) of |dist(vertex, meshes[0]) − |δ_j||
/// exceeds |δ_j|/2 (every offset component is one when meshes[0] has no faces). Meshes without faces have
/// no components.
/// @throws InvalidArgument when the sizes differ, isos[0] ≠ 0 or a δ_j is 0 or not finite, an index is
/// out of range, or the options are not finite and ≥ 0.
SelfCheckReport selfCheck(const std::vector<Mesh>& meshes, const std::vector<double>& isos, const Points& inputPoints,
                          const SelfCheckOptions& options = {});

/// The area fraction below which a fit's mesh `mesh` loses its components: options.minAreaFraction on the
/// zero-level mesh (0), the larger of it and options.minOffsetAreaFraction on the offset meshes.
double dropFraction(const SelfCheckOptions& options, std::size_t mesh);

/// dropSmallComponents on every mesh of a fit in place, at dropFraction; what each lost (in mesh order).
/// @throws InvalidArgument when a fraction is not in [0, 1).
std::vector<DroppedComponents> dropSmallComponents(std::vector<Mesh>& meshes, const SelfCheckOptions& options);

/// The components of a zero-level mesh with no input point within toleranceEdges × the mesh's mean edge
/// length of their triangles: selfCheck's NoInputPoints test at another tolerance (the phantom repair asks
/// at one edge, half the check's default, since a phantom beside a real surface can lie within two).
/// @throws InvalidArgument when toleranceEdges is not finite and > 0, or an index is out of range.
std::vector<EmptyComponent> emptyZeroLevelComponents(const Mesh& zero, const Points& inputPoints, double toleranceEdges);

/// dropSmallComponents(meshes, options), then selfCheck on the result; the report's surfaces say what was
/// dropped, and seconds cover both.
SelfCheckReport cleanAndSelfCheck(std::vector<Mesh>& meshes, const std::vector<double>& isos,
                                  const Points& inputPoints, const SelfCheckOptions& options = {});

}  // namespace duplexfit
