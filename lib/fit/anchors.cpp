// Sign anchors of one level (see anchors.hpp): cubic grid cells near enough to the samples for the level's
// supports to matter there, far enough for the winding number to be reliable, classified inside/outside.
#include "fit/anchors.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <numeric>
#include <vector>

#include "duplexfit/fit.hpp"
#include "duplexfit/neighbors.hpp"
#include "duplexfit/winding.hpp"
#include "fit/constraints.hpp"
#include "spatial/disk_distance.hpp"
#include "spatial/morton.hpp"

namespace duplexfit::detail {

namespace {

/// The winding number's quick pass (see levelAnchors): its β, and how close to a threshold its value must
/// come for the tree's own β to decide.
constexpr double kQuickBeta = 2.0;
constexpr double kQuickMargin = 0.2;

}  // namespace

Anchors levelAnchors(const Eigen::AlignedBox3d& box, const Points& inputPoints, const Points& inwardNormals,
                     const Eigen::VectorXd& areas, const NeighborIndex& inputIndex, const WindingNumber& winding, const Points& centres,
                     const AnchorOptions& o) {
  Anchors out;
  if (!(o.spacing > 0.0) || inputPoints.rows() == 0) return out;
  const Eigen::Vector3d extent = box.sizes();
  Eigen::Array3i n;
  std::size_t total = 1;
  for (int a = 0; a < 3; ++a) {
    const double cells = std::ceil(extent[a] / o.spacing);
    if (!(cells < 1e6)) {
      out.gridTooLarge = true;
      return out;
    }
    n[a] = std::max(1, static_cast<int>(cells));
    total *= static_cast<std::size_t>(n[a]);
  }
  if (total > o.maxCells) {
    out.gridTooLarge = true;
    return out;
  }
  // Grid centred on the box.
  const Eigen::Vector3d lo = box.center() - 0.5 * o.spacing * n.cast<double>().matrix();
  auto cellOf = [&](const Eigen::Vector3d& p, int a) {
    const double t = (p[a] - lo[a]) / o.spacing;
    return std::clamp(static_cast<int>(std::floor(t)), 0, n[a] - 1);
  };
  auto linear = [&](int i, int j, int k) {
    return (static_cast<std::size_t>(k) * static_cast<std::size_t>(n[1]) + static_cast<std::size_t>(j)) *
               static_cast<std::size_t>(n[0]) + static_cast<std::size_t>(i);
  };

  // Cells within `rings` (Chebyshev, in cells) of an occupied cell: a multi-source breadth-first search.
  std::vector<std::uint8_t> ring(total, 255);
  const int rings = o.maxDistance > 0.0 ? std::min(250, static_cast<int>(std::ceil(o.maxDistance / o.spacing)) + 1) : -1;
  std::vector<std::size_t> frontier;
  bool clamped = false;  // a point outside the grid went to a boundary cell: the ring bounds below do not hold
  if (rings >= 0) {
    for (Eigen::Index r = 0; r < inputPoints.rows(); ++r) {
      const Eigen::Vector3d p = inputPoints.row(r).transpose();
      for (int a = 0; a < 3; ++a) {
        const double t = (p[a] - lo[a]) / o.spacing;
        clamped = clamped || !(t >= 0.0 && t < n[a]);
      }
      const std::size_t c = linear(cellOf(p, 0), cellOf(p, 1), cellOf(p, 2));
      if (ring[c] != 0) {
        ring[c] = 0;
        frontier.push_back(c);
      }
    }
    for (int step = 1; step <= rings && !frontier.empty(); ++step) {
      std::vector<std::size_t> next;
      for (const std::size_t c : frontier) {
        const int i = static_cast<int>(c % static_cast<std::size_t>(n[0]));
        const int j = static_cast<int>((c / static_cast<std::size_t>(n[0])) % static_cast<std::size_t>(n[1]));
        const int k = static_cast<int>(c / (static_cast<std::size_t>(n[0]) * static_cast<std::size_t>(n[1])));
        for (int dk = -1; dk <= 1; ++dk) {
          for (int dj = -1; dj <= 1; ++dj) {
            for (int di = -1; di <= 1; ++di) {
              const int ii = i + di, jj = j + dj, kk = k + dk;
              if (ii < 0 || jj < 0 || kk < 0 || ii >= n[0] || jj >= n[1] || kk >= n[2]) continue;
              const std::size_t m = linear(ii, jj, kk);
              if (ring[m] == 255) {
                ring[m] = static_cast<std::uint8_t>(step);
                next.push_back(m);
              }
            }
          }
        }
      }
      frontier.swap(next);
    }
  }
  // A cell at Chebyshev distance r (in cells) from the nearest occupied cell has its centre at least
  // (r − 1/2)·spacing from every input point (along one axis) and at most √3·(r + 1/2)·spacing from one.
  // Rings that cannot reach the distance band (the occupied cells themselves at the σ_k/2 spacing, the
  // last ring) are counted as candidates for maxCandidates but never queried; the band test decides the same
  // for them, so the anchors are the same.
  const auto mayBeInBand = [&](int r) {
    if (rings < 0 || clamped) return true;
    const double nearest = std::max(0.0, r - 0.5) * o.spacing, farthest = std::sqrt(3.0) * (r + 0.5) * o.spacing;
    if (farthest < o.minDistance * (1.0 - 1e-9)) return false;
    return !(o.maxDistance > 0.0 && nearest > o.maxDistance * (1.0 + 1e-9));
  };
  std::vector<Eigen::Vector3d> cand;
  std::vector<std::uint64_t> candKey;  // the Morton code of each candidate's cell (integer indices)
  std::size_t nearCells = 0;
  for (int k = 0; k < n[2]; ++k) {
    for (int j = 0; j < n[1]; ++j) {
      for (int i = 0; i < n[0]; ++i) {
        const int r = rings >= 0 ? ring[linear(i, j, k)] : 0;
        if (rings >= 0 && r == 255) continue;
        ++nearCells;
        if (!mayBeInBand(r)) continue;
        cand.push_back(lo + o.spacing * Eigen::Vector3d(i + 0.5, j + 0.5, k + 0.5));
        candKey.push_back(spreadBits(static_cast<std::uint64_t>(i)) | (spreadBits(static_cast<std::uint64_t>(j)) << 1) |
                          (spreadBits(static_cast<std::uint64_t>(k)) << 2));
      }
    }
  }
  if (nearCells > o.maxCandidates) {
    out.tooMany = true;
    return out;
  }
  Points q(static_cast<Eigen::Index>(cand.size()), 3);
  for (std::size_t r = 0; r < cand.size(); ++r) q.row(static_cast<Eigen::Index>(r)) = cand[r].transpose();

  // Distance band: the nearest input point of every candidate; the band's candidates then get their
  // kNear nearest (the search is exact and sorted by distance and index, so the first agreeNeighbors of
  // them are the votes' neighbours and all of them the disk-soup distance's).
  // With an upper end, a search that never looks beyond it (the same nearest point within it; none beyond,
  // where the band test drops the candidate anyway).
  const NeighborLists nearest = o.maxDistance > 0.0 && std::isfinite(o.maxDistance)
                                    ? inputIndex.nearestWithin(q, o.maxDistance)
                                    : inputIndex.knnSearch(q, 1);
  std::vector<Eigen::Index> band;
  std::vector<double> bandDistance;
  for (Eigen::Index r = 0; r < q.rows(); ++r) {
    const auto ur = static_cast<std::size_t>(r);
    if (nearest.count(ur) == 0) continue;
    const double d = nearest.distances[static_cast<std::size_t>(nearest.offsets[ur])];
    if (d < o.minDistance || (o.maxDistance > 0.0 && d > o.maxDistance)) continue;
    band.push_back(r);
    bandDistance.push_back(d);
  }
  out.candidates = band.size();
  if (band.empty()) return out;
  Points bq(static_cast<Eigen::Index>(band.size()), 3);
  for (std::size_t r = 0; r < band.size(); ++r) bq.row(static_cast<Eigen::Index>(r)) = q.row(band[r]);

  std::vector<char> clear(band.size(), 1);
  if (centres.rows() > 0 && o.centreClearance > 0.0) {
    const NeighborIndex centreIndex(centres);
    // Only whether a centre is nearer than the clearance counts: a search that never looks beyond it.
    const NeighborLists nc = std::isfinite(o.centreClearance) ? centreIndex.nearestWithin(bq, o.centreClearance)
                                                               : centreIndex.knnSearch(bq, 1);
    for (std::size_t r = 0; r < band.size(); ++r) {
      if (nc.count(r) > 0 && nc.distances[static_cast<std::size_t>(nc.offsets[r])] < o.centreClearance) clear[r] = 0;
    }
  }
  const int kAgree = std::max(1, std::min<int>(o.agreeNeighbors, static_cast<int>(inputPoints.rows())));
  const int kNear = std::max(kAgree, std::min<int>(kDiskNeighbours, static_cast<int>(inputPoints.rows())));
  // The winding number decides only by its thresholds (ambiguity and 1 − ambiguity): a quick pass at
  // β = 2 (half the time of the tree's β = 3), then the tree's own β wherever the quick value lies within
  // kQuickMargin of a threshold. Three spacings or more from the samples, where every anchor lies, the
  // quick pass differs from β = 3 by at most 0.06 on the shared clouds measured (test_winding asserts
  // ≤ 0.1), so every decision is β = 3's. Only the candidates the crowding test keeps are asked (a crowded
  // one is dropped whatever its side; w stays 1/2 there, unread).
  Eigen::VectorXd w = Eigen::VectorXd::Constant(static_cast<Eigen::Index>(band.size()), 0.5);
  {
    std::vector<Eigen::Index> open;
    open.reserve(band.size());
    for (std::size_t r = 0; r < band.size(); ++r) {
      if (clear[r] != 0) open.push_back(static_cast<Eigen::Index>(r));
    }
    const Eigen::VectorXd quick = winding.evaluate(bq(open, Eigen::all), kQuickBeta);
    std::vector<Eigen::Index> again;
    for (std::size_t i = 0; i < open.size(); ++i) {
      const double v = quick[static_cast<Eigen::Index>(i)];
      w[open[i]] = v;
      if (std::abs(v - o.ambiguity) < kQuickMargin || std::abs(v - (1.0 - o.ambiguity)) < kQuickMargin) {
        again.push_back(open[i]);
      }
    }
    const Eigen::VectorXd exactEnough = winding.evaluate(bq(again, Eigen::all));
    for (std::size_t r = 0; r < again.size(); ++r) w[again[r]] = exactEnough[static_cast<Eigen::Index>(r)];
  }
  // The nearest samples (votes and disk-soup distances) only for the candidates the tests so far keep: not
  // crowded, not ambiguous and, outside, within outsideMaxDistance. keptAt: a band row's row in kq (none:
  // dropped by one of those tests).
  constexpr std::size_t kNone = std::numeric_limits<std::size_t>::max();
  std::vector<std::size_t> keptAt(band.size(), kNone);
  std::vector<std::size_t> kept;
  for (std::size_t r = 0; r < band.size(); ++r) {
    const double wr = w[static_cast<Eigen::Index>(r)];
    if (clear[r] == 0 || (wr > o.ambiguity && wr < 1.0 - o.ambiguity)) continue;
    if (wr < 0.5 && o.outsideMaxDistance > 0.0 && bandDistance[r] > o.outsideMaxDistance) continue;
    keptAt[r] = kept.size();
    kept.push_back(r);
  }
  Points kq(static_cast<Eigen::Index>(kept.size()), 3);
  for (std::size_t i = 0; i < kept.size(); ++i) kq.row(static_cast<Eigen::Index>(i)) = bq.row(static_cast<Eigen::Index>(kept[i]));
  const NeighborLists near = inputIndex.knnSearch(kq, kNear);
  const Eigen::VectorXd disk =
      diskSoupDistance(kq, inputPoints, inwardNormals, areas, near, std::min<int>(kNear, kDiskNeighbours));

  std::vector<Eigen::Vector3d> pos;
  std::vector<double> target;
  std::vector<std::uint64_t> posKey;
  for (std::size_t r = 0; r < band.size(); ++r) {
    if (clear[r] == 0) {
      ++out.crowded;
      continue;
    }
    const double wr = w[static_cast<Eigen::Index>(r)];
    if (wr > o.ambiguity && wr < 1.0 - o.ambiguity) {
      ++out.ambiguous;
      continue;
    }
    const std::size_t kr = keptAt[r];
    if (kr == kNone) {  // neither crowded nor ambiguous: outside, beyond outsideMaxDistance
      ++out.farOutside;
      continue;
    }
    const bool inside = wr >= 0.5;
    // The nearest samples' tangent planes: (c − p)·ν > 0 puts c on the inner side of p.
    int agree = 0, votes = 0;
    const auto votesEnd = std::min(near.offsets[kr + 1], near.offsets[kr] + kAgree);
    for (auto e = near.offsets[kr]; e < votesEnd; ++e) {
      const Index j = near.indices[static_cast<std::size_t>(e)];
      if (inwardNormals.row(j).squaredNorm() == 0.0) continue;
      const double s = (bq.row(static_cast<Eigen::Index>(r)) - inputPoints.row(j)).dot(inwardNormals.row(j));
      ++votes;
      agree += (s > 0.0) == inside ? 1 : 0;
    }
    if (votes > 0 && agree == 0) {
      ++out.disagreeing;
      continue;
    }
    bool nearOffset = false;
    for (const double delta : o.offsets) {
      if ((delta > 0.0) == inside && std::abs(bandDistance[r] - std::abs(delta)) < o.offsetClearance) nearOffset = true;
    }
    if (nearOffset) {
      ++out.nearOffset;
      continue;
    }
    (inside ? out.inside : out.outside) += 1;
    pos.push_back(bq.row(static_cast<Eigen::Index>(r)).transpose());
    target.push_back((inside ? 1.0 : -1.0) * std::min(disk[static_cast<Eigen::Index>(kr)], o.clamp));
    posKey.push_back(candKey[static_cast<std::size_t>(band[r])]);
  }
  // The anchors in the Morton order of their grid cells (integer indices, so no rounding can reorder
  // them), not the grid's row order: they follow the level's Morton-sorted constraints in the system, and
  // so each block of its block Jacobi preconditioner holds nearby anchors and an anchor's neighbours lie
  // near it in memory. fandisk_550k: level 8's solve 2.3–3.5 → 2.1–2.2 s, the fit 21.1–23.5 → 20.5–20.9 s
  // (docs/benchmarks.md). Sorting them in among the constraints was faster still but let rounding-level
  // changes of the input reorder the rows.
  std::vector<std::size_t> order(pos.size());
  std::iota(order.begin(), order.end(), std::size_t{0});
  std::stable_sort(order.begin(), order.end(), [&posKey](std::size_t a, std::size_t b) { return posKey[a] < posKey[b]; });
  out.positions.resize(static_cast<Eigen::Index>(pos.size()), 3);
  out.targets.resize(static_cast<Eigen::Index>(pos.size()));
  for (std::size_t r = 0; r < pos.size(); ++r) {
    out.positions.row(static_cast<Eigen::Index>(r)) = pos[order[r]].transpose();
    out.targets[static_cast<Eigen::Index>(r)] = target[order[r]];
  }
  return out;
}

void addLevelAnchors(LevelConstraints& c, double sigma, double spacing, const std::vector<double>& deltas,
                     const Eigen::AlignedBox3d& anchorBox, int k, bool lastAnchored, const Points& cloud,
                     const Points& inwardNormals, const WindingNumber& winding, const NeighborIndex& index,
                     LevelReport& report, double scale) {
  AnchorOptions ao;
  ao.spacing = sigma / 2.0;
  // Lower bound 3σ_k/4: at σ_k/2, anchors next to the offset band left bumps of 4.5% of δ on
  // notched_cube_24k's inner offset (0.9% at 3σ_k/4); at σ_k the hole of thin_torus_20k refills.
  ao.minDistance = std::max(0.75 * sigma, 3.0 * spacing);
  ao.maxDistance = k == 1 ? 0.0 : 2.0 * sigma;
  // At the finest anchored level, outside the solid, only as far as the level's own bumps reach and at least
  // to 1.5σ_k = 0.75σ_{k−1}, where the coarser level's outside anchors begin: the anchors beyond only repeat
  // what level k − 1 set, and they were a fifth of fandisk_550k's level-8 centres, examined by every
  // evaluation near the surface (docs/method.md, "Sign of empty space"). The bumps of the surface and
  // off-surface centres (σ_k/10 out) end within 1.5σ_k; an outward offset's, σ_k beyond |δ|.
  if (lastAnchored && k > 1) {
    double outward = 0.0;
    for (const double d : deltas) outward = std::max(outward, -d);
    const double reach = std::max(1.5 * sigma, sigma + outward);
    if (reach < ao.maxDistance && reach > ao.minDistance) ao.outsideMaxDistance = reach;
  }
  ao.centreClearance = sigma / 4.0;
  ao.offsets = deltas;
  ao.offsetClearance = sigma / 2.0;
  // At most about a quarter as many anchors as the level has centres: where the σ_k/2 grid would give
  // more (fine levels of dense clouds: fandisk_550k's level 8 had 646k anchors beside 588k centres,
  // 1.7x the fit's CPU time), the spacing doubles.
  const auto cap = std::max<std::size_t>(256, static_cast<std::size_t>(c.centres.rows()));
  ao.maxCandidates = 4 * cap;
  Anchors an;
  double usedSpacing = ao.spacing;
  for (int attempt = 0; attempt < 4; ++attempt) {
    usedSpacing = ao.spacing;
    an = levelAnchors(anchorBox, cloud, inwardNormals, winding.areas(), index, winding, c.centres, ao);
    if (!an.tooMany && static_cast<std::size_t>(an.positions.rows()) <= cap) break;
    ao.spacing *= 2.0;
    if (attempt == 2) ao.maxCandidates = std::numeric_limits<std::size_t>::max();
  }
  report.anchorSpacing = usedSpacing / scale;
  report.anchorsInside = an.inside;
  report.anchorsOutside = an.outside;
  report.anchorsSkipped = an.ambiguous + an.disagreeing + an.crowded + an.nearOffset + an.farOutside;
  const Eigen::Index base = c.centres.rows(), extra = an.positions.rows();
  c.centres.conservativeResize(base + extra, 3);
  c.centres.bottomRows(extra) = an.positions;
  c.targets.conservativeResize(base + extra);
  c.targets.tail(extra) = an.targets;
  // One source per centre (the point each came from); anchors have none.
  if (c.sources.size() == static_cast<std::size_t>(base)) c.sources.resize(static_cast<std::size_t>(base + extra), -1);
}

}  // namespace duplexfit::detail
