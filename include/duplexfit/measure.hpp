// Mesh measurements (docs/method.md §8): input validation shared by every command, a bounding-volume
// hierarchy with exact closest-point queries, Metro-style area-uniform sampling, two-sided Metro
// distances with the symmetric Hausdorff distance, offset-surface accuracy against a surface, and a
// mesh check (closed, manifold, oriented, outward, genus, boundary loops, self-intersections).
#pragma once

#include <cstddef>
#include <cstdint>
#include <limits>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "duplexfit/interrupter.hpp"
#include "duplexfit/mesh.hpp"
#include "duplexfit/types.hpp"
#include "duplexfit/resources.hpp"

namespace duplexfit {

// ---------------------------------------------------------------------------------------------
// Validation

/// What validateMesh found besides hard errors.
struct MeshValidation {
  std::size_t vertices = 0, faces = 0;
  std::size_t repeatedIndexFaces = 0;  ///< faces with a repeated vertex index
  std::size_t zeroAreaFaces = 0;       ///< distinct indices but zero area (coincident or collinear corners)
  std::int64_t firstDegenerateFace = -1;  ///< the first face of either kind, −1 when none
  std::size_t degenerateFaces() const noexcept { return repeatedIndexFaces + zeroAreaFaces; }
};

/// Checks a mesh before any measurement: at least one face, every index in [0, #V), every vertex
/// finite with |coordinate| ≤ 1e64 (beyond, areas and squared distances overflow). Degenerate triangles are counted, not rejected. A triangle has zero area when
/// |(b − a) × (c − a)| ≤ 1e-12 · (its longest edge)² (this includes coincident corners).
/// @param source the name used in messages (typically the file name)
/// @throws InvalidArgument "<source>: mesh has no faces", "<source>: face 12: index 99 out of range
///         (mesh has 40 vertices)", "<source>: vertex 7: coordinate y is NaN" (or "is infinite", or "= 1e+200 is too large ...").
MeshValidation validateMesh(const Mesh& mesh, const std::string& source = "mesh");

// ---------------------------------------------------------------------------------------------
// Closest points and the triangle BVH

/// The part of a triangle that holds a closest point.
enum class TriangleFeature : std::uint8_t {
  Face,    ///< the interior
  Edge,    ///< edge `local` = corners (local, local + 1 mod 3), end points excluded
  Vertex,  ///< corner `local`
};

/// The closest point of a mesh (or of one triangle) to a query point.
struct ClosestPoint {
  double distance = std::numeric_limits<double>::infinity();  ///< Euclidean distance, never NaN
  Eigen::Vector3d point = Eigen::Vector3d::Zero();             ///< the closest point
  std::int64_t face = -1;                                      ///< face index in the mesh (−1: none)
  TriangleFeature feature = TriangleFeature::Face;
  int local = 0;  ///< corner or edge index within the face (see TriangleFeature)
};

/// The exact closest point of triangle (a, b, c) to q (Voronoi-region classification). Degenerate
/// triangles (collinear or coincident corners) are treated as their edges; the result is never NaN
/// for finite input. `face` is left at −1.
ClosestPoint closestPointOnTriangle(const Eigen::Vector3d& q, const Eigen::Vector3d& a,
                                    const Eigen::Vector3d& b, const Eigen::Vector3d& c);

/// A binary bounding-volume hierarchy over the triangles of a mesh (object-median splits along the
/// longest axis of the centroid bounds, at most 4 triangles a leaf), answering exact closest-point
/// and box-overlap queries. Immutable after construction; copies share the tree; queries are
/// thread-safe. The batch queries run in parallel with OpenMP.
class TriangleBvh {
 public:
  /// Builds the tree (copies the triangle corners). Degenerate triangles are kept.
  /// @throws InvalidArgument when the mesh has no faces or an index is out of range.
  explicit TriangleBvh(const Mesh& mesh);

  /// The closest point of the mesh to q.
  ClosestPoint closest(const Eigen::Vector3d& q) const;
  /// closest(q), starting from `hint`: −1, or the value a previous call left there (for a nearby
  /// point, the search starts with a tight bound; coherent query sequences run about twice as fast).
  /// The result does not depend on the hint.
  ClosestPoint closest(const Eigen::Vector3d& q, std::int64_t& hint) const;
  /// closest() for every row of `queries`, in parallel.
  std::vector<ClosestPoint> closest(const Points& queries) const;
  /// Only the distances, in parallel.
  Eigen::VectorXd distances(const Points& queries) const;
  /// Appends to `out` the faces whose bounding boxes intersect the box [lo, hi] (closed boxes).
  void overlapping(const Eigen::Vector3d& lo, const Eigen::Vector3d& hi,
                   std::vector<std::int64_t>& out) const;
  /// overlapping(lo, hi, out), appending at most `limit` faces: returns false when it stopped there with
  /// faces left unvisited (the faces appended are then the first `limit` in tree order, deterministic).
  bool overlapping(const Eigen::Vector3d& lo, const Eigen::Vector3d& hi, std::vector<std::int64_t>& out,
                   std::size_t limit) const;

