// The self-check of a fit's meshes (self_check.hpp): input points landing on each zero-level component
// (exact closest points on the triangle BVH), offset components against the zero-level mesh
// (offsetComponents, the rule of `measure --offset-of`), and the removal of small components.
#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <limits>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "duplexfit/error.hpp"
#include "duplexfit/timer.hpp"
#include "duplexfit/measure.hpp"
#include "duplexfit/neighbors.hpp"
#include "duplexfit/self_check.hpp"
#include "spatial/morton.hpp"

namespace duplexfit {

namespace {

using Clock = std::chrono::steady_clock;

double triangleArea(const Mesh& m, Eigen::Index f) {
  const Eigen::Vector3d a = m.vertices.row(m.faces(f, 0)).transpose();
  const Eigen::Vector3d b = m.vertices.row(m.faces(f, 1)).transpose();
  const Eigen::Vector3d c = m.vertices.row(m.faces(f, 2)).transpose();
  return 0.5 * (b - a).cross(c - a).norm();
}

/// Size and extent of every component of a mesh, in label order.
struct ComponentStats {
  std::size_t faces = 0, vertices = 0;
  double area = 0.0;
  Eigen::AlignedBox3d box;
};

struct Components {
  std::vector<Index> labels;  ///< per face
  std::vector<ComponentStats> stats;
  double area = 0.0;          ///< whole mesh
};

Components components(const Mesh& mesh) {
  Components c;
  std::size_t count = 0;
  c.labels = faceComponents(mesh, &count);  // checks the indices
  c.stats.assign(count, {});
  std::vector<Index> vertexLabel(static_cast<std::size_t>(mesh.vertices.rows()), -1);
  for (Eigen::Index f = 0; f < mesh.faces.rows(); ++f) {
    const auto l = static_cast<std::size_t>(c.labels[static_cast<std::size_t>(f)]);
    ComponentStats& s = c.stats[l];
    ++s.faces;
    const double a = triangleArea(mesh, f);
    s.area += a;
    c.area += a;
    for (int k = 0; k < 3; ++k) {
      const auto v = static_cast<std::size_t>(mesh.faces(f, k));
      if (vertexLabel[v] >= 0) continue;
      vertexLabel[v] = static_cast<Index>(l);
      ++s.vertices;
      s.box.extend(mesh.vertices.row(static_cast<Eigen::Index>(v)).transpose());
    }
  }
  return c;
}

void checkFraction(double minAreaFraction) {
  if (!(std::isfinite(minAreaFraction) && minAreaFraction >= 0.0 && minAreaFraction < 1.0)) {
    throw InvalidArgument("minimum component area fraction must be in [0, 1) (got " +
                          std::to_string(minAreaFraction) + ")");
  }
}

double meanEdgeLength(const Mesh& m) {
  double sum = 0.0;
  for (Eigen::Index f = 0; f < m.faces.rows(); ++f) {
    for (int k = 0; k < 3; ++k) {
      sum += (m.vertices.row(m.faces(f, k)) - m.vertices.row(m.faces(f, (k + 1) % 3))).norm();
    }
  }
  return m.faces.rows() > 0 ? sum / (3.0 * static_cast<double>(m.faces.rows())) : 0.0;
}

/// Which components of the zero-level mesh have an input point within `tol` of their triangles. Each round
/// credits, for every point, the component nearest to it among those not yet credited (when it is within
/// tol), on a BVH of those components only; a round that credits none ends it, since then no point is
/// within tol of any remaining component. One closest-point query per point is enough when every component
/// carries points (the usual case), and later rounds run on the few faces left.
std::vector<char> componentsWithPoints(const Mesh& mesh, const TriangleBvh& tree, const std::vector<Index>& labels,
                                       std::size_t count, const Points& points, double tol) {
  std::vector<char> carried(count, 0);
  std::optional<TriangleBvh> remainingTree;
  std::vector<Index> remainingLabels;  // per face of remainingTree
  const TriangleBvh* current = &tree;
  const std::vector<Index>* currentLabels = &labels;
  const auto n = static_cast<long long>(points.rows());
  // Points in Morton order, so that each query's hint (the previous closest face) is a tight start.
  const std::vector<std::uint32_t> order = detail::processingOrder(points, 2);  // empty: the input order
  std::size_t open = count;  // components not credited yet
  while (true) {
    std::vector<char> credit(count, 0);
    const TriangleBvh& t = *current;
    const std::vector<Index>& l = *currentLabels;
    // Once every component still open has been credited in this round, the rest of the points can only
    // credit them again: they are skipped (one component, the usual case, needs a handful of queries).
    std::atomic<std::size_t> creditedNow{0};
    std::atomic<bool> allCredited{false};
#pragma omp parallel default(none) shared(t, l, points, order, credit, n, tol, creditedNow, allCredited, open)
    {
      std::int64_t hint = -1;
#pragma omp for schedule(dynamic, 256)
      for (long long i = 0; i < n; ++i) {
        if (allCredited.load(std::memory_order_relaxed)) continue;
        const auto row = static_cast<Eigen::Index>(order.empty() ? i : order[static_cast<std::size_t>(i)]);
        const ClosestPoint cp = t.closest(points.row(row).transpose(), hint);
        if (cp.face < 0 || !(cp.distance <= tol)) continue;
        const auto c = static_cast<std::size_t>(l[static_cast<std::size_t>(cp.face)]);
        char before = 0;
#pragma omp atomic capture
        {
          before = credit[c];
          credit[c] = 1;
        }
        if (before == 0 && creditedNow.fetch_add(1) + 1 == open) allCredited.store(true, std::memory_order_relaxed);
      }
    }
    bool credited = false, remaining = false;
    for (std::size_t c = 0; c < count; ++c) {
      credited = credited || credit[c] != 0;
      carried[c] = static_cast<char>(carried[c] != 0 || credit[c] != 0);
      remaining = remaining || carried[c] == 0;
    }
    open -= creditedNow.load();
    if (!credited || !remaining) break;
    Mesh rest;
    rest.vertices = mesh.vertices;
    std::vector<Eigen::Index> rows;
    for (Eigen::Index f = 0; f < mesh.faces.rows(); ++f) {
      if (!carried[static_cast<std::size_t>(labels[static_cast<std::size_t>(f)])]) rows.push_back(f);
    }
    rest.faces.resize(static_cast<Eigen::Index>(rows.size()), 3);
    remainingLabels.resize(rows.size());
    for (std::size_t i = 0; i < rows.size(); ++i) {
      rest.faces.row(static_cast<Eigen::Index>(i)) = mesh.faces.row(rows[i]);
      remainingLabels[i] = labels[static_cast<std::size_t>(rows[i])];
    }
    remainingTree.emplace(rest);
    current = &*remainingTree;
    currentLabels = &remainingLabels;
  }
  return carried;
}

/// The components of the zero-level mesh with no input point within `tol` of their triangles, each with
/// the distance from its nearest vertex to the nearest input point (label order).
std::vector<std::pair<std::size_t, double>> emptyComponents(const Mesh& zero, const TriangleBvh& tree, const Components& c,
                                                            const Points& inputPoints, double tol) {
  std::vector<std::pair<std::size_t, double>> out;
  const std::vector<char> carried = componentsWithPoints(zero, tree, c.labels, c.stats.size(), inputPoints, tol);
  std::vector<char> isEmpty(c.stats.size(), 0);
  bool any = false;
  for (std::size_t l = 0; l < carried.size(); ++l) {
    isEmpty[l] = static_cast<char>(!carried[l]);
    any = any || isEmpty[l];
  }
  if (!any) return out;
  // How far the nearest input point is, from the vertices of each empty component.
  std::vector<Index> vertexLabel(static_cast<std::size_t>(zero.vertices.rows()), -1);
  for (Eigen::Index f = 0; f < zero.faces.rows(); ++f) {
    const Index l = c.labels[static_cast<std::size_t>(f)];
    if (!isEmpty[static_cast<std::size_t>(l)]) continue;
    for (int k = 0; k < 3; ++k) vertexLabel[static_cast<std::size_t>(zero.faces(f, k))] = l;
  }
  std::vector<Eigen::Index> rows;
  for (std::size_t v = 0; v < vertexLabel.size(); ++v) {
    if (vertexLabel[v] >= 0) rows.push_back(static_cast<Eigen::Index>(v));
  }
  Points queries(static_cast<Eigen::Index>(rows.size()), 3);
  for (std::size_t i = 0; i < rows.size(); ++i) queries.row(static_cast<Eigen::Index>(i)) = zero.vertices.row(rows[i]);
  const NeighborLists nearest = NeighborIndex(inputPoints).knnSearch(queries, 1);
  std::vector<double> best(c.stats.size(), std::numeric_limits<double>::infinity());
  for (std::size_t i = 0; i < rows.size(); ++i) {
    if (nearest.count(i) == 0) continue;
    const auto l = static_cast<std::size_t>(vertexLabel[static_cast<std::size_t>(rows[i])]);
    best[l] = std::min(best[l], nearest.distances[static_cast<std::size_t>(nearest.offsets[i])]);
  }
  for (std::size_t l = 0; l < isEmpty.size(); ++l) {
    if (isEmpty[l]) out.emplace_back(l, best[l]);
  }
  return out;
}

/// The listed components (label, nearest input point) with their faces and vertices.
std::vector<EmptyComponent> describeEmpty(const Mesh& zero, const Components& c,
                                          const std::vector<std::pair<std::size_t, double>>& list) {
  std::vector<EmptyComponent> out;
  if (list.empty()) return out;
  std::vector<Index> slot(c.stats.size(), -1);
  for (const auto& [l, nearest] : list) {
    EmptyComponent e;
    e.component = l;
    e.faces = c.stats[l].faces;
    e.area = c.stats[l].area;
    e.box = c.stats[l].box;
    e.nearestInputPoint = nearest;
    slot[l] = static_cast<Index>(out.size());
    out.push_back(std::move(e));
  }
  std::vector<char> seen(static_cast<std::size_t>(zero.vertices.rows()), 0);
  for (Eigen::Index f = 0; f < zero.faces.rows(); ++f) {
    const Index i = slot[static_cast<std::size_t>(c.labels[static_cast<std::size_t>(f)])];
    if (i < 0) continue;
    EmptyComponent& e = out[static_cast<std::size_t>(i)];
    e.faceList.push_back(static_cast<Index>(f));
    for (int k = 0; k < 3; ++k) {
      const auto v = static_cast<std::size_t>(zero.faces(f, k));
      if (seen[v]) continue;
      seen[v] = 1;
      e.vertexList.push_back(static_cast<Index>(v));
    }
  }
  return out;
}

ComponentIssue makeIssue(int surface, double iso, std::size_t label, const ComponentStats& s, double meshArea,
                         ComponentIssue::Why why) {
  ComponentIssue issue;
  issue.surface = surface;
  issue.iso = iso;
  issue.component = label;
  issue.faces = s.faces;
  issue.vertices = s.vertices;
  issue.area = s.area;
  issue.areaFraction = meshArea > 0.0 ? s.area / meshArea : 0.0;
  issue.box = s.box;
  issue.why = why;
  return issue;
}

}  // namespace

const char* componentIssueName(ComponentIssue::Why why) noexcept {
  switch (why) {
    case ComponentIssue::Why::NoInputPoints: return "no_input_points";
    case ComponentIssue::Why::OffOffset: return "off_offset";
  }
  return "unknown";
}

namespace {

Mesh withoutSmallComponents(const Mesh& mesh, double minAreaFraction, DroppedComponents* dropped) {
  checkFraction(minAreaFraction);
  if (dropped != nullptr) {
    *dropped = {};
    dropped->minAreaFraction = minAreaFraction;
  }
  if (minAreaFraction == 0.0 || mesh.faces.rows() == 0) return mesh;
  const Components c = components(mesh);
  std::size_t largest = 0;
  for (std::size_t l = 1; l < c.stats.size(); ++l) {
    if (c.stats[l].area > c.stats[largest].area) largest = l;
  }
  std::vector<char> keep(c.stats.size(), 1);
  DroppedComponents d;
  d.minAreaFraction = minAreaFraction;
  for (std::size_t l = 0; l < c.stats.size(); ++l) {
    if (l == largest || !(c.stats[l].area < minAreaFraction * c.area)) continue;
    keep[l] = 0;
    ++d.components;
    d.faces += c.stats[l].faces;
    d.vertices += c.stats[l].vertices;
    d.area += c.stats[l].area;
  }
  d.areaFraction = c.area > 0.0 ? d.area / c.area : 0.0;
  if (dropped != nullptr) *dropped = d;
  if (d.components == 0) return mesh;

  std::vector<char> keepFace(static_cast<std::size_t>(mesh.faces.rows()));
  for (std::size_t f = 0; f < keepFace.size(); ++f) keepFace[f] = keep[static_cast<std::size_t>(c.labels[f])];
  return keepFaces(mesh, keepFace);
}

}  // namespace

DropResult dropSmallComponents(const Mesh& mesh, double minAreaFraction) {
  DropResult r;
  r.mesh = withoutSmallComponents(mesh, minAreaFraction, &r.dropped);
  return r;
}

SelfCheckReport selfCheck(const std::vector<Mesh>& meshes, const std::vector<double>& isos, const Points& inputPoints,
                          const SelfCheckOptions& options) {
  const auto start = Clock::now();
  if (meshes.empty() || meshes.size() != isos.size()) {
    throw InvalidArgument("self-check: " + std::to_string(meshes.size()) + " meshes for " +
                          std::to_string(isos.size()) + " iso values (need the same number, at least one)");
  }
  if (isos[0] != 0.0) throw InvalidArgument("self-check: the first mesh must be the zero level (iso " +
                                            std::to_string(isos[0]) + ")");
  for (std::size_t j = 1; j < isos.size(); ++j) {
    if (!std::isfinite(isos[j]) || isos[j] == 0.0) {
      throw InvalidArgument("self-check: offset " + std::to_string(j) + " must be a non-zero number (got " +
                            std::to_string(isos[j]) + ")");
    }
  }
  if (!(std::isfinite(options.pointTolerance) && options.pointTolerance >= 0.0)) {
    throw InvalidArgument("self-check: pointTolerance must be finite and >= 0");
  }
  if (!(std::isfinite(options.pointToleranceEdges) && options.pointToleranceEdges > 0.0)) {
    throw InvalidArgument("self-check: pointToleranceEdges must be finite and > 0");
  }
  if (!(std::isfinite(options.candidateEdges) && options.candidateEdges >= 0.0)) {
    throw InvalidArgument("self-check: candidateEdges must be finite and >= 0");
  }
  checkFraction(options.minAreaFraction);

  SelfCheckReport r;
  r.minAreaFraction = options.minAreaFraction;
  r.minOffsetAreaFraction = options.minOffsetAreaFraction;
  const Mesh& zero = meshes[0];
  std::vector<Components> comps;
  comps.reserve(meshes.size());
  for (std::size_t i = 0; i < meshes.size(); ++i) {
    comps.push_back(components(meshes[i]));
    SurfaceSelfCheck s;
    s.surface = static_cast<int>(i);
    s.iso = isos[i];
    s.faces = static_cast<std::size_t>(meshes[i].faces.rows());
    s.components = comps.back().stats.size();
    s.area = comps.back().area;
    r.surfaces.push_back(s);
  }
  std::optional<TriangleBvh> zeroTree;
  if (zero.faces.rows() > 0) zeroTree.emplace(zero);

  // The zero level: every component must carry input points.
  if (zeroTree && inputPoints.rows() > 0) {
    r.pointsChecked = true;
    const double edge = meanEdgeLength(zero);
    r.pointTolerance = options.pointTolerance > 0.0 ? options.pointTolerance : options.pointToleranceEdges * edge;
    const Components& c = comps[0];
    // The components without points within the candidates' tolerance first when it is the smaller: the
    // issues are among them (none when every component carries points there, the usual case, at the cost
    // of one early-ending pass).
    const double looseTol = options.candidateEdges * edge;
    std::vector<std::pair<std::size_t, double>> loose;
    const bool asked = options.candidateEdges > 0.0 && looseTol < r.pointTolerance;
    if (asked) loose = emptyComponents(zero, *zeroTree, c, inputPoints, looseTol);
    const std::vector<std::pair<std::size_t, double>> strict =
        asked && loose.empty() ? loose : emptyComponents(zero, *zeroTree, c, inputPoints, r.pointTolerance);
    for (const auto& [l, nearest] : strict) {
      ComponentIssue issue = makeIssue(0, 0.0, l, c.stats[l], c.area, ComponentIssue::Why::NoInputPoints);
      issue.nearestInputPoint = nearest;
      r.issues.push_back(issue);
    }
    if (options.candidateEdges > 0.0) r.emptyComponents = describeEmpty(zero, c, asked ? loose : strict);
  }

  // The offsets: every component must lie at about |δ_j| from the zero level (not yet when the caller will
  // change the meshes for the candidates found and check them again).
  r.offsetsChecked = !(options.candidatesFirst && !r.emptyComponents.empty());
  for (std::size_t j = 1; j < meshes.size() && r.offsetsChecked; ++j) {
    const Components& c = comps[j];
    if (c.stats.empty()) continue;
    std::vector<OffsetReport::Component> measured;
    if (zeroTree) {
      measured = offsetComponents(meshes[j], *zeroTree, isos[j], c.labels, c.stats.size(), options.offsetVertexSamples);
    }
    SurfaceSelfCheck& s = r.surfaces[j];
    for (const OffsetReport::Component& m : measured) {
      if (std::isfinite(m.minDistance) && !(m.minDistance >= s.thinnestWall)) {  // NaN: none yet
        s.thinnestWall = m.minDistance;
        s.thinnestWallAt = m.minAt;
      }
    }
    for (std::size_t l = 0; l < c.stats.size(); ++l) {
      if (zeroTree && !measured[l].offOffset) continue;
      ComponentIssue issue =
          makeIssue(static_cast<int>(j), isos[j], l, c.stats[l], c.area, ComponentIssue::Why::OffOffset);
      issue.meanDistance = zeroTree ? measured[l].meanDistance : std::numeric_limits<double>::infinity();
      issue.meanDeviation = zeroTree ? measured[l].meanDeviation : std::numeric_limits<double>::infinity();
      r.issues.push_back(issue);
    }
  }
  for (const ComponentIssue& issue : r.issues) ++r.surfaces[static_cast<std::size_t>(issue.surface)].issues;
  r.seconds = secondsSince(start);
  return r;
}

double dropFraction(const SelfCheckOptions& options, std::size_t mesh) {
  return mesh == 0 ? options.minAreaFraction : std::max(options.minAreaFraction, options.minOffsetAreaFraction);
}

std::vector<DroppedComponents> dropSmallComponents(std::vector<Mesh>& meshes, const SelfCheckOptions& options) {
  checkFraction(options.minAreaFraction);
  checkFraction(options.minOffsetAreaFraction);
  std::vector<DroppedComponents> dropped(meshes.size());
  for (std::size_t i = 0; i < meshes.size(); ++i) {
    const double fraction = dropFraction(options, i);
    if (fraction > 0.0) meshes[i] = withoutSmallComponents(meshes[i], fraction, &dropped[i]);
  }
  return dropped;
}

SelfCheckReport cleanAndSelfCheck(std::vector<Mesh>& meshes, const std::vector<double>& isos, const Points& inputPoints,
                                  const SelfCheckOptions& options) {
  const auto start = Clock::now();
  const std::vector<DroppedComponents> dropped = dropSmallComponents(meshes, options);
  SelfCheckReport r = selfCheck(meshes, isos, inputPoints, options);
  for (std::size_t i = 0; i < r.surfaces.size(); ++i) r.surfaces[i].dropped = dropped[i];
  r.seconds = secondsSince(start);
  return r;
}

std::vector<EmptyComponent> emptyZeroLevelComponents(const Mesh& zero, const Points& inputPoints, double toleranceEdges) {
  if (!(std::isfinite(toleranceEdges) && toleranceEdges > 0.0)) {
    throw InvalidArgument("empty components: the tolerance must be finite and > 0 mesh edges");
  }
  if (zero.faces.rows() == 0 || inputPoints.rows() == 0) return {};
  const Components c = components(zero);
  const TriangleBvh tree(zero);
  return describeEmpty(zero, c, emptyComponents(zero, tree, c, inputPoints, toleranceEdges * meanEdgeLength(zero)));
}

}  // namespace duplexfit
