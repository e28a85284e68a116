// TriangleBvh: build in Morton order with radix splits (spatial/morton.hpp), exact
// closest-point queries by best-first descent with box pruning, box-overlap queries; and the exact
// point-triangle closest point (Voronoi regions of the triangle, after Ericson, Real-Time Collision
// Detection §5.1.5, re-derived here), with an edge fallback for degenerate triangles.
#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <string>

#include "duplexfit/error.hpp"
#include "measure/bvh_data.hpp"
#include "measure/geometry.hpp"
#include "spatial/morton.hpp"
#include "measure/parallel_errors.hpp"
#include "parallel/omp_threads.hpp"

namespace duplexfit {

namespace geom {

namespace {

/// Closest point of segment [a, b] to q; feature Vertex (local ia or ib) at the ends, else Edge.
double closestOnSegment(const double* q, const double* a, const double* b, int ia, int ib, int edge,
                        double* point, TriangleFeature& feature, int& local) {
  double ab[3], aq[3];
  sub(b, a, ab);
  sub(q, a, aq);
  const double l2 = norm2(ab);
  double t = l2 > 0.0 ? dot(aq, ab) / l2 : 0.0;
  if (!(t > 0.0)) {
    t = 0.0;
    feature = TriangleFeature::Vertex;
    local = ia;
  } else if (t >= 1.0) {
    t = 1.0;
    feature = TriangleFeature::Vertex;
    local = ib;
  } else {
    feature = TriangleFeature::Edge;
    local = edge;
  }
  if (t == 1.0) {
    point[0] = b[0];
    point[1] = b[1];
    point[2] = b[2];
  } else {
    for (int k = 0; k < 3; ++k) point[k] = a[k] + t * ab[k];
  }
  return dist2(q, point);
}

}  // namespace

double closestOnTriangle(const double* q, const double* tri, double* point, TriangleFeature& feature,
                         int& local) {
  const double* a = tri;
  const double* b = tri + 3;
  const double* c = tri + 6;
  double ab[3], ac[3];
  sub(b, a, ab);
  sub(c, a, ac);
  auto set = [&](const double* p, TriangleFeature f, int l) {
    point[0] = p[0];
    point[1] = p[1];
    point[2] = p[2];
    feature = f;
    local = l;
    return dist2(q, point);
  };
  if (nearlyDegenerate(ab, ac)) {
    // A segment or a point: the best of the three edges.
    double p[3];
    TriangleFeature f;
    int l;
    double best = closestOnSegment(q, a, b, 0, 1, 0, point, feature, local);
    double d = closestOnSegment(q, b, c, 1, 2, 1, p, f, l);
    if (d < best) {
      best = d;
      set(p, f, l);
    }
    d = closestOnSegment(q, c, a, 2, 0, 2, p, f, l);
    if (d < best) {
      best = d;
      set(p, f, l);
    }
    return best;
  }
  double ap[3];
  sub(q, a, ap);
  const double d1 = dot(ab, ap), d2 = dot(ac, ap);
  if (d1 <= 0.0 && d2 <= 0.0) return set(a, TriangleFeature::Vertex, 0);
  double bp[3];
  sub(q, b, bp);
  const double d3 = dot(ab, bp), d4 = dot(ac, bp);
  if (d3 >= 0.0 && d4 <= d3) return set(b, TriangleFeature::Vertex, 1);
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0) {
    const double v = d1 / (d1 - d3);
    double p[3] = {a[0] + v * ab[0], a[1] + v * ab[1], a[2] + v * ab[2]};
    return set(p, TriangleFeature::Edge, 0);
  }
  double cp[3];
  sub(q, c, cp);
  const double d5 = dot(ab, cp), d6 = dot(ac, cp);
  if (d6 >= 0.0 && d5 <= d6) return set(c, TriangleFeature::Vertex, 2);
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0) {
    const double w = d2 / (d2 - d6);
    double p[3] = {a[0] + w * ac[0], a[1] + w * ac[1], a[2] + w * ac[2]};
    return set(p, TriangleFeature::Edge, 2);
  }
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0.0 && d4 - d3 >= 0.0 && d5 - d6 >= 0.0) {
    const double w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
    double p[3] = {b[0] + w * (c[0] - b[0]), b[1] + w * (c[1] - b[1]), b[2] + w * (c[2] - b[2])};
    return set(p, TriangleFeature::Edge, 1);
  }
  const double denom = va + vb + vc;
  const double v = vb / denom, w = vc / denom;
  double p[3] = {a[0] + v * ab[0] + w * ac[0], a[1] + v * ab[1] + w * ac[1], a[2] + v * ab[2] + w * ac[2]};
  const double d = set(p, TriangleFeature::Face, 0);
  if (std::isfinite(d)) return d;
  // Unreachable for non-degenerate finite input; keep the result finite regardless.
  double e[3];
  TriangleFeature f;
  int l;
  double best = closestOnSegment(q, a, b, 0, 1, 0, point, feature, local);
  for (int k = 1; k < 3; ++k) {
    const double dk = closestOnSegment(q, tri + 3 * k, tri + 3 * ((k + 1) % 3), k, (k + 1) % 3, k, e, f, l);
    if (dk < best) {
      best = dk;
      set(e, f, l);
    }
  }
  return best;
}

}  // namespace geom

