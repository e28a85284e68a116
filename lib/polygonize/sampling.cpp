// Node sampling for polygonisation (docs/method.md §7): requests are gathered into large batches for
// the sampler (a device evaluates whole batches), validated and stored as floats in a NodeStore.
// The adaptive mode refines coarse blocks octree-style and skips blocks that cannot contain a
// crossing of any iso value under the bound |∇f| ≤ lipschitz.
#include "sampling.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <exception>
#include <limits>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "duplexfit/error.hpp"
#include "duplexfit/timer.hpp"

#ifdef _OPENMP
#include <omp.h>
#endif

namespace duplexfit::detail {

namespace {

/// Cells handled by one group of coarse block layers: bounds the block lists of the refinement.
constexpr std::int64_t kGroupCells = std::int64_t{1} << 24;

/// A box of cells [lo, hi) per axis; its corners are the nodes lo and hi.
struct Block {
  std::array<int, 3> lo;
  std::array<int, 3> hi;
};

/// Collects node requests and evaluates them in batches.
class BatchSampler {
 public:
  BatchSampler(const FieldSampler& sampler, const GridSpec& grid, NodeStore& store,
               PolygonizeStats& stats, const PolygonizeOptions& options,
               std::function<void()> onFlush)
      : sampler_(sampler),
        store_(store),
        stats_(stats),
        batch_(static_cast<std::size_t>(options.batchSize)),
        onFlush_(std::move(onFlush)),
        coords_(nodeCoordinates(grid)) {
#ifdef _OPENMP
    threads_ = options.threads > 0 ? options.threads : omp_get_max_threads();
#endif
  }

  /// Requests node (i, j, k) of the fine grid unless it is sampled or already requested.
  void request(int i, int j, int k) {
    float& v = store_.ensureTile(i, j, k)[store_.local(i, j, k)];
    if (!std::isnan(v)) return;
    v = NodeStore::kPending;
    push(i, j, k);
  }
  /// Requests a node known to be unsampled (no duplicate check).
  void push(int i, int j, int k) {
    pending_.push_back({i, j, k});
    if (pending_.size() >= batch_) flush();
  }
  /// The threads the block tests of the adaptive mode may use.
  int threads() const noexcept { return threads_; }
  /// Switches the destination between the coarse lattice and the tiles (flushes first).
  void setCoarseTarget(bool coarse) {
    flush();
    coarse_ = coarse;
  }

  void flush() {
    if (pending_.empty()) return;
    const Eigen::Index m = static_cast<Eigen::Index>(pending_.size());
    queries_.resize(m, 3);
#pragma omp parallel for schedule(static) num_threads(threads_)
    for (Eigen::Index r = 0; r < m; ++r) {
      const auto& n = pending_[static_cast<std::size_t>(r)];
      queries_(r, 0) = coords_[0][static_cast<std::size_t>(n[0])];
      queries_(r, 1) = coords_[1][static_cast<std::size_t>(n[1])];
      queries_(r, 2) = coords_[2][static_cast<std::size_t>(n[2])];
    }
    const auto start = std::chrono::steady_clock::now();
    sampler_(queries_, values_);
    stats_.samplerSeconds +=
        secondsSince(start);
    ++stats_.samplerCalls;
    if (values_.size() != m) {
      throw InvalidArgument("polygonize: the sampler returned " + std::to_string(values_.size()) +
                            " values for " + std::to_string(m) + " query points");
    }
    for (Eigen::Index r = 0; r < m; ++r) {
      if (!std::isfinite(values_(r))) badValue(r);
    }
    constexpr double kMax = static_cast<double>(std::numeric_limits<float>::max());
    for (Eigen::Index r = 0; r < m; ++r) {
      const auto& n = pending_[static_cast<std::size_t>(r)];
      const float v = static_cast<float>(std::clamp(values_(r), -kMax, kMax));
      if (coarse_) {
        store_.coarse(store_.coarseIndex(0, n[0]), store_.coarseIndex(1, n[1]),
                      store_.coarseIndex(2, n[2])) = v;
      } else {
        store_.ensureTile(n[0], n[1], n[2])[store_.local(n[0], n[1], n[2])] = v;
      }
    }
    stats_.evaluatedNodes += m;
    pending_.clear();
    if (onFlush_) onFlush_();
  }

