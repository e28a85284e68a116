// Sign anchors (docs/method.md, "Sign of empty space"): centres in empty space whose target is the signed
// distance to the cloud, the sign taken from the cloud's generalized winding number. They keep coarse
// levels, whose supports span holes and cavities, from lifting f above 0 where nothing was sampled.
#pragma once

#include <cstddef>
#include <limits>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "duplexfit/types.hpp"

namespace duplexfit {
class NeighborIndex;
class WindingNumber;
struct LevelReport;
}  // namespace duplexfit

namespace duplexfit::detail {

struct AnchorOptions {
  double spacing = 0.0;      ///< grid spacing of the candidates (normalised units)
  double minDistance = 0.0;  ///< a candidate must be at least this far from every input point
  double maxDistance = 0.0;  ///< ... and at most this far (<= 0: no upper limit)
  /// > 0: outside the solid (winding number below 1/2), at most this far (a lower upper end there).
  double outsideMaxDistance = 0.0;
  double centreClearance = 0.0;  ///< ... and this far from every other centre of the level
  double clamp = 1.0;        ///< |target| = min(disk-soup distance, clamp)
  double ambiguity = 0.25;   ///< skip when |w − 0.5| < 0.5 − ambiguity (w in (ambiguity, 1 − ambiguity))
  /// Offsets (signed, normalised, > 0 inside): an anchor on an offset's side whose distance is within
  /// offsetClearance of |δ| is skipped, so that the anchors' small target errors do not bend the δ level.
  std::vector<double> offsets;
  double offsetClearance = 0.0;
  int agreeNeighbors = 8;    ///< skip when all these nearest samples put the candidate on the other side
  std::size_t maxCells = std::size_t{1} << 24;  ///< larger grids are not scanned (the level gets none)
  /// More grid cells than this near the samples: give up at once (tooMany), so that the caller can retry
  /// with a coarser spacing before any distance query is made.
  std::size_t maxCandidates = std::numeric_limits<std::size_t>::max();
};

struct Anchors {
  Points positions;
  Eigen::VectorXd targets;
  std::size_t candidates = 0;  ///< grid cells within the distance band
  std::size_t inside = 0, outside = 0;
  std::size_t ambiguous = 0;   ///< winding number too close to 1/2
  std::size_t disagreeing = 0; ///< the nearest samples unanimously contradict the winding number
  std::size_t crowded = 0;     ///< too close to another centre of the level
  std::size_t nearOffset = 0;  ///< within offsetClearance of an offset level
  std::size_t farOutside = 0;  ///< outside, beyond outsideMaxDistance
  bool gridTooLarge = false;
  bool tooMany = false;        ///< more than maxCandidates cells near the samples (nothing else computed)
};

/// Anchors on a cubic grid over `box`: `inputIndex` indexes the input points (normalised) with inward
/// normals `inwardNormals` and point areas `areas`; `winding` is their winding number; `centres` the
/// level's other centres. Targets are the disk-soup distance (spatial/disk_distance.hpp): the distance to
/// the nearest sample overestimates the distance to the surface by up to spacing²/(8d), and as noise
/// between neighbouring anchors it left bumps of 6% of δ on notched_cube_24k's offset.
Anchors levelAnchors(const Eigen::AlignedBox3d& box, const Points& inputPoints, const Points& inwardNormals,
                     const Eigen::VectorXd& areas, const NeighborIndex& inputIndex, const WindingNumber& winding, const Points& centres,
                     const AnchorOptions& options);

struct LevelConstraints;

/// Level k's sign anchors as fit() adds them (σ = σ_k, `spacing` the input's median spacing, normalised
/// units), appended to c's centres and targets (sources −1), with the counts and the spacing (÷ scale: input
/// units) in `report`. At most about as many anchors as the level has centres: the grid spacing doubles
/// while there would be more. `lastAnchored`: k is the finest level given anchors, whose outside band ends
/// at the level's own reach (AnchorOptions::outsideMaxDistance; those beyond count as skipped).
void addLevelAnchors(LevelConstraints& c, double sigma, double spacing, const std::vector<double>& deltas,
                     const Eigen::AlignedBox3d& anchorBox, int k, bool lastAnchored, const Points& cloud,
                     const Points& inwardNormals, const WindingNumber& winding, const NeighborIndex& index,
                     LevelReport& report, double scale);

}  // namespace duplexfit::detail