ClosestPoint closestPointOnTriangle(const Eigen::Vector3d& q, const Eigen::Vector3d& a,
                                    const Eigen::Vector3d& b, const Eigen::Vector3d& c) {
  const double tri[9] = {a.x(), a.y(), a.z(), b.x(), b.y(), b.z(), c.x(), c.y(), c.z()};
  const double qq[3] = {q.x(), q.y(), q.z()};
  ClosestPoint r;
  double p[3];
  const double d2 = geom::closestOnTriangle(qq, tri, p, r.feature, r.local);
  r.distance = std::sqrt(d2);
  r.point = Eigen::Vector3d(p[0], p[1], p[2]);
  return r;
}

namespace {

constexpr std::uint32_t kLeafSize = 4;
constexpr std::size_t kExactCoin = 32;  // nodes of at most this many triangles get coins from their corners

using Node = TriangleBvh::Data::Node;

/// Builds the tree over the triangles in leaf order (their corners in d.corners, their Morton codes in
/// `code`): radix splits (spatial/morton.hpp), each node's box the union of its children's, its coin's
/// axis the sum of its triangles' area vectors. A node of at most kExactCoin triangles gets its coin's
/// height and radius from its corners; a larger one bounds them from its children's coins and its box's
/// corners (the smaller of the two bounds), which is looser but costs nothing a triangle.
struct Builder {
  TriangleBvh::Data& d;  ///< the triangles (leaf order) and the nodes, sized by count()
  const std::uint32_t* code;
  int depth = 0;

  /// The nodes of the subtree over triangles [begin, end) at depth `level` (the same splits as build's).
  std::size_t count(std::size_t begin, std::size_t end, int level) const {
    if (end - begin <= kLeafSize || level >= detail::kMortonTreeDepth) return 1;
    const std::size_t mid = detail::radixSplit(code, begin, end);
    return 1 + count(begin, mid, level + 1) + count(mid, end, level + 1);
  }

  /// Height and radius of the triangles [begin, end) around the node's axis through its centre.
  void exactCoin(Node& n, std::size_t begin, std::size_t end) const {
    double height = 0.0, radius2 = 0.0;
    for (std::size_t i = begin; i < end; ++i) {
      const double* t = d.triangle(i);
      for (int v = 0; v < 3; ++v) {
        double w[3];
        geom::sub(t + 3 * v, n.c, w);
        const double h = geom::dot(w, n.n);
        height = std::max(height, std::abs(h));
        radius2 = std::max(radius2, geom::norm2(w) - h * h);
      }
    }
    inflate(n, height, std::sqrt(std::max(radius2, 0.0)));
  }
  /// Inflates by a few ulps of the node's size so that rounding in the query never cuts a triangle off.
  static void inflate(Node& n, double height, double radius) {
    const double size = std::sqrt(geom::dist2(n.lo, n.hi));
    n.halfHeight = height * (1.0 + 1e-12) + 1e-14 * size;
    n.rho = radius * (1.0 + 1e-12) + 1e-14 * size;
  }
  /// Sets the coin's centre (the box's) and axis (normalised `axis`, +z when it has no direction).
  static void coinAxis(Node& n, const double axis[3]) {
    const double len = std::sqrt(geom::norm2(axis));
    const bool none = !(len > 0.0) || !std::isfinite(len);
    for (int k = 0; k < 3; ++k) {
      n.n[k] = none ? (k == 2 ? 1.0 : 0.0) : axis[k] / len;
      n.c[k] = 0.5 * (n.lo[k] + n.hi[k]);
    }
  }