 private:
  [[noreturn]] void badValue(Eigen::Index r) const {
    const auto& n = pending_[static_cast<std::size_t>(r)];
    std::ostringstream s;
    s.precision(17);
    s << "polygonize: the sampler returned a non-finite value (" << values_(r) << ") at grid node ("
      << n[0] << ", " << n[1] << ", " << n[2] << "), position (" << queries_(r, 0) << ", "
      << queries_(r, 1) << ", " << queries_(r, 2) << ")";
    throw InvalidArgument(s.str());
  }

  const FieldSampler& sampler_;
  NodeStore& store_;
  PolygonizeStats& stats_;
  std::size_t batch_;
  std::function<void()> onFlush_;
  std::array<std::vector<double>, 3> coords_;
  std::vector<std::array<int, 3>> pending_;
  bool coarse_ = false;
  int threads_ = 1;
  Points queries_;
  Eigen::VectorXd values_;
};

/// Full mode: every node, tile by tile (spatially coherent batches).
void sampleAll(BatchSampler& batch, NodeStore& store, const ZRange& range, const ProgressReport& report,
               double progressEnd) {
  const int t = store.tile();
  const int tzLo = range.begin / t, tzHi = std::min(store.tiles(2) - 1, range.end / t);
  for (int tz = tzLo; tz <= tzHi; ++tz) {
    for (int ty = 0; ty < store.tiles(1); ++ty) {
      for (int tx = 0; tx < store.tiles(0); ++tx) {
        const int i0 = tx * t, j0 = ty * t, k0 = tz * t;
        float* data = store.ensureTile(i0, j0, k0);
        const int i1 = std::min(i0 + t - 1, store.cells(0));
        const int j1 = std::min(j0 + t - 1, store.cells(1));
        const int k1 = std::min({k0 + t - 1, store.cells(2), range.end});
        for (int k = std::max(k0, range.begin); k <= k1; ++k) {
          for (int j = j0; j <= j1; ++j) {
            for (int i = i0; i <= i1; ++i) {
              data[store.local(i, j, k)] = NodeStore::kPending;
              batch.push(i, j, k);
              if (i < store.cells(0) && j < store.cells(1) && k < range.end) {
                store.markCell(i, j, k);
              }
            }
          }
        }
      }
    }
    if (report) report(progressEnd * (tz - tzLo + 1) / (tzHi - tzLo + 1));
  }
  batch.flush();
}

/// Adaptive mode (see PolygonizeOptions::lipschitz for the skipping rule).
class Refiner {
 public:
  Refiner(const GridSpec& grid, const std::vector<double>& isos, double lipschitz, const ZRange& range,
          NodeStore& store, BatchSampler& batch, PolygonizeStats& stats)
      : isos_(isos), lipschitz_(lipschitz), range_(range), store_(store), batch_(batch), stats_(stats) {
    const Eigen::Vector3d h = grid.cellSize();
    h_ = {h(0), h(1), h(2)};
  }

  void run(const ProgressReport& report, double progressEnd) {
    const int t = store_.tile();
    int blocks[3];
    for (int a = 0; a < 3; ++a) blocks[a] = store_.coarseCount(a) - 1;
    // The block layers of the sampled range (all of them without a slab; a slab's range is block-aligned).
    const int bzLo = range_.begin / t, bzHi = std::min(blocks[2], (range_.end + t - 1) / t);
    stats_.coarseBlocks = static_cast<std::int64_t>(blocks[0]) * blocks[1] * (bzHi - bzLo);

    // The coarse lattice, in one pass.
    store_.allocateCoarse();
    batch_.setCoarseTarget(true);
    for (int ck = bzLo; ck <= bzHi; ++ck) {
      for (int cj = 0; cj < store_.coarseCount(1); ++cj) {
        for (int ci = 0; ci < store_.coarseCount(0); ++ci) {
          batch_.push(store_.coarseNode(0, ci), store_.coarseNode(1, cj), store_.coarseNode(2, ck));
        }
      }
    }
    batch_.setCoarseTarget(false);

    // Groups of coarse block layers, refined level by level so that each level's requests form
    // large batches; nodes shared with earlier groups are never sampled twice.
    const std::int64_t layerCells = static_cast<std::int64_t>(blocks[0]) * blocks[1] * t * t * t;
    const int layersPerGroup =
        static_cast<int>(std::max<std::int64_t>(1, kGroupCells / layerCells));
    std::vector<Block> current, next;
    for (int bz0 = bzLo; bz0 < bzHi; bz0 += layersPerGroup) {
      const int bz1 = std::min(bz0 + layersPerGroup, bzHi);
      current.clear();
      for (int bz = bz0; bz < bz1; ++bz) {
        for (int by = 0; by < blocks[1]; ++by) {
          for (int bx = 0; bx < blocks[0]; ++bx) {
            Block b;
            const int idx[3] = {bx, by, bz};
            for (int a = 0; a < 3; ++a) {
              b.lo[a] = store_.coarseNode(a, idx[a]);
              b.hi[a] = store_.coarseNode(a, idx[a] + 1);
            }
            current.push_back(b);
          }
        }
      }
      for (bool coarseLevel = true; !current.empty(); coarseLevel = false) {
        next.clear();
        decide(current, false);
        for (std::size_t i = 0; i < current.size(); ++i) apply(current[i], decisions_[i], coarseLevel, next);
        batch_.flush();
        if (!deferred_.empty()) {
          // The last level's blocks that waited for their centre node (cellDecision).
          std::vector<Block> waited;
          waited.swap(deferred_);
          decide(waited, true);
          for (std::size_t i = 0; i < waited.size(); ++i) apply(waited[i], decisions_[i], false, next);
          batch_.flush();
        }
        current.swap(next);
      }
      if (report) report(progressEnd * (bz1 - bzLo) / std::max(1, bzHi - bzLo));
    }
  }

