// Point-cloud pre-processing before a fit: the bilateral point filter of docs/method.md §9 (denoising),
// and normal estimation with consistent outward orientation for clouds that carry no normals.
// Neighbour queries run on the host (NeighborIndex's k-d tree); the per-point sums run as OpenCL kernels on the device, or as
// the same loops in C++ on the reference device.
#pragma once

#include <cstddef>
#include <string>
#include <vector>

#include "duplexfit/interrupter.hpp"
#include "duplexfit/device.hpp"
#include "duplexfit/point_set.hpp"
#include "duplexfit/neighbors.hpp"
#include "duplexfit/types.hpp"
#include "duplexfit/resources.hpp"

namespace duplexfit {

/// Options of bilateralFilter. Every length is in input units; 0 picks the rule of docs/method.md §9.
struct BilateralOptions {
  /// σ_ψ, width of the spatial weight ψ(r) = exp(−r²/(2σ_ψ²)); 0: 4·R_ave.
  double sigmaSpatial = 0.0;
  /// σ_ζ, width of the range weight on the normal offset ‖K_q(p) − p‖; 0: 4·R_ave.
  double sigmaRange = 0.0;
  /// Neighbourhood radius (points q with ‖q − p‖ < radius contribute); 0: 2·σ_ψ.
  double radius = 0.0;
  /// σ of the area weights s_q = σ²/N(q) (N(q): points within σ of q, q included); 0: σ_M, the support
  /// of the finest level the fit would use (§4 with α = 0.75).
  double areaSigma = 0.0;
  /// Passes; each starts from the previous pass's output (the paper uses one). Parameters are chosen once
  /// from the input; neighbourhoods and area weights are recomputed every pass.
  int iterations = 1;
  /// ζ(r) = exp(−r²/(2σ_ζ²)) instead of the printed exp(−r²/σ_ζ²) (§12.14).
  bool symmetricRange = false;
  /// Arithmetic of the per-point sums (positions are centred first, displacements added in double).
  Precision precision = Precision::Float;
  /// Keep the input normals (the paper, default) or re-estimate them by PCA on the filtered points
  /// (estimateNormals' PCA with `normalK` neighbours), each signed to agree with its input normal.
  bool reestimateNormals = false;
  int normalK = 15;
  /// The memory budget, checked before the first pass (about 300 bytes a point).
  ResourceLimits limits{};
};

/// What bilateralFilter did: the parameters actually used and the effect.
struct BilateralReport {
  std::string device;               ///< spec of the device that ran the sums
  Precision precision = Precision::Float;
  std::size_t points = 0;
  double sigmaSpatial = 0.0;        ///< σ_ψ used
  double sigmaRange = 0.0;          ///< σ_ζ used
  double radius = 0.0;              ///< neighbourhood radius used
  double areaSigma = 0.0;           ///< σ of s_q used
  double rAve = 0.0;                ///< R_ave = mean √s_q over the input
  int levels = 0;                   ///< M behind the default σ_M (0 when areaSigma was given)
  int iterations = 0;
  bool symmetricRange = false;
  bool normalsReestimated = false;
  double meanNeighbors = 0.0;       ///< mean neighbourhood size of the last pass (the point included)
  std::size_t isolated = 0;         ///< points of the last pass with no neighbour but themselves
  std::size_t moved = 0;            ///< points that moved by more than 1e-9·L in total
  double maxDisplacement = 0.0;     ///< input units, over all passes (‖output − input‖)
  double meanDisplacement = 0.0;
  double neighborSeconds = 0.0;     ///< k-d tree builds and radius queries (host)
  double filterSeconds = 0.0;       ///< weighted sums, including transfers
  double seconds = 0.0;             ///< everything
};

/// Filters noisy positions with the bilateral point filter (docs/method.md §9): each point moves to the
/// weighted mean of its projections K_q(p) = p − ((p − q)·n_q) n_q onto its neighbours' tangent planes,
/// with weights s_q·ψ(‖q − p‖)·ζ(‖K_q(p) − p‖). All points of a pass move at once. Normals are kept
/// unless options.reestimateNormals. Points whose normal is zero contribute K_q(p) = p.
/// @throws InvalidArgument on options out of range, fewer than 2 points, all points coincident, or a
/// precision the device lacks (DeviceError); DeviceError on OpenCL failures.
struct BilateralResult {
  PointSet points;  ///< the filtered cloud (rows match the input's)
  BilateralReport report;
};
/// @param interrupter may be null; polled before each pass with the percent of the passes done.
/// @throws as above, and Cancelled when the interrupter interrupts.
BilateralResult bilateralFilter(const Device& device, const PointSet& points, const BilateralOptions& options = {},
                                Interrupter* interrupter = nullptr);

/// Options of estimateNormals.
struct NormalOptions {
  /// Neighbours of each point in its PCA (the point itself not counted; k + 1 points in all). At least 3.
  int k = 15;
  /// Neighbours per point of the orientation graph (symmetrised kNN); 0: k.
  int graphK = 0;
  /// Arithmetic of the covariance sums on the device (eigenvectors are always taken in double).
  Precision precision = Precision::Float;
  /// When true (default) a cloud or component whose outward side cannot be decided (flat, or no enclosed
  /// volume) is an InvalidArgument; when false it keeps the propagated orientation (seed normal up,
  /// +z) and is counted in NormalReport::ambiguousComponents.
  bool requireOutward = true;
  /// The memory budget, checked before the neighbour searches ((k + 1) neighbours and 2·graphK graph edges a point).
  ResourceLimits limits{};
};

/// What estimateNormals did.
struct NormalReport {
  std::string device;
  Precision precision = Precision::Float;
  std::size_t points = 0;
  std::size_t duplicates = 0;        ///< points equal to an earlier point (they share its normal)
  int k = 0;
  int graphK = 0;
  std::size_t components = 0;        ///< connected components of the orientation graph
  std::size_t ambiguousComponents = 0;  ///< components whose outward side could not be decided
  std::size_t flippedComponents = 0; ///< components flipped by the outward (enclosed-volume) test
  std::size_t nestedComponents = 0;  ///< components inside an odd number of others (cavity walls), whose
                                     ///< normals therefore face inward into the cavity
  std::size_t flipped = 0;           ///< normals whose final sign is opposite to their raw PCA sign
  std::size_t degenerate = 0;        ///< neighbourhoods with no plane (collinear): the normal is zero
  std::size_t nonPlanar = 0;         ///< surface variation λ0/(λ0+λ1+λ2) > 0.1 (corners, noise)
  double minVolumeRatio = 0.0;       ///< smallest |enclosed-volume ratio| over decided components (1 = sphere)
  double neighborSeconds = 0.0;      ///< k-d tree build and kNN query
  double pcaSeconds = 0.0;           ///< covariance sums (device) and eigenvectors (host)
  double orientSeconds = 0.0;        ///< graph, spanning-tree propagation and outward test
  double seconds = 0.0;
};

/// Estimates unit normals of an unoriented cloud: PCA of each point's k nearest neighbours, then a
/// consistent orientation by propagation along a minimum spanning tree of the symmetrised kNN graph
/// (Hoppe et al. 1992; edge cost 1 − |n_i·n_j| plus a penalty for edges that leave the tangent planes),
/// seeded at the highest point of each connected component with its normal up, and finally the sign of
/// each component chosen so that its normals point outward: the sign of the enclosed volume
/// (1/3)∮(x − c)·n dA estimated as Σ a_i (p_i − c)·n_i (divergence theorem; a_i from the kNN radius) is
/// made positive. A component nested inside an odd number of others (the inner wall of a hollow shell, by
/// the generalised winding number of the others) is then flipped so that it faces into its cavity.
/// Output rows match the input rows; exact duplicates share the first occurrence's normal.
/// @throws InvalidArgument naming the point for a NaN/Inf coordinate; when k < 3, fewer than k + 1
/// distinct points, all points on a line, or (with requireOutward) all points on a plane or a component
/// without an outward side; DeviceError on OpenCL failures or a precision the device lacks.
struct NormalResult {
  PointSet points;  ///< the positions with their estimated unit normals
  NormalReport report;
};
/// @param interrupter may be null; polled between the stages (neighbours, PCA, orientation).
/// @throws as above, and Cancelled when the interrupter interrupts.
NormalResult estimateNormals(const Device& device, const Points& points, const NormalOptions& options = {},
                             Interrupter* interrupter = nullptr);

/// Options of findOutliers.
struct OutlierOptions {
  double quantile = 0.005;  ///< per axis, the bulk's box spans the quantiles [quantile, 1 − quantile]
  double margin = 0.5;      ///< a point more than margin × the bulk box's largest side outside it is an outlier
  /// Isolated points (specks in empty space, inside the box): a point whose distance to its k-th nearest
  /// neighbour (k = neighbours) exceeds isolationFactor × the cloud's median of that distance. On the
  /// shared clouds the largest ratio is 8.5 (maxplanck_12k, a scan's sparse base), 4.7 on a half scan,
  /// at most 2.3 elsewhere; a speck of up to k points at 20 spacings from the surface reaches 20.
  /// 0: no isolation test (the O(n) box test only).
  int neighbours = 8;
  double isolationFactor = 20.0;
};

/// The outliers of a cloud: points well outside the box of its bulk (robust quantiles per axis), and
/// points isolated from the rest (their k-th neighbour distance against the cloud's distribution).
struct OutlierReport {
  std::vector<Index> indices;              ///< rows of the outliers (either test), ascending
  Index worst = 0;                         ///< the row farthest outside the box (when any is)
  double worstDistance = 0.0;              ///< its distance outside the bulk box (per-axis maximum)
  Eigen::Vector3d bulkMin = Eigen::Vector3d::Zero(), bulkMax = Eigen::Vector3d::Zero();
  double quantile = 0.0, margin = 0.0;
  int neighbours = 0;                      ///< the options' k and factor (0: the isolation test was off)
  double isolationFactor = 0.0;
  std::size_t outsideBox = 0;              ///< outliers by the box test
  std::size_t isolated = 0;                ///< outliers by the isolation test only (inside the box)
  double medianNeighbourDistance = 0.0;    ///< the cloud's median k-th neighbour distance (0: not measured)
  Index mostIsolated = 0;                  ///< the isolated point with the largest ratio (when any)
  double worstIsolation = 0.0;             ///< its k-th neighbour distance / the median
  /// "3 points far outside the rest of the cloud (worst: point 180 at (10000, 0, 0), ...)" or "no outliers".
  std::string describe(const Points& positions) const;
};

/// Finds the outliers: the box test in O(n), the isolation test with one k-nearest-neighbour search (clouds
/// under 20 points have none). @throws InvalidArgument for bad options.
/// `index` (may be null): a NeighborIndex over `positions`, used instead of building one (the fit shares it
/// with estimateNoise).
OutlierReport findOutliers(const Points& positions, const OutlierOptions& options = {},
                           const NeighborIndex* index = nullptr);

/// Options of estimateNoise.
struct NoiseOptions {
  std::size_t samples = 5000;  ///< points measured, evenly strided over the cloud (all when fewer)
  int neighbours = 13;         ///< each sample with its k − 1 nearest others (k ≥ 4)
  /// A cloud "looks noisy" when the median ratio exceeds this. On the shared clouds the clean ones reach
  /// 0.23 at most (wheel_29k: sharp rims between sparse rows; sphere_180: curvature at 180 points) and the
  /// 0.5% noise twins lie at 0.59–0.64 (docs/method.md §9).
  double threshold = 0.4;
};

/// How far the points scatter off their local surface, in point spacings: for each sample, the RMS distance
/// of it and its neighbours from their least-squares plane (the smallest eigenvalue of their covariance),
/// divided by the cloud's median nearest-neighbour distance; the median over the samples. Noise of standard
/// deviation σ on a surface sampled at spacing h gives about σ / h; a clean smooth surface, (h κ)-small values.
struct NoiseEstimate {
  double ratio = 0.0;        ///< the median ratio (0: not measured)
  double spacing = 0.0;      ///< the median nearest-other-point distance of the samples
  std::size_t samples = 0;   ///< samples measured (0: too few points or all coincide)
  double threshold = 0.0;    ///< the options' threshold
  bool noisy() const noexcept { return samples > 0 && ratio > threshold; }
};

/// Estimates the cloud's noise (above) with one k-nearest search of the samples in `index`, a NeighborIndex
/// over `positions` (the fit's, shared with findOutliers; 5,000 searches take about 20 ms at 550k points).
/// The spacing is each sample's nearest point at a positive distance, so coincident points (unmerged
/// duplicates) do not make it zero. Clouds under `neighbours` points, or whose samples all coincide with
/// their neighbours, are not measured (samples = 0). @throws InvalidArgument for bad options or an index of
/// another size.
NoiseEstimate estimateNoise(const Points& positions, const NeighborIndex& index, const NoiseOptions& options = {});
/// The same with its own k-d tree over the points (about 0.2 s more at 550k points).
NoiseEstimate estimateNoise(const Points& positions, const NoiseOptions& options = {});

}  // namespace duplexfit