  /// Builds the subtree of triangles [begin, end) at node `self` (depth-first: the left child at self + 1);
  /// returns the node after it. `axis` gets the sum of their area vectors.
  std::size_t build(std::size_t begin, std::size_t end, int level, double axis[3], std::size_t self) {
    depth = std::max(depth, level);
    const std::size_t count = end - begin;
    if (count <= kLeafSize || level >= detail::kMortonTreeDepth) {
      Node n{};
      for (int k = 0; k < 3; ++k) {
        n.lo[k] = std::numeric_limits<double>::infinity();
        n.hi[k] = -std::numeric_limits<double>::infinity();
        axis[k] = 0.0;
      }
      for (std::size_t i = begin; i < end; ++i) {
        const double* t = d.triangle(i);
        double ab[3], ac[3], nn[3];
        geom::sub(t + 3, t, ab);
        geom::sub(t + 6, t, ac);
        geom::cross(ab, ac, nn);
        for (int k = 0; k < 3; ++k) {
          n.lo[k] = std::min({n.lo[k], t[k], t[3 + k], t[6 + k]});
          n.hi[k] = std::max({n.hi[k], t[k], t[3 + k], t[6 + k]});
          axis[k] += nn[k];
        }
      }
      coinAxis(n, axis);
      exactCoin(n, begin, end);
      n.index = static_cast<std::uint32_t>(begin);
      n.count = static_cast<std::uint32_t>(count);
      d.nodes[self] = n;
      return self + 1;
    }
    const std::size_t mid = detail::radixSplit(code, begin, end);
    double al[3], ar[3];
    const std::size_t right = build(begin, mid, level + 1, al, self + 1);
    const std::size_t after = build(mid, end, level + 1, ar, right);
    join(self, right, begin, end, al, ar, axis);
    return after;
  }

  /// Node `self` over triangles [begin, end), from its children at self + 1 and `right` (area vectors al, ar;
  /// `axis` gets their sum).
  void join(std::size_t self, std::size_t right, std::size_t begin, std::size_t end, const double al[3],
            const double ar[3], double axis[3]) {
    const std::size_t count = end - begin;
    const Node& l = d.nodes[self + 1];
    const Node& r = d.nodes[right];
    Node n{};
    for (int k = 0; k < 3; ++k) {
      n.lo[k] = std::min(l.lo[k], r.lo[k]);
      n.hi[k] = std::max(l.hi[k], r.hi[k]);
      axis[k] = al[k] + ar[k];
    }
    coinAxis(n, axis);
    if (count <= kExactCoin) {
      exactCoin(n, begin, end);
    } else {
      // A child's coin (centre c', axis n', radius ρ', half-height h') lies within |(c' − c)·n| + h'cosθ +
      // ρ'sinθ of this coin's mid-plane and within |(c' − c)⊥| + h'sinθ + ρ' of its axis (θ between the
      // axes).
      double height = 0.0, radius = 0.0;
      for (const Node* ch : {&l, &r}) {
        double dc[3];
        geom::sub(ch->c, n.c, dc);
        const double a = geom::dot(dc, n.n);
        const double cosT = std::min(1.0, std::abs(geom::dot(ch->n, n.n)));
        const double sinT = std::sqrt(std::max(0.0, 1.0 - cosT * cosT));
        const double radial = std::sqrt(std::max(0.0, geom::norm2(dc) - a * a));
        height = std::max(height, std::abs(a) + ch->halfHeight * cosT + ch->rho * sinT);
        radius = std::max(radius, radial + ch->halfHeight * sinT + ch->rho);
      }
      // The box's corners bound them too.
      double boxHeight = 0.0, boxRadius2 = 0.0;
      for (int corner = 0; corner < 8; ++corner) {
        const double b[3] = {(corner & 1) != 0 ? n.hi[0] : n.lo[0], (corner & 2) != 0 ? n.hi[1] : n.lo[1],
                             (corner & 4) != 0 ? n.hi[2] : n.lo[2]};
        double w[3];
        geom::sub(b, n.c, w);
        const double h = geom::dot(w, n.n);
        boxHeight = std::max(boxHeight, std::abs(h));
        boxRadius2 = std::max(boxRadius2, geom::norm2(w) - h * h);
      }
      inflate(n, std::min(height, boxHeight), std::min(radius, std::sqrt(std::max(boxRadius2, 0.0))));
    }
    n.index = static_cast<std::uint32_t>(right);
    n.count = 0;
    d.nodes[self] = n;
  }