 private:
  /// True when no iso value can be reached inside block b under |∇f| ≤ L. With all corners on one
  /// side of an iso value, corner c rules out the ball of radius ρ_c = |f_c − iso| / L around it.
  /// Cutting the block at any inner point m into 8 boxes, the box spanned by c and m lies within
  /// |m − c| of c, so the block is ruled out when |m − c| < ρ_c for every corner. m = the centre
  /// gives "every ρ_c > half the diagonal"; a point moved toward the corners with small ρ is tried
  /// too, which lets blocks on a slope be skipped closer to the surface.
  bool skippable(const Block& b) const {
    double f[8];
    for (int c = 0; c < 8; ++c) {
      f[c] = static_cast<double>(store_.value(
          (c & 1) ? b.hi[0] : b.lo[0], (c & 2) ? b.hi[1] : b.lo[1], (c & 4) ? b.hi[2] : b.lo[2]));
      if (!std::isfinite(f[c])) return false;  // defensive: never skip on missing data
    }
    double e[3];
    for (int a = 0; a < 3; ++a) e[a] = (b.hi[a] - b.lo[a]) * h_[a];
    const double lo = *std::min_element(f, f + 8), hi = *std::max_element(f, f + 8);
    for (double iso : isos_) {
      if (!(lo > iso || hi < iso)) return false;  // a corner on each side (or on iso)
      double rho2[8];
      for (int c = 0; c < 8; ++c) {
        const double r = std::abs(f[c] - iso) / lipschitz_;
        rho2[c] = r * r;
      }
      if (!coveredFrom(centre(e), e, rho2) && !coveredFrom(radicalPoint(e, rho2), e, rho2)) {
        return false;
      }
    }
    return true;
  }

  static std::array<double, 3> centre(const double e[3]) {
    return {0.5 * e[0], 0.5 * e[1], 0.5 * e[2]};
  }

  /// Per axis, the radical plane of the mean squared radii of the two opposite faces' corners:
  /// where a low-face and a high-face ball of those radii reach equally far.
  static std::array<double, 3> radicalPoint(const double e[3], const double rho2[8]) {
    std::array<double, 3> m{};
    for (int a = 0; a < 3; ++a) {
      double low = 0.0, high = 0.0;
      for (int c = 0; c < 8; ++c) ((c >> a) & 1 ? high : low) += 0.25 * rho2[c];
      m[a] = e[a] > 0.0 ? std::clamp((low - high + e[a] * e[a]) / (2.0 * e[a]), 0.0, e[a]) : 0.0;
    }
    return m;
  }

  /// True when |m − c|² < ρ_c² for all 8 corners c (block-local coordinates, corner 0 at 0).
  static bool coveredFrom(const std::array<double, 3>& m, const double e[3], const double rho2[8]) {
    for (int c = 0; c < 8; ++c) {
      double d2 = 0.0;
      for (int a = 0; a < 3; ++a) {
        const double d = ((c >> a) & 1 ? e[a] : 0.0) - m[a];
        d2 += d * d;
      }
      if (!(d2 < rho2[c])) return false;
    }
    return true;
  }