  std::size_t faceCount() const noexcept;
  std::size_t nodeCount() const noexcept;
  int depth() const noexcept;  ///< levels of the tree (1 for a single leaf)

  struct Data;  ///< the tree (private to the library)

 private:
  std::shared_ptr<const Data> data_;
};

// ---------------------------------------------------------------------------------------------
// Sampling and distances

/// Options of the Metro sampling (§8.2).
struct MeasureOptions {
  /// Face samples per triangle on average (> 0; may be fractional). The total is
  /// ceil(samplesPerFace · #F) in expectation, spread over the faces in proportion to their area.
  double samplesPerFace = 10.0;
  /// Seed of the deterministic sampling: the same mesh, options and seed give the same samples on
  /// any number of threads.
  std::uint64_t seed = 1;
  /// Also sample every vertex referenced by a face (Metro's vertex sampling).
  bool includeVertices = true;
  /// The memory budget, checked before sampling (samples, their distances, the other mesh's tree).
  ResourceLimits limits{};
};

/// Samples of a mesh: the referenced vertices first (when included), then the face samples.
struct MeshSamples {
  Points points;                    ///< #S×3
  std::vector<std::int64_t> faces;  ///< per sample, the face it lies on (−1 for a vertex sample)
  std::size_t vertexSamples = 0, faceSamples = 0;
};

/// Area-uniform random samples of the faces (stratified: face i gets floor(M·aᵢ/A + uᵢ) samples with
/// uᵢ uniform in [0, 1), then uniform points in the triangle), plus the referenced vertices.
/// @throws InvalidArgument when samplesPerFace is not a positive finite number, or the mesh is
/// invalid (validateMesh).
MeshSamples sampleMesh(const Mesh& mesh, const MeasureOptions& options = {});

/// Statistics of one set of per-sample values (distances or deviations).
struct SampleStats {
  std::size_t samples = 0;
  double min = 0.0, max = 0.0, mean = 0.0, rms = 0.0;
  double p99 = 0.0;  ///< 99th percentile (nearest rank)
  Eigen::Vector3d maxAt = Eigen::Vector3d::Zero();       ///< the sample with the largest value
  Eigen::Vector3d maxClosest = Eigen::Vector3d::Zero();  ///< its closest point on the other mesh
};

/// Two-sided Metro distance between meshes A and B.
struct DistanceReport {
  SampleStats forward;   ///< samples of A → mesh B
  SampleStats backward;  ///< samples of B → mesh A
  double hausdorff = 0.0;  ///< symmetric Hausdorff distance: max(forward.max, backward.max)
  double diagonalA = 0.0, diagonalB = 0.0;  ///< bounding-box diagonals
};

/// Metro (§8.2): samples both meshes (options; B with seed + 1) and takes exact distances to the
/// other mesh through a BVH. Mean and RMS are over all samples (vertices included). `interrupter` is
/// polled every 65,536 samples with the percent done.
/// @throws InvalidArgument for invalid meshes ("first mesh"/"second mesh") or options; Cancelled.
DistanceReport measureDistance(const Mesh& a, const Mesh& b, const MeasureOptions& options = {},
                               Interrupter* interrupter = nullptr);

/// Accuracy of an offset mesh O against its surface mesh S, for signed δ (positive = inward, as in
/// FitOptions::offsets).
struct OffsetReport {
  double delta = 0.0;
  std::size_t samples = 0;
  SampleStats distance;           ///< dist(sample, S)
  SampleStats deviation;          ///< |dist(sample, S) − |δ||
  SampleStats relativeDistance;   ///< distance / |δ|
  SampleStats relativeDeviation;  ///< deviation / |δ|
  /// Samples on the wrong side of S (outside for δ > 0, inside for δ < 0). The side is the sign of
  /// (sample − closest point) · the angle-weighted pseudo-normal of the closest feature (face, edge
  /// or vertex) of S; samples exactly on S count as neither side.
  std::size_t wrongSide = 0;
  double wrongSideShare = 0.0;  ///< wrongSide / samples
  /// Per connected component of O (faces sharing vertices), from its vertices' distances to S; largest
  /// component first.
  struct Component {
    std::size_t faces = 0, vertices = 0;
    double meanDistance = 0.0;   ///< mean dist(vertex, S)
    double meanDeviation = 0.0;  ///< mean |dist − |δ||
    double maxDeviation = 0.0;
    /// The smallest dist(vertex, S) and that vertex (+∞ and NaN when no vertex was measured): where the
    /// wall between the offset and S is thinnest.
    double minDistance = std::numeric_limits<double>::infinity();
    Eigen::Vector3d minAt = Eigen::Vector3d::Constant(std::numeric_limits<double>::quiet_NaN());
    /// Not on the offset: mean deviation above half of |δ| (a spurious sheet, not a piece of the offset).
    bool offOffset = false;
  };
  std::vector<Component> components;
  std::size_t offOffsetComponents = 0;  ///< components with offOffset set
};

/// Samples O (options) and measures it against S. S should be closed and outward-oriented.
/// @throws InvalidArgument for invalid meshes ("offset mesh"/"surface mesh"), δ = 0 or not finite,
/// or bad options; Cancelled when `interrupter` (polled every 65,536 samples) says stop.
OffsetReport measureOffset(const Mesh& offset, const Mesh& surface, double delta,
                           const MeasureOptions& options = {}, Interrupter* interrupter = nullptr);

/// The per-component part of measureOffset (and of selfCheck, self_check.hpp): for every connected
/// component of O, in label order (`labels` and `count` as faceComponents(offset) returns them), the
/// distances of its vertices to S through `surface` (a BVH of S) and the off-offset rule (mean |dist − |δ||
/// above |δ|/2). Unsorted, so that entry c belongs to label c. maxVertices > 0 measures only every k-th
/// vertex (in index order) of a component with n > maxVertices vertices, k = ⌈n/maxVertices⌉: the means
/// and the maximum are then over that subset (Component::vertices still counts them all).
/// @throws InvalidArgument when the labels do not match the faces or an index is out of range.
std::vector<OffsetReport::Component> offsetComponents(const Mesh& offset, const TriangleBvh& surface, double delta,
                                                      const std::vector<Index>& labels, std::size_t count,
                                                      std::size_t maxVertices = 0);

// ---------------------------------------------------------------------------------------------
// Triangle quality

/// Whether a triangle is degenerate once its corners are rounded to float32 (as STL and binary PLY store
/// them): the rounded corners are not three distinct points, or their cross product (b − a) × (c − a)
/// is zero in float32 arithmetic, or at most 1e-12 · (longest edge)² in double (validateMesh's rule).
bool float32Degenerate(const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c);

/// The smallest interior angle of triangle (a, b, c), in degrees (0 for coincident corners).
double minAngleDegrees(const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c);

/// minAngleDegrees(a, b, c) < degrees, decided without the arc tangent unless the angle lies within a
/// relative 1e-9 of the bound (the same answer, for the cleaning's and the projection's per-face tests).
bool minAngleBelow(const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c, double degrees);

/// Shape statistics of a mesh's triangles.
struct TriangleQuality {
  std::size_t faces = 0;
  /// Faces that are degenerate in float32 (float32Degenerate; repeated indices included).
  std::size_t float32DegenerateFaces = 0;
  std::int64_t firstFloat32DegenerateFace = -1;  ///< −1 when none
  double sliverAngle = 1.0;  ///< degrees: the threshold `slivers` counts below
  /// Faces that are not float32-degenerate with a minimum angle below sliverAngle.
  std::size_t slivers = 0;
  /// Faces with a minimum angle below 1°, 5° and 10° (cumulative; float32-degenerate faces included).
  std::size_t below1 = 0, below5 = 0, below10 = 0;
  double minAngle = 0.0;        ///< degrees, over the faces that are not float32-degenerate (0: none)
  std::int64_t worstFace = -1;  ///< the face attaining minAngle
  double shortestEdge = 0.0;    ///< over all faces with distinct indices (0 for an empty mesh)
};

/// TriangleQuality of a mesh (indices must be valid: validateMesh first), slivers below `sliverAngle`
/// degrees.
TriangleQuality triangleQuality(const Mesh& mesh, double sliverAngle = 1.0);

// ---------------------------------------------------------------------------------------------
// Mesh check

/// Options of checkMesh.
struct CheckOptions {
  /// A sliver is a triangle whose smallest angle is below this many degrees (reported in
  /// MeshCheck::quality).
  double sliverAngle = 1.0;
  /// Slivers make the mesh invalid only when they are more than this share of its faces (0.001: one in a
  /// thousand; docs/method.md §7). Float32-degenerate triangles are always an error.
  double maxSliverShare = 0.001;
  bool selfIntersections = true;  ///< look for intersecting triangle pairs (the slowest check)
  std::size_t listedPairs = 20;   ///< how many intersecting pairs to list in MeshCheck::pairs
  /// Work bound of the self-intersection test, in candidate pairs (faces with overlapping boxes): each
  /// face examines at most max(1024, candidatePairBudget / #F) candidates, so time and memory stay linear
  /// in #F even when thousands of faces overlap (duplicated triangles, a fanned polygon with repeated
  /// corners). Meshes without such clusters never reach it; when a face does, the count is a lower bound
  /// (MeshCheck::selfIntersectionsComplete is false).
  std::size_t candidatePairBudget = 400'000'000;
  /// The memory budget, checked before the tree and the per-face tables are built.
  ResourceLimits limits{};
};

/// The facts checkMesh reports.
struct MeshCheck {
  MeshTopology topology;        ///< from analyzeTopology
  MeshValidation validation;    ///< from validateMesh (degenerate triangles)
  TriangleQuality quality;      ///< float32-degenerate triangles, slivers, the angle histogram
  /// quality.slivers exceeds CheckOptions::maxSliverShare of the faces.
  bool tooManySlivers = false;
  bool watertight = false;      ///< no boundary and no non-manifold edges
  bool manifold = false;        ///< 2-manifold at every edge and vertex
  bool oriented = false;        ///< neighbouring faces traverse their shared edge in opposite directions
  bool outward = false;         ///< signed volume > 0
  double signedVolume = 0.0, area = 0.0;
  std::size_t boundaryLoops = 0;  ///< connected cycles of boundary edges
  /// Genus (sum over components), known for manifold, consistently oriented meshes:
  /// (2·components − χ − boundaryLoops) / 2.
  bool genusKnown = false;
  long long genus = 0;
  bool selfIntersectionsChecked = false;
  /// Intersecting triangle pairs: pairs without a shared vertex that touch or cross; pairs sharing
  /// one vertex whose intersection extends beyond it; pairs sharing an edge that are coplanar and
  /// fold over each other; duplicate faces. Vertices at identical positions count as shared.
  /// Degenerate (zero-area) triangles are skipped.
  /// Counted exactly, without storing the pairs (memory stays linear in #F); a lower bound ("at least")
  /// when selfIntersectionsComplete is false.
  std::size_t selfIntersections = 0;
  /// Every candidate pair was examined (see CheckOptions::candidatePairBudget); false when not checked.
  bool selfIntersectionsComplete = false;
  /// The first listedPairs intersecting pairs (smallest first) among those examined, sorted.
  std::vector<std::pair<std::int64_t, std::int64_t>> pairs;
  /// No non-degenerate face: nothing to be valid (watertight is then false too).
  bool empty() const noexcept { return topology.faces == topology.degenerateFaces; }
  /// Not empty, closed, manifold, oriented, outward, free of self-intersections (when checked; a check
  /// that stopped at the work bound without finding any does not count as free of them), without a
  /// float32-degenerate triangle and without too many slivers.
  bool valid() const noexcept {
    return !empty() && watertight && manifold && oriented && outward && selfIntersections == 0 &&
           (!selfIntersectionsChecked || selfIntersectionsComplete) && quality.float32DegenerateFaces == 0 &&
           !tooManySlivers;
  }
};

/// Checks a mesh (validateMesh first).
/// @throws InvalidArgument for an invalid mesh (no faces, bad index, NaN vertex).
MeshCheck checkMesh(const Mesh& mesh, const CheckOptions& options = {});

/// The intersecting triangle pairs as checkMesh counts them (MeshCheck::selfIntersections), without the
/// topology and quality checks.
struct SelfIntersections {
  std::size_t count = 0;  ///< pairs found (a lower bound when `complete` is false)
  bool complete = true;   ///< every candidate pair was examined (CheckOptions::candidatePairBudget)
  std::vector<std::pair<std::int64_t, std::int64_t>> pairs;  ///< the first options.listedPairs, sorted
};

/// checkMesh's self-intersection test alone, over the pairs with at least one face in `faces` (every pair
/// when `faces` is null; each pair counted once). After moving some vertices of a mesh whose pairs were
/// all tested, asking about the faces around the moved vertices finds every pair the move can have made.
/// A mesh with no faces has none; any other mesh must pass validateMesh.
/// @throws InvalidArgument for an invalid mesh (validateMesh) or a listed face out of range;
/// MemoryLimitExceeded.
SelfIntersections findSelfIntersections(const Mesh& mesh, const CheckOptions& options = {},
                                        const std::vector<std::int64_t>* faces = nullptr);

}  // namespace duplexfit