  /// Sizes d.nodes and builds the tree over triangles [0, m), the root's two subtrees at once when they are
  /// large (each writes its own range of nodes: the right one starts after the left's count): the same nodes
  /// in the same order as one thread's build. fandisk_550k's zero mesh: 0.39 s of a serial build.
  void buildRoot(std::size_t m, double axis[3]) {
    if (m <= kLeafSize || m < kParallelBuild || detail::maxThreads() < 2) {
      d.nodes.resize(count(0, m, 1));
      build(0, m, 1, axis, 0);
      return;
    }
    const std::size_t mid = detail::radixSplit(code, 0, m);
    std::size_t counts[2] = {0, 0};
    double al[3], ar[3];
    Builder other{d, code};
    measure_detail::ParallelErrors errors;
#pragma omp parallel num_threads(2)
    {
      const bool first = detail::threadId() == 0;
      const bool alone = detail::teamSize() < 2;
      if (first || alone) errors.run([&] { counts[0] = count(0, mid, 2); });
      if (!first || alone) errors.run([&] { counts[1] = count(mid, m, 2); });
#pragma omp barrier
#pragma omp single
      errors.run([&] { d.nodes.resize(1 + counts[0] + counts[1]); });
      if (!errors.failed()) {
        if (first || alone) errors.run([&] { build(0, mid, 2, al, 1); });
        if (!first || alone) errors.run([&] { other.build(mid, m, 2, ar, 1 + counts[0]); });
      }
    }
    errors.rethrow();
    depth = std::max({depth, 1, other.depth});
    join(0, 1 + counts[0], 0, m, al, ar, axis);
  }
  static constexpr std::size_t kParallelBuild = 65536;  ///< fewer triangles: one thread
};

}  // namespace

TriangleBvh::TriangleBvh(const Mesh& mesh) {
  const auto nf = static_cast<std::size_t>(mesh.faces.rows());
  const Eigen::Index nv = mesh.vertices.rows();
  if (nf == 0) throw InvalidArgument("TriangleBvh: mesh has no faces");
  if (nf >= std::numeric_limits<std::uint32_t>::max() / 4) {
    throw InvalidArgument("TriangleBvh: too many faces (" + std::to_string(nf) + ")");
  }
  const double* v = mesh.vertices.data();
  const std::int32_t* f = mesh.faces.data();
  for (std::size_t i = 0; i < nf; ++i) {
    for (int k = 0; k < 3; ++k) {
      const std::int32_t idx = f[3 * i + static_cast<std::size_t>(k)];
      if (idx < 0 || idx >= nv) {
        throw InvalidArgument("TriangleBvh: face " + std::to_string(i) + ": index " + std::to_string(idx) +
                              " out of range (mesh has " + std::to_string(nv) + " vertices)");
      }
      for (std::size_t c = 0; c < 3; ++c) {
        if (!std::isfinite(v[3 * static_cast<std::size_t>(idx) + c])) {
          throw InvalidArgument("TriangleBvh: vertex " + std::to_string(idx) + " is not finite");
        }
      }
    }
  }
  const auto corner = [v, f](std::size_t face, int k, int c) {
    return v[3 * static_cast<std::size_t>(f[3 * face + static_cast<std::size_t>(k)]) + static_cast<std::size_t>(c)];
  };
  // The triangles in the Morton order of their centroids.
  const std::vector<std::uint64_t> key = detail::mortonSortedKeys(nf, [&corner](std::size_t i, double* x) {
    for (int c = 0; c < 3; ++c) x[c] = (corner(i, 0, c) + corner(i, 1, c) + corner(i, 2, c)) / 3.0;
  });
  auto data = std::make_shared<Data>();
  data->corners.resize(9 * nf);
  data->normals.resize(3 * nf);
  data->faceOf.resize(nf);
  detail::ScratchVector<std::uint32_t> code(nf);
  const auto count = static_cast<std::int64_t>(nf);
#pragma omp parallel for schedule(static)
  for (std::int64_t kk = 0; kk < count; ++kk) {
    const auto k = static_cast<std::size_t>(kk);
    const auto face = static_cast<std::size_t>(key[k] & 0xffffffffU);
    code[k] = static_cast<std::uint32_t>(key[k] >> 32);
    double* t = data->corners.data() + 9 * k;
    for (int j = 0; j < 3; ++j) {
      for (int c = 0; c < 3; ++c) t[3 * j + c] = corner(face, j, c);
    }
    data->faceOf[k] = static_cast<std::int64_t>(face);
    double ab[3], ac[3], n[3];
    geom::sub(t + 3, t, ab);
    geom::sub(t + 6, t, ac);
    geom::cross(ab, ac, n);
    const double len = std::sqrt(geom::norm2(n));
    const bool flat = geom::nearlyDegenerate(ab, ac) || !(len > 0.0);
    for (std::size_t c = 0; c < 3; ++c) data->normals[3 * k + c] = flat ? 0.0 : n[c] / len;
  }
  Builder builder{*data, code.data()};
  double axis[3];
  builder.buildRoot(nf, axis);
  data->depth = builder.depth;
  data_ = std::move(data);
}