  /// What a block's tests decided: skipped, halved, the cells of a last-level block to sample (a bit
  /// each, in z, y, x order of the block's cells), or (a last-level block with every corner on one side)
  /// its centre node first, the block tested again once it is known.
  struct Decision {
    enum Kind : std::uint8_t { Skip, Halve, Cells, Centre } kind = Skip;
    std::uint8_t cells = 0;
  };
  /// Per-thread scratch of the cell tests.
  struct Scratch {
    std::vector<char> oneSide;
    std::vector<std::array<double, 9>> rho2;
  };

  /// decisions_[i] for blocks[i]: the tests only read node values sampled before (the corners, and the
  /// centres of `withCentre` blocks), so they run on the sampler's threads, and their requests are made
  /// afterwards in block order (the same requests and batches as one thread would make).
  void decide(const std::vector<Block>& blocks, bool withCentre) {
    decisions_.assign(blocks.size(), Decision{});
    const auto n = static_cast<long long>(blocks.size());
    std::exception_ptr error;  // an allocation of the scratch failing, caught where it happened
#pragma omp parallel num_threads(std::max(1, batch_.threads())) if (n > 256)
    {
      Scratch scratch;
#pragma omp for schedule(dynamic, 256)
      for (long long i = 0; i < n; ++i) {
        const Block& b = blocks[static_cast<std::size_t>(i)];
        Decision& d = decisions_[static_cast<std::size_t>(i)];
        try {
          int maxExtent = 0;
          for (int a = 0; a < 3; ++a) maxExtent = std::max(maxExtent, b.hi[a] - b.lo[a]);
          if (withCentre) {
            d = cellDecision(b, true, scratch);
          } else if (skippable(b)) {
            d.kind = Decision::Skip;
          } else if (maxExtent <= 2) {
            d = cellDecision(b, false, scratch);
          } else {
            d.kind = Decision::Halve;
          }
        } catch (...) {
#pragma omp critical(duplexfit_sampling_error)
          if (!error) error = std::current_exception();
        }
      }
    }
    if (error) std::rethrow_exception(error);
  }

  /// The requests of block b's decision (and its children into `next`).
  void apply(const Block& b, const Decision& d, bool coarseLevel, std::vector<Block>& next) {
    if (d.kind == Decision::Skip) return;
    if (coarseLevel) ++stats_.refinedBlocks;
    if (d.kind == Decision::Centre) {
      batch_.request(b.lo[0] + 1, b.lo[1] + 1, b.lo[2] + 1);
      deferred_.push_back(b);
      return;
    }
    if (d.kind == Decision::Cells) {
      int bit = 0;
      for (int k = b.lo[2]; k < b.hi[2]; ++k) {
        for (int j = b.lo[1]; j < b.hi[1]; ++j) {
          for (int i = b.lo[0]; i < b.hi[0]; ++i, ++bit) {
            if (((d.cells >> bit) & 1) == 0) continue;
            for (int corner = 0; corner < 8; ++corner) {
              batch_.request(i + (corner & 1), j + ((corner >> 1) & 1), k + ((corner >> 2) & 1));
            }
            store_.markCell(i, j, k);
          }
        }
      }
      return;
    }
    // Halve every axis with at least 2 cells; sample the new lattice nodes; test the children at
    // the next level.
    int cuts[3][3], counts[3];
    for (int a = 0; a < 3; ++a) {
      const int e = b.hi[a] - b.lo[a];
      counts[a] = 0;
      cuts[a][counts[a]++] = b.lo[a];
      if (e >= 2) cuts[a][counts[a]++] = b.lo[a] + e / 2;
      cuts[a][counts[a]] = b.hi[a];
    }
    for (int z = 0; z <= counts[2]; ++z) {
      for (int y = 0; y <= counts[1]; ++y) {
        for (int x = 0; x <= counts[0]; ++x) batch_.request(cuts[0][x], cuts[1][y], cuts[2][z]);
      }
    }
    for (int z = 0; z < counts[2]; ++z) {
      for (int y = 0; y < counts[1]; ++y) {
        for (int x = 0; x < counts[0]; ++x) {
          next.push_back(Block{{cuts[0][x], cuts[1][y], cuts[2][z]},
                               {cuts[0][x + 1], cuts[1][y + 1], cuts[2][z + 1]}});
        }
      }
    }
  }

  /// The last level (blocks of at most 2 cells per edge): each cell is tested before any of its
  /// nodes is sampled, against the balls of the block's 8 sampled corners (radius |f − c| / L;
  /// f ≠ c inside each). A connected cell covered by such balls holds no point with f = c, so its
  /// corners all lie on one side of c and it has no crossing. Only the cells not covered for some
  /// iso value get their nodes sampled and are contoured (the Cells decision lists them).
  ///
  /// A block of 2 × 2 × 2 cells whose corners lie on one side of every iso value but whose balls
  /// leave a cell uncovered first has its centre node sampled (`withCentre` false: the Centre decision,
  /// the block deferred to a second pass after the batch). The centre is a corner of all 8 cells, so it is
  /// never wasted where a cell is sampled, and its ball covers a cell together with the opposite
  /// block corner's wherever both lie about L times the cell's edge from the level: the band of
  /// sampled cells on either side of a surface narrows (fandisk_550k: about 3.9 nodes evaluated per
  /// node of a crossed cell before). A centre on the other side of an iso value makes the block a
  /// crossing one for it: every cell is then sampled, as for a corner there.
  Decision cellDecision(const Block& b, bool withCentre, Scratch& scratch) const {
    double f[8];
    for (int c = 0; c < 8; ++c) {
      f[c] = static_cast<double>(store_.value(
          (c & 1) ? b.hi[0] : b.lo[0], (c & 2) ? b.hi[1] : b.lo[1], (c & 4) ? b.hi[2] : b.lo[2]));
    }
    const bool full = b.hi[0] - b.lo[0] == 2 && b.hi[1] - b.lo[1] == 2 && b.hi[2] - b.lo[2] == 2;
    const int mid[3] = {b.lo[0] + 1, b.lo[1] + 1, b.lo[2] + 1};
    double fc = 0.0;
    if (withCentre) fc = static_cast<double>(store_.value(mid[0], mid[1], mid[2]));
    // Per iso value: whether all corners (and the centre, when known) lie strictly on one side (with a
    // sign change every cell is sampled, as the coarser levels do, so that a field steeper than the
    // bound still gives the continuation surfaces to follow), and the squared ball radii.
    std::vector<char>& oneSide = scratch.oneSide;
    std::vector<std::array<double, 9>>& rho2 = scratch.rho2;
    oneSide.assign(isos_.size(), 0);
    rho2.resize(isos_.size());
    bool allOneSide = true;
    for (std::size_t q = 0; q < isos_.size(); ++q) {
      int above = 0, below = 0;
      for (int c = 0; c < 8; ++c) {
        above += f[c] > isos_[q];
        below += f[c] < isos_[q];
        const double r = std::abs(f[c] - isos_[q]) / lipschitz_;
        rho2[q][static_cast<std::size_t>(c)] = r * r;
      }
      oneSide[q] = above == 8 || below == 8;  // false for a NaN corner too
      if (withCentre) {
        oneSide[q] = oneSide[q] && (above == 8 ? fc > isos_[q] : fc < isos_[q]);
        const double r = std::abs(fc - isos_[q]) / lipschitz_;
        rho2[q][8] = r * r;
      } else {
        rho2[q][8] = 0.0;
      }
      allOneSide = allOneSide && oneSide[q];
    }
    Balls balls;
    balls.count = withCentre ? 9 : 8;
    for (int c = 0; c < 8; ++c) {
      for (int a = 0; a < 3; ++a) {
        balls.centre[c][a] = ((c >> a) & 1 ? b.hi[a] - b.lo[a] : 0) * h_[a];
      }
    }
    for (int a = 0; a < 3; ++a) balls.centre[8][a] = h_[a];
    const auto covered = [&](int i, int j, int k) {
      const int idx[3] = {i, j, k};
      std::array<double, 3> lo{}, hi{};
      for (int a = 0; a < 3; ++a) {
        lo[a] = (idx[a] - b.lo[a]) * h_[a];
        hi[a] = lo[a] + h_[a];
      }
      bool all = true;
      for (std::size_t q = 0; q < isos_.size() && all; ++q) {
        all = oneSide[q] && (balls.rho2 = rho2[q], balls.cover(lo, hi, kCoverDepth));
      }
      return all;
    };
    Decision d;
    d.kind = Decision::Cells;
    if (!withCentre && full && allOneSide) {
      bool any = false;
      for (int k = b.lo[2]; k < b.hi[2] && !any; ++k) {
        for (int j = b.lo[1]; j < b.hi[1] && !any; ++j) {
          for (int i = b.lo[0]; i < b.hi[0] && !any; ++i) any = !covered(i, j, k);
        }
      }
      if (any) d.kind = Decision::Centre;
      return d;
    }
    int bit = 0;
    for (int k = b.lo[2]; k < b.hi[2]; ++k) {
      for (int j = b.lo[1]; j < b.hi[1]; ++j) {
        for (int i = b.lo[0]; i < b.hi[0]; ++i, ++bit) {
          if (!covered(i, j, k)) d.cells = static_cast<std::uint8_t>(d.cells | (1U << bit));
        }
      }
    }
    return d;
  }