namespace {

constexpr std::size_t kNoHint = ~std::size_t{0};

/// Best-first descent: the closest point of the tree to q. `hint` (a triangle in leaf order, e.g. the
/// answer of the previous, nearby query) gives the search a tight starting bound; on return it holds
/// this query's triangle.
ClosestPoint query(const TriangleBvh::Data& d, const double q[3], std::size_t& hint) {
  struct Entry {
    double d2;
    std::uint32_t node;
  };
  Entry stack[96];
  int sp = 0;
  double best2 = std::numeric_limits<double>::infinity();
  double bestPoint[3] = {0.0, 0.0, 0.0};
  std::size_t bestTri = 0;
  TriangleFeature bestFeature = TriangleFeature::Face;
  int bestLocal = 0;
  if (hint != kNoHint) {
    best2 = geom::closestOnTriangle(q, d.triangle(hint), bestPoint, bestFeature, bestLocal);
    bestTri = hint;
  }
  stack[sp++] = {TriangleBvh::Data::lowerBound2(d.nodes[0], q, best2), 0};
  while (sp > 0) {
    const Entry e = stack[--sp];
    if (e.d2 >= best2) continue;
    const Node& n = d.nodes[e.node];
    if (n.count > 0) {
      for (std::size_t k = n.index; k < std::size_t{n.index} + n.count; ++k) {
        // The distance to the triangle's plane is a lower bound of the distance to the triangle.
        const double* t = d.triangle(k);
        const double* nk = d.normal(k);
        const double plane = nk[0] * (q[0] - t[0]) + nk[1] * (q[1] - t[1]) + nk[2] * (q[2] - t[2]);
        if (plane * plane >= best2) continue;
        double p[3];
        TriangleFeature f;
        int l;
        const double d2 = geom::closestOnTriangle(q, t, p, f, l);
        if (d2 < best2) {
          best2 = d2;
          bestPoint[0] = p[0];
          bestPoint[1] = p[1];
          bestPoint[2] = p[2];
          bestTri = k;
          bestFeature = f;
          bestLocal = l;
        }
      }
      continue;
    }
    const std::uint32_t left = e.node + 1, right = n.index;
    const double dl = TriangleBvh::Data::lowerBound2(d.nodes[left], q, best2);
    const double dr = TriangleBvh::Data::lowerBound2(d.nodes[right], q, best2);
    // Push the farther child first so that the nearer one is searched first.
    if (dl <= dr) {
      if (dr < best2) stack[sp++] = {dr, right};
      if (dl < best2) stack[sp++] = {dl, left};
    } else {
      if (dl < best2) stack[sp++] = {dl, left};
      if (dr < best2) stack[sp++] = {dr, right};
    }
  }
  hint = bestTri;
  ClosestPoint r;
  r.distance = std::sqrt(best2);
  r.point = Eigen::Vector3d(bestPoint[0], bestPoint[1], bestPoint[2]);
  r.face = d.faceOf[bestTri];
  r.feature = bestFeature;
  r.local = bestLocal;
  return r;
}

}  // namespace

ClosestPoint TriangleBvh::closest(const Eigen::Vector3d& q) const {
  const double qq[3] = {q.x(), q.y(), q.z()};
  std::size_t hint = kNoHint;
  return query(*data_, qq, hint);
}

ClosestPoint TriangleBvh::closest(const Eigen::Vector3d& q, std::int64_t& hint) const {
  const double qq[3] = {q.x(), q.y(), q.z()};
  std::size_t h = hint >= 0 && static_cast<std::size_t>(hint) < data_->faceOf.size() ? static_cast<std::size_t>(hint)
                                                                                      : kNoHint;
  const ClosestPoint r = query(*data_, qq, h);
  hint = static_cast<std::int64_t>(h);
  return r;
}

std::vector<ClosestPoint> TriangleBvh::closest(const Points& queries) const {
  std::vector<ClosestPoint> out(static_cast<std::size_t>(queries.rows()));
  const Data& d = *data_;
  const double* q = queries.data();
  const auto n = static_cast<long long>(queries.rows());
  measure_detail::ParallelErrors errors;
#pragma omp parallel default(none) shared(out, d, q, n, errors)
  {
    std::size_t hint = kNoHint;
#pragma omp for schedule(dynamic, 256)
    for (long long i = 0; i < n; ++i) {
      errors.run([&] { out[static_cast<std::size_t>(i)] = query(d, q + 3 * i, hint); });
    }
  }
  errors.rethrow();
  return out;
}

Eigen::VectorXd TriangleBvh::distances(const Points& queries) const {
  Eigen::VectorXd out(queries.rows());
  const Data& d = *data_;
  const double* q = queries.data();
  const auto n = static_cast<long long>(queries.rows());
  measure_detail::ParallelErrors errors;
#pragma omp parallel default(none) shared(out, d, q, n, errors)
  {
    std::size_t hint = kNoHint;
#pragma omp for schedule(dynamic, 256)
    for (long long i = 0; i < n; ++i) {
      errors.run([&] { out[static_cast<Eigen::Index>(i)] = query(d, q + 3 * i, hint).distance; });
    }
  }
  errors.rethrow();
  return out;
}

void TriangleBvh::overlapping(const Eigen::Vector3d& lo, const Eigen::Vector3d& hi,
                              std::vector<std::int64_t>& out) const {
  overlapping(lo, hi, out, std::numeric_limits<std::size_t>::max());
}

bool TriangleBvh::overlapping(const Eigen::Vector3d& lo, const Eigen::Vector3d& hi, std::vector<std::int64_t>& out,
                              std::size_t limit) const {
  const Data& d = *data_;
  std::size_t room = limit;
  std::uint32_t stack[96];
  int sp = 0;
  stack[sp++] = 0;
  while (sp > 0) {
    const Node& n = d.nodes[stack[--sp]];
    const std::uint32_t self = static_cast<std::uint32_t>(&n - d.nodes.data());
    bool disjoint = false;
    for (int k = 0; k < 3; ++k) disjoint = disjoint || n.lo[k] > hi[k] || n.hi[k] < lo[k];
    if (disjoint) continue;
    if (n.count == 0) {
      stack[sp++] = n.index;
      stack[sp++] = self + 1;
      continue;
    }
    for (std::size_t k = n.index; k < std::size_t{n.index} + n.count; ++k) {
      const double* t = d.triangle(k);
      bool miss = false;
      for (int c = 0; c < 3; ++c) {
        miss = miss || std::min({t[c], t[3 + c], t[6 + c]}) > hi[c] || std::max({t[c], t[3 + c], t[6 + c]}) < lo[c];
      }
      if (miss) continue;
      if (room == 0) return false;
      out.push_back(d.faceOf[k]);
      --room;
    }
  }
  return true;
}

std::size_t TriangleBvh::faceCount() const noexcept { return data_->faceOf.size(); }
std::size_t TriangleBvh::nodeCount() const noexcept { return data_->nodes.size(); }
int TriangleBvh::depth() const noexcept { return data_->depth; }

}  // namespace duplexfit