  /// Subdivisions tried when covering a cell by balls (each halves the box on every axis).
  static constexpr int kCoverDepth = 2;

  /// Open balls around a block's corners and (the 9th, when count is 9) its centre, in block-local
  /// coordinates.
  struct Balls {
    int count = 8;
    double centre[9][3];
    std::array<double, 9> rho2;

    /// True when the box [lo, hi] lies in the union of the balls: in one ball, or (depth > 0) each
    /// of its 8 halves is covered. A box whose centre is in no ball is never covered.
    bool cover(const std::array<double, 3>& lo, const std::array<double, 3>& hi, int depth) const {
      std::array<double, 3> mid{};
      for (int a = 0; a < 3; ++a) mid[a] = 0.5 * (lo[a] + hi[a]);
      bool centreIn = false;
      for (int c = 0; c < count; ++c) {
        double far2 = 0.0, mid2 = 0.0;
        for (int a = 0; a < 3; ++a) {
          const double d = std::max(std::abs(lo[a] - centre[c][a]), std::abs(hi[a] - centre[c][a]));
          const double m = mid[a] - centre[c][a];
          far2 += d * d;
          mid2 += m * m;
        }
        if (far2 < rho2[c]) return true;
        centreIn = centreIn || mid2 < rho2[c];
      }
      if (!centreIn || depth == 0) return false;
      for (int s = 0; s < 8; ++s) {
        std::array<double, 3> l{}, u{};
        for (int a = 0; a < 3; ++a) {
          l[a] = (s >> a) & 1 ? mid[a] : lo[a];
          u[a] = (s >> a) & 1 ? hi[a] : mid[a];
        }
        if (!cover(l, u, depth - 1)) return false;
      }
      return true;
    }
  };

  const std::vector<double>& isos_;
  double lipschitz_;
  ZRange range_;
  std::vector<Decision> decisions_;          ///< decide's results, a block each
  std::vector<Block> deferred_;              ///< last-level blocks waiting for their centre node
  NodeStore& store_;
  BatchSampler& batch_;
  PolygonizeStats& stats_;
  std::array<double, 3> h_{};
};

}  // namespace

const std::array<std::array<int, 3>, 6>& cellFaces() {
  // Corner c has bit 0 = +x, bit 1 = +y, bit 2 = +z; a face's mask lists its 4 corners.
  static const std::array<std::array<int, 3>, 6> faces = {
      {{0, -1, 0x55}, {0, +1, 0xAA}, {1, -1, 0x33}, {1, +1, 0xCC}, {2, -1, 0x0F}, {2, +1, 0xF0}}};
  return faces;
}

std::array<std::vector<double>, 3> nodeCoordinates(const GridSpec& grid) {
  std::array<std::vector<double>, 3> c;
  for (int a = 0; a < 3; ++a) {
    const int n = grid.cells(a);
    c[a].resize(static_cast<std::size_t>(n) + 1);
    for (int i = 0; i <= n; ++i) {
      c[a][static_cast<std::size_t>(i)] =
          nodeCoordinate(grid.box.min()(a), grid.box.max()(a), n, i);
    }
  }
  return c;
}

void sampleNodes(const FieldSampler& sampler, const GridSpec& grid,
                 const std::vector<double>& isoValues, const PolygonizeOptions& options,
                 const ProgressReport& report, double progressEnd, NodeStore& store,
                 PolygonizeStats& stats) {
  // Cancellation is checked after every sampler call; fractions there are coarse estimates.
  double lastFraction = 0.0;
  const ProgressReport tracked = [&](double f) {
    lastFraction = f;
    if (report) report(f);
  };
  BatchSampler batch(sampler, grid, store, stats, options, [&] {
    if (report) report(lastFraction);
  });
  const ZRange range = sampledCells(options, grid.cells(2));
  if (options.adaptive) {
    Refiner(grid, isoValues, options.lipschitz, range, store, batch, stats).run(tracked, progressEnd);
  } else {
    sampleAll(batch, store, range, tracked, progressEnd);
  }
}

ZRange slabCells(const PolygonizeOptions& options, int nz) {
  return {options.slabBegin, options.slabEnd < 0 ? nz : options.slabEnd};
}

ZRange sampledCells(const PolygonizeOptions& options, int nz) {
  const ZRange slab = slabCells(options, nz);
  if (slab.begin == 0 && slab.end == nz) return slab;
  const int t = options.coarseStep, halo = slabHalo(options);
  const int lo = std::max(0, slab.begin - halo) / t * t;
  const int hi = std::min(nz, (slab.end + halo + t - 1) / t * t);
  return {lo, hi};
}

std::int64_t closeSurfaces(const FieldSampler& sampler, const GridSpec& grid,
                           const std::vector<double>& isoValues, const PolygonizeOptions& options,
                           const ProgressReport& report, double progress, NodeStore& store,
                           PolygonizeStats& stats, std::vector<std::array<int, 3>> cells,
                           std::vector<char>* changedZ) {
  BatchSampler batch(sampler, grid, store, stats, options, [&] {
    if (report) report(progress);
  });
  std::int64_t added = 0;
  std::vector<std::array<int, 3>> next;
  const ZRange range = sampledCells(options, grid.cells(2));
  while (!cells.empty()) {
    // Mark and sample this round's cells (each once), then look across their faces.
    cells.erase(std::remove_if(cells.begin(), cells.end(), [&range](const std::array<int, 3>& c) { return !range.contains(c[2]); }),
                cells.end());
    std::sort(cells.begin(), cells.end());
    cells.erase(std::unique(cells.begin(), cells.end()), cells.end());
    std::size_t kept = 0;
    for (const auto& c : cells) {
      if (store.cellMarked(c[0], c[1], c[2])) continue;
      store.markCell(c[0], c[1], c[2]);
      if (changedZ != nullptr) (*changedZ)[static_cast<std::size_t>(c[2])] = 1;
      for (int corner = 0; corner < 8; ++corner) {
        batch.request(c[0] + (corner & 1), c[1] + ((corner >> 1) & 1), c[2] + ((corner >> 2) & 1));
      }
      cells[kept++] = c;
    }
    cells.resize(kept);
    batch.flush();
    added += static_cast<std::int64_t>(kept);
    next.clear();
    for (const auto& c : cells) {
      float v[8];
      for (int corner = 0; corner < 8; ++corner) {
        v[corner] = store.value(c[0] + (corner & 1), c[1] + ((corner >> 1) & 1),
                                c[2] + ((corner >> 2) & 1));
      }
      appendOpenNeighbours(store, c, v, isoValues, next);
    }
    cells.swap(next);
  }
  return added;
}

void appendOpenNeighbours(const NodeStore& store, const std::array<int, 3>& cell, const float* v,
                          const std::vector<double>& isoValues,
                          std::vector<std::array<int, 3>>& out) {
  int crossed = 0;  // faces with a sign change for some iso value
  for (double iso : isoValues) {
    int mask = 0;
    for (int c = 0; c < 8; ++c) mask |= (static_cast<double>(v[c]) >= iso) << c;
    for (int f = 0; f < 6; ++f) {
      const int fm = cellFaces()[static_cast<std::size_t>(f)][2];
      if ((mask & fm) != 0 && (mask & fm) != fm) crossed |= 1 << f;
    }
  }
  for (int f = 0; f < 6; ++f) {
    if (((crossed >> f) & 1) == 0) continue;
    const auto& face = cellFaces()[static_cast<std::size_t>(f)];
    std::array<int, 3> n = cell;
    n[static_cast<std::size_t>(face[0])] += face[1];
    if (n[static_cast<std::size_t>(face[0])] < 0 ||
        n[static_cast<std::size_t>(face[0])] >= store.cells(face[0])) {
      continue;  // the grid boundary: the surface stays open there
    }
    if (!store.cellMarked(n[0], n[1], n[2])) out.push_back(n);
  }
}

}  // namespace duplexfit::detail
