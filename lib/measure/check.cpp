// checkMesh: topology (analyzeTopology), boundary loops, genus, signed volume and intersecting
// triangle pairs. Candidate pairs come from box queries on a lean tree of float boxes; each pair is
// classified by the vertices it shares (vertices at identical positions are welded for this): none → a
// triangle-triangle test (plane-side rejection, then overlap of the two intervals on the planes' common
// line, or a 2D test for coplanar triangles); one → whether the triangles extend beyond the shared vertex
// in a common direction; an edge → coplanar fold-over; all three → a duplicate face.
#include <algorithm>
#include <cstddef>
#include <limits>
#include <cmath>
#include <numeric>
#include <string>
#include <vector>

#include <sstream>

#include "core/disjoint_sets.hpp"
#include "duplexfit/error.hpp"
#include "duplexfit/measure.hpp"
#include "measure/geometry.hpp"
#include "spatial/morton.hpp"
#include "measure/parallel_errors.hpp"

namespace duplexfit {

namespace {

using geom::cross;
using geom::dot;
using geom::norm2;
using geom::sub;

constexpr double kRelTol = 1e-10;  // geometric tolerance relative to the larger triangle's longest edge
constexpr std::size_t kQueryGroup = 4;  // faces a walk of the pair search's tree serves

using detail::DisjointSets;

/// Connected cycles of boundary edges (edges of exactly one non-degenerate face).
std::size_t countBoundaryLoops(const Mesh& mesh) {
  const auto nf = static_cast<std::size_t>(mesh.faces.rows());
  const std::int32_t* f = mesh.faces.data();
  std::vector<std::uint64_t> keys;
  keys.reserve(3 * nf);
  for (std::size_t i = 0; i < nf; ++i) {
    const std::int32_t* t = f + 3 * i;
    if (t[0] == t[1] || t[1] == t[2] || t[0] == t[2]) continue;
    for (std::size_t k = 0; k < 3; ++k) {
      const auto a = static_cast<std::uint64_t>(t[k]), b = static_cast<std::uint64_t>(t[(k + 1) % 3]);
      keys.push_back((std::min(a, b) << 32) | std::max(a, b));
    }
  }
  std::sort(keys.begin(), keys.end());
  DisjointSets sets(static_cast<std::size_t>(mesh.vertices.rows()));
  std::vector<std::size_t> boundaryVertices;
  for (std::size_t i = 0; i < keys.size();) {
    std::size_t j = i + 1;
    while (j < keys.size() && keys[j] == keys[i]) ++j;
    if (j - i == 1) {
      const std::size_t a = keys[i] >> 32, b = keys[i] & 0xffffffffULL;
      sets.unite(a, b);
      boundaryVertices.push_back(a);
      boundaryVertices.push_back(b);
    }
    i = j;
  }
  std::vector<std::size_t> roots;
  roots.reserve(boundaryVertices.size());
  for (const std::size_t v : boundaryVertices) roots.push_back(sets.find(v));
  std::sort(roots.begin(), roots.end());
  return static_cast<std::size_t>(std::unique(roots.begin(), roots.end()) - roots.begin());
}

/// Vertex ids with vertices at identical positions merged (the smallest index of each position), of the
/// vertices marked in `used` (all when null; the others get -1). Among the marked vertices, two get the
/// same id exactly when they are at the same position, as over the whole mesh. Identical positions share
/// a Morton cell, so the vertices are radix sorted by cell and only each cell's run (a few vertices) is
/// sorted by position: a comparison sort of all positions took 0.2 s of one thread on fandisk_550k's 1.8M
/// vertices, this 0.05 s.
std::vector<std::int32_t> weldedIds(const Mesh& mesh, const std::vector<char>* used = nullptr) {
  const auto nv = static_cast<std::size_t>(mesh.vertices.rows());
  const double* v = mesh.vertices.data();
  std::vector<std::int32_t> chosen;
  if (used) {
    for (std::size_t i = 0; i < nv; ++i) {
      if ((*used)[i]) chosen.push_back(static_cast<std::int32_t>(i));
    }
  }
  const std::size_t n = used ? chosen.size() : nv;
  const auto vertexOf = [&](std::size_t k) { return used ? static_cast<std::size_t>(chosen[k]) : k; };
  const std::vector<std::uint64_t> key = detail::mortonSortedKeys(n, [&](std::size_t k, double* x) {
    const double* p = v + 3 * vertexOf(k);
    x[0] = p[0];
    x[1] = p[1];
    x[2] = p[2];
  });
  const auto same = [v](std::int32_t a, std::int32_t b) {
    const double* pa = v + 3 * static_cast<std::size_t>(a);
    const double* pb = v + 3 * static_cast<std::size_t>(b);
    return pa[0] == pb[0] && pa[1] == pb[1] && pa[2] == pb[2];
  };
  std::vector<std::int32_t> id(nv, -1);
  std::vector<std::int32_t> run;
  for (std::size_t i = 0; i < n;) {
    std::size_t j = i + 1;
    while (j < n && (key[j] >> 32) == (key[i] >> 32)) ++j;
    run.clear();
    for (std::size_t k = i; k < j; ++k) run.push_back(static_cast<std::int32_t>(vertexOf(key[k] & 0xffffffffU)));
    // Within the cell, by position (ties in index order): the first of each position is its smallest index.
    std::sort(run.begin(), run.end(), [v](std::int32_t a, std::int32_t b) {
      const double* pa = v + 3 * static_cast<std::size_t>(a);
      const double* pb = v + 3 * static_cast<std::size_t>(b);
      for (int c = 0; c < 3; ++c) {
        if (pa[c] != pb[c]) return pa[c] < pb[c];
      }
      return a < b;
    });
    for (std::size_t a = 0; a < run.size(); ++a) {
      const bool first = a == 0 || !same(run[a - 1], run[a]);
      id[static_cast<std::size_t>(run[a])] = first ? run[a] : id[static_cast<std::size_t>(run[a - 1])];
    }
    i = j;
  }
  return id;
}

/// A triangle prepared for the pair tests (made on the fly, on the stack: see FaceSource).
struct Tri {
  double p[9];
  double n[3];       // unit normal
  std::int32_t id[3];  // welded vertex ids
  double tol;        // kRelTol · longest edge
  bool skip;         // degenerate
};

/// The triangle with corners p and vertex ids id, prepared for the pair tests (a mesh's face: FaceSource::tri).
Tri preparedTri(const double* p, const std::int32_t* id) {
  Tri t{};
  std::copy(p, p + 9, t.p);
  std::copy(id, id + 3, t.id);
  double ab[3], ac[3], bc[3];
  sub(t.p + 3, t.p, ab);
  sub(t.p + 6, t.p, ac);
  sub(t.p + 6, t.p + 3, bc);
  cross(ab, ac, t.n);
  const double len = std::sqrt(norm2(t.n));
  const double longest = std::sqrt(std::max({norm2(ab), norm2(ac), norm2(bc)}));
  t.tol = kRelTol * longest;
  t.skip = t.id[0] == t.id[1] || t.id[1] == t.id[2] || t.id[0] == t.id[2] || !(len > 1e-12 * longest * longest);
  if (!t.skip) {
    for (double& x : t.n) x /= len;
  }
  return t;
}

/// The mesh's faces for the pair search, prepared when asked for from the mesh's own arrays: nothing is
/// stored a face (a table of prepared triangles took 128 bytes a face, fresh memory on every call).
struct FaceSource {
  const std::int32_t* f;       // 3 vertex indices a face
  const double* v;             // 3 coordinates a vertex
  const std::int32_t* welded;  // welded vertex ids
  /// The face's corners, 9 coordinates.
  void corners(std::size_t i, double* p) const {
    for (std::size_t k = 0; k < 3; ++k) {
      const auto idx = static_cast<std::size_t>(f[3 * i + k]);
      for (std::size_t c = 0; c < 3; ++c) p[3 * k + c] = v[3 * idx + c];
    }
  }
  /// The face's bounding box.
  void box(std::size_t i, double lo[3], double hi[3]) const {
    double p[9];
    corners(i, p);
    for (int c = 0; c < 3; ++c) {
      lo[c] = std::min({p[c], p[3 + c], p[6 + c]});
      hi[c] = std::max({p[c], p[3 + c], p[6 + c]});
    }
  }
  /// The face's tolerance (as tri(i).tol, without the welded ids).
  double tolOf(std::size_t i) const {
    double p[9], ab[3], ac[3], bc[3];
    corners(i, p);
    sub(p + 3, p, ab);
    sub(p + 6, p, ac);
    sub(p + 6, p + 3, bc);
    return kRelTol * std::sqrt(std::max({norm2(ab), norm2(ac), norm2(bc)}));
  }
  Tri tri(std::size_t i) const {
    double p[9];
    std::int32_t id[3];
    corners(i, p);
    for (std::size_t k = 0; k < 3; ++k) id[k] = welded[static_cast<std::size_t>(f[3 * i + k])];
    return preparedTri(p, id);
  }
};

/// Distances of q's corners to the plane (unit normal n through a), snapped to 0 within tol.
void planeDistances(const double* q, const double* n, const double* a, double tol, double* d) {
  for (int k = 0; k < 3; ++k) {
    double e[3];
    sub(q + 3 * k, a, e);
    d[k] = dot(n, e);
    if (std::abs(d[k]) <= tol) d[k] = 0.0;
  }
}

bool sameStrictSide(const double* d) {
  return (d[0] > 0.0 && d[1] > 0.0 && d[2] > 0.0) || (d[0] < 0.0 && d[1] < 0.0 && d[2] < 0.0);
}

/// The part of a triangle (corners p) in a plane, given its corners' distances d to it (snapped, not all
/// zero, not all on one strict side): its corners on the plane and its edges' crossings of it, at most two
/// points (3 coordinates each) into out; returns how many.
int crossingSegment(const double* p, const double* d, double* out) {
  int m = 0;
  for (int k = 0; k < 3 && m < 2; ++k) {
    if (d[k] == 0.0) {
      for (int c = 0; c < 3; ++c) out[3 * m + c] = p[3 * k + c];
      ++m;
    }
    const int n = (k + 1) % 3;
    if (m < 2 && ((d[k] > 0.0 && d[n] < 0.0) || (d[k] < 0.0 && d[n] > 0.0))) {
      const double t = d[k] / (d[k] - d[n]);
      for (int c = 0; c < 3; ++c) out[3 * m + c] = p[3 * k + c] + t * (p[3 * n + c] - p[3 * k + c]);
      ++m;
    }
  }
  return m;
}

double orient2(const double* a, const double* b, const double* c) {
  return (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]);
}

/// Orientation of c against segment ab, snapped to 0 when c is within tol of the line.
int side2(const double* a, const double* b, const double* c, double tol) {
  const double o = orient2(a, b, c);
  const double len = std::hypot(b[0] - a[0], b[1] - a[1]);
  if (std::abs(o) <= tol * len) return 0;
  return o > 0.0 ? 1 : -1;
}

bool onSegment2(const double* a, const double* b, const double* c, double tol) {
  return c[0] >= std::min(a[0], b[0]) - tol && c[0] <= std::max(a[0], b[0]) + tol &&
         c[1] >= std::min(a[1], b[1]) - tol && c[1] <= std::max(a[1], b[1]) + tol;
}

bool segments2(const double* a, const double* b, const double* c, const double* d, double tol) {
  const int o1 = side2(a, b, c, tol), o2 = side2(a, b, d, tol);
  const int o3 = side2(c, d, a, tol), o4 = side2(c, d, b, tol);
  if (o1 * o2 < 0 && o3 * o4 < 0) return true;
  return (o1 == 0 && onSegment2(a, b, c, tol)) || (o2 == 0 && onSegment2(a, b, d, tol)) ||
         (o3 == 0 && onSegment2(c, d, a, tol)) || (o4 == 0 && onSegment2(c, d, b, tol));
}

bool inside2(const double* t, const double* p, double tol) {
  const int s0 = side2(t, t + 2, p, tol), s1 = side2(t + 2, t + 4, p, tol), s2 = side2(t + 4, t, p, tol);
  return (s0 >= 0 && s1 >= 0 && s2 >= 0) || (s0 <= 0 && s1 <= 0 && s2 <= 0);
}

/// Coplanar triangles (plane normal n): overlap in the projection that drops n's largest axis.
bool coplanarIntersect(const double* p, const double* q, const double* n, double tol) {
  int drop = 0;
  for (int k = 1; k < 3; ++k) {
    if (std::abs(n[k]) > std::abs(n[drop])) drop = k;
  }
  const int u = (drop + 1) % 3, w = (drop + 2) % 3;
  double a[6], b[6];
  for (int k = 0; k < 3; ++k) {
    a[2 * k] = p[3 * k + u];
    a[2 * k + 1] = p[3 * k + w];
    b[2 * k] = q[3 * k + u];
    b[2 * k + 1] = q[3 * k + w];
  }
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) {
      if (segments2(a + 2 * i, a + 2 * ((i + 1) % 3), b + 2 * j, b + 2 * ((j + 1) % 3), tol)) return true;
    }
  }
  return inside2(a, b, tol) || inside2(b, a, tol);
}

/// Planes of two faces closer than this (the sine of their angle) are nearly parallel.
constexpr double kParallel = 1e-6;
/// Corners this close to the other face's plane, relative to the longer longest edge, lie on it when the
/// planes are nearly parallel.
constexpr double kNearPlane = 1e-6;

/// Triangles without a shared vertex: do they touch or cross (within tol)?
bool disjointPairIntersect(const Tri& s, const Tri& t, double tol) {
  double dq[3], dp[3];
  planeDistances(t.p, s.n, s.p, tol, dq);
  if (sameStrictSide(dq)) return false;
  planeDistances(s.p, t.n, t.p, tol, dp);
  if (sameStrictSide(dp)) return false;
  if (dq[0] == 0.0 && dq[1] == 0.0 && dq[2] == 0.0) return coplanarIntersect(s.p, t.p, s.n, tol);
  if (dp[0] == 0.0 && dp[1] == 0.0 && dp[2] == 0.0) return coplanarIntersect(s.p, t.p, t.n, tol);
  // Planes at an angle below kParallel with every corner within kNearPlane of the longer longest edge of
  // the other's plane: the faces are as good as coplanar (their gap is far below float32's rounding of
  // the corners) and touch where they overlap in the plane.
  double dir[3];
  cross(s.n, t.n, dir);
  if (norm2(dir) < kParallel * kParallel) {
    const double near = kNearPlane * std::max(s.tol, t.tol) / kRelTol;
    bool close = true;
    for (int k = 0; k < 3; ++k) close = close && std::abs(dq[k]) <= near && std::abs(dp[k]) <= near;
    if (close) return coplanarIntersect(s.p, t.p, s.n, tol);
  }
  // Two planes: s ∩ t lies in t's plane, so it is the part of s there (a segment or a point: its corners
  // on the plane and its edges' crossings) met with t, a test in t's plane. (The textbook test compares
  // the two parts' intervals on the planes' common line; but the corners snapped onto a plane lie off that
  // line, by up to tol over the sine of the planes' angle: two nearly coplanar faces side by side, each
  // with corners within tol of the other's plane, were reported as crossing.)
  double seg[6];
  const int m = crossingSegment(s.p, dp, seg);
  if (m == 0) return false;
  int drop = 0;
  for (int k = 1; k < 3; ++k) {
    if (std::abs(t.n[k]) > std::abs(t.n[drop])) drop = k;
  }
  const int u = (drop + 1) % 3, w = (drop + 2) % 3;
  const double a[2] = {seg[u], seg[w]};
  const double b[2] = {seg[3 * (m - 1) + u], seg[3 * (m - 1) + w]};
  double tt[6];
  for (int k = 0; k < 3; ++k) {
    tt[2 * k] = t.p[3 * k + u];
    tt[2 * k + 1] = t.p[3 * k + w];
  }
  if (inside2(tt, a, tol) || inside2(tt, b, tol)) return true;
  if (m == 1) return false;
  for (int j = 0; j < 3; ++j) {
    if (segments2(a, b, tt + 2 * j, tt + 2 * ((j + 1) % 3), tol)) return true;
  }
  return false;
}

/// Is direction d strictly inside the sector spanned by e1, e2 (angle below 180°)?
bool inSector(const double* e1, const double* e2, const double* d) {
  double w[3], c1[3], c2[3];
  cross(e1, e2, w);
  cross(e1, d, c1);
  cross(d, e2, c2);
  const double scale = std::sqrt(norm2(w) * norm2(d));
  const double eps = 1e-10 * scale;
  return dot(c1, w) > eps * std::sqrt(norm2(e1)) && dot(c2, w) > eps * std::sqrt(norm2(e2));
}

/// The least |n · e| / |e| of the corners off a shared vertex for offPlaneOneSide.
constexpr double kOffPlane = 1e-4;

/// Whether e1 and e2 (a triangle's edges from a vertex) both point off the plane with unit normal n by more
/// than kOffPlane of their lengths, to the same side.
bool offPlaneOneSide(const double* n, const double* e1, const double* e2) {
  const double d1 = dot(n, e1), d2 = dot(n, e2);
  if (!((d1 > 0.0 && d2 > 0.0) || (d1 < 0.0 && d2 < 0.0))) return false;
  const double k2 = kOffPlane * kOffPlane;
  return d1 * d1 > k2 * norm2(e1) && d2 * d2 > k2 * norm2(e2);
}

/// Triangles sharing exactly the vertex at corner i of s and corner j of t: does their intersection
/// extend beyond it?
bool vertexPairIntersect(const Tri& s, int i, const Tri& t, int j) {
  const double* v = s.p + 3 * i;
  double a1[3], a2[3], b1[3], b2[3];
  sub(s.p + 3 * ((i + 1) % 3), v, a1);
  sub(s.p + 3 * ((i + 2) % 3), v, a2);
  sub(t.p + 3 * ((j + 1) % 3), v, b1);
  sub(t.p + 3 * ((j + 2) % 3), v, b2);
  // Most such pairs on a mesh are neighbours around a vertex with one triangle's other corners well off the
  // other's plane, on one side: the planes then meet at an angle whose sine is at least kOffPlane (far from
  // the one-plane case below), and that triangle meets the other's plane at v only, so no direction of their
  // common line lies inside its sector and the test below says no. Decided here from two dot products (the
  // sector tests were a tenth of a mesh's pair search).
  if (offPlaneOneSide(s.n, b1, b2) || offPlaneOneSide(t.n, a1, a2)) return false;
  double dir[3];
  cross(s.n, t.n, dir);
  if (std::sqrt(norm2(dir)) > 1e-10) {
    // Different planes: the intersection lies on their common line through v.
    const double neg[3] = {-dir[0], -dir[1], -dir[2]};
    return (inSector(a1, a2, dir) && inSector(b1, b2, dir)) || (inSector(a1, a2, neg) && inSector(b1, b2, neg));
  }
  // One plane: the sectors at v overlap when an edge or the bisector of one lies inside the other.
  double abis[3], bbis[3];
  for (int k = 0; k < 3; ++k) {
    abis[k] = a1[k] / std::sqrt(norm2(a1)) + a2[k] / std::sqrt(norm2(a2));
    bbis[k] = b1[k] / std::sqrt(norm2(b1)) + b2[k] / std::sqrt(norm2(b2));
  }
  return inSector(a1, a2, b1) || inSector(a1, a2, b2) || inSector(a1, a2, bbis) || inSector(b1, b2, a1) ||
         inSector(b1, b2, a2) || inSector(b1, b2, abis);
}

/// Triangles sharing the edge (corners i0, i1 of s): coplanar and folded onto the same side.
bool edgePairIntersect(const Tri& s, int i0, int i1, const Tri& t, int jOther, double tol) {
  const double* u = s.p + 3 * i0;
  const double* w = s.p + 3 * i1;
  const double* a = s.p + 3 * (3 - i0 - i1);
  const double* b = t.p + 3 * jOther;
  double ub[3];
  sub(b, u, ub);
  if (std::abs(dot(s.n, ub)) > tol) return false;
  double e[3], ua[3], ca[3], cb[3];
  sub(w, u, e);
  sub(a, u, ua);
  cross(e, ua, ca);
  cross(e, ub, cb);
  return dot(ca, cb) > 0.0;
}

bool pairIntersect(const Tri& s, const Tri& t, double tol) {
  int shared = 0, si[3] = {0, 0, 0}, ti[3] = {0, 0, 0};
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) {
      if (s.id[i] == t.id[j]) {
        si[shared] = i;
        ti[shared] = j;
        ++shared;
      }
    }
  }
  if (shared == 0) return disjointPairIntersect(s, t, tol);
  if (shared == 1) return vertexPairIntersect(s, si[0], t, ti[0]);
  if (shared == 2) return edgePairIntersect(s, si[0], si[1], t, 3 - ti[0] - ti[1], tol);
  return true;  // the same three vertices: a duplicate face
}

/// The pair search's tree of boxes over the tested triangles, in the Morton order of their box centres
/// with radix splits (spatial/morton.hpp). Nodes depth-first with the left child next to its parent, at
/// most kBoxLeaf triangles a leaf, boxes in float rounded outward (a superset of the double boxes'
/// overlaps; each candidate is then tested on its exact double box). About 60 bytes a triangle. The
/// object-median build it replaced took 1.6 s of the 3.6 s pair search of fandisk_550k's 3.7M-triangle
/// zero mesh inside a fit (docs/benchmarks.md).
class BoxTree {
 public:
  BoxTree(const FaceSource& faces, const std::vector<std::int64_t>& tested) : faces_(faces) {
    const std::size_t m = tested.size();
    if (m >= std::numeric_limits<std::uint32_t>::max() / 2) {
      throw InvalidArgument("self-intersections: too many faces (" + std::to_string(m) + ")");
    }
    std::vector<std::uint64_t> key = detail::mortonSortedKeys(m, [&faces, &tested](std::size_t i, double* x) {
      double lo[3], hi[3];
      faces.box(static_cast<std::size_t>(tested[i]), lo, hi);
      for (int c = 0; c < 3; ++c) x[c] = 0.5 * (lo[c] + hi[c]);
    });
    leafBox_.resize(m);
    face_.resize(m);
    code_.resize(m);
    for (std::size_t k = 0; k < m; ++k) {
      const std::int64_t face = tested[static_cast<std::size_t>(key[k] & 0xffffffffU)];
      double lo[3], hi[3];
      faces.box(static_cast<std::size_t>(face), lo, hi);
      for (int c = 0; c < 3; ++c) {
        leafBox_[k].lo[c] = down(lo[c]);
        leafBox_[k].hi[c] = up(hi[c]);
      }
      face_[k] = face;
      code_[k] = static_cast<std::uint32_t>(key[k] >> 32);
    }
    key = {};
    nodes_.reserve(2 * m);  // an upper bound (leaves of at least one entry); only what is used is touched
    if (m > 0) build(0, m, 0);
    code_ = {};
  }

  /// A face found by a box query, with its double bounding box.
  struct Hit {
    std::int64_t face;
    double lo[3], hi[3];
  };

  /// Appends the faces whose double bounding boxes meet [lo, hi], at most `limit`: false when it stopped
  /// there with faces left unvisited.
  bool overlapping(const double lo[3], const double hi[3], std::vector<std::int64_t>& out, std::size_t limit) const {
    return visit(lo, hi, limit, [&out](std::int64_t face, const double*, const double*) { out.push_back(face); });
  }
  /// As overlapping, with each face's box.
  bool overlapping(const double lo[3], const double hi[3], std::vector<Hit>& out, std::size_t limit) const {
    return visit(lo, hi, limit, [&out](std::int64_t face, const double* tlo, const double* thi) {
      out.push_back(Hit{face, {tlo[0], tlo[1], tlo[2]}, {thi[0], thi[1], thi[2]}});
    });
  }

  /// The tested faces in leaf (Morton) order.
  const std::vector<std::int64_t>& leafFaces() const { return face_; }

 private:
  /// Calls emit(face, lo, hi) for the faces (in depth-first leaf order) whose double bounding boxes meet
  /// [lo, hi], at most `limit` times: false when a further face was found.
  template <typename Emit>
  bool visit(const double lo[3], const double hi[3], std::size_t limit, Emit&& emit) const {
    if (nodes_.empty()) return true;
    const float flo[3] = {down(lo[0]), down(lo[1]), down(lo[2])};
    const float fhi[3] = {up(hi[0]), up(hi[1]), up(hi[2])};
    std::size_t room = limit;
    std::uint32_t stack[kMaxDepth + 2];
    int sp = 0;
    stack[sp++] = 0;
    while (sp > 0) {
      const std::uint32_t self = stack[--sp];
      const Node& n = nodes_[self];
      if (!meets(n.box, flo, fhi)) continue;
      if (n.count == 0) {
        stack[sp++] = n.index;
        stack[sp++] = self + 1;
        continue;
      }
      for (std::size_t k = n.index; k < std::size_t{n.index} + n.count; ++k) {
        if (!meets(leafBox_[k], flo, fhi)) continue;
        double tlo[3], thi[3];
        faces_.box(static_cast<std::size_t>(face_[k]), tlo, thi);
        bool miss = false;
        for (int c = 0; c < 3; ++c) miss = miss || tlo[c] > hi[c] || thi[c] < lo[c];
        if (miss) continue;
        if (room == 0) return false;
        emit(face_[k], tlo, thi);
        --room;
      }
    }
    return true;
  }

  static constexpr std::size_t kBoxLeaf = 4;
  // The query stack's bound: a query holds at most one pending right child a level.
  static constexpr int kMaxDepth = detail::kMortonTreeDepth;
  struct Box {
    float lo[3], hi[3];
  };
  struct Node {
    Box box;
    std::uint32_t index;  // leaf: first slot; inner: right child (left = this + 1)
    std::uint32_t count;  // leaf: faces; inner: 0
  };
  static float down(double x) {
    float f = static_cast<float>(x);
    if (static_cast<double>(f) > x) f = std::nextafter(f, -std::numeric_limits<float>::infinity());
    return f;
  }
  static float up(double x) {
    float f = static_cast<float>(x);
    if (static_cast<double>(f) < x) f = std::nextafter(f, std::numeric_limits<float>::infinity());
    return f;
  }
  static bool meets(const Box& b, const float lo[3], const float hi[3]) {
    return !(b.lo[0] > hi[0] || b.hi[0] < lo[0] || b.lo[1] > hi[1] || b.hi[1] < lo[1] || b.lo[2] > hi[2] ||
             b.hi[2] < lo[2]);
  }
  static void unite(Box& a, const Box& b) {
    for (int c = 0; c < 3; ++c) {
      a.lo[c] = std::min(a.lo[c], b.lo[c]);
      a.hi[c] = std::max(a.hi[c], b.hi[c]);
    }
  }
  /// Builds the subtree of slots [begin, end) (sorted codes) at nodes_.size(), returning its box.
  Box build(std::size_t begin, std::size_t end, int depth) {
    const std::size_t self = nodes_.size();
    nodes_.push_back(Node{});
    const std::size_t count = end - begin;
    if (count <= kBoxLeaf || depth >= kMaxDepth) {
      Box b = leafBox_[begin];
      for (std::size_t k = begin + 1; k < end; ++k) unite(b, leafBox_[k]);
      nodes_[self] = Node{b, static_cast<std::uint32_t>(begin), static_cast<std::uint32_t>(count)};
      return b;
    }
    const std::size_t mid = detail::radixSplit(code_.data(), begin, end);
    Box b = build(begin, mid, depth + 1);
    const auto right = static_cast<std::uint32_t>(nodes_.size());
    unite(b, build(mid, end, depth + 1));
    nodes_[self] = Node{b, right, 0};
    return b;
  }
  const FaceSource& faces_;
  std::vector<Node> nodes_;
  std::vector<Box> leafBox_;           // leaf order
  std::vector<std::int64_t> face_;     // leaf order -> face
  std::vector<std::uint32_t> code_;    // leaf order -> Morton code (during the build)
};

SelfIntersections selfIntersectionsOf(const Mesh& mesh, const CheckOptions& options,
                                      const std::vector<std::int64_t>* faces);

}  // namespace

MeshCheck checkMesh(const Mesh& mesh, const CheckOptions& options) {
  MeshCheck r;
  r.validation = validateMesh(mesh, "mesh");
  {
    // The topology's incident-face lists (12 bytes a face), the pair search (about 140 bytes a face), the
    // quality and per-face tables; the pair search keeps only counts (bounded by candidatePairBudget).
    const double faces = static_cast<double>(mesh.faces.rows());
    std::ostringstream what;
    what.precision(3);
    what << "the mesh's " << faces << " faces";
    requireMemory(options.limits, "check", 200.0 * faces + 32.0 * static_cast<double>(mesh.vertices.rows()), what.str(),
                  "check a simplified mesh (mesh --max-triangles)");
  }
  r.topology = analyzeTopology(mesh);
  r.watertight = r.topology.watertight();
  r.manifold = r.topology.manifold();
  r.oriented = r.topology.oriented();
  r.signedVolume = signedVolume(mesh);
  r.area = surfaceArea(mesh);
  r.outward = r.signedVolume > 0.0;
  // A loop needs a boundary edge (both count edges of one face with three distinct indices): a closed
  // mesh skips the sort of its 3·#F edge keys.
  r.boundaryLoops = r.topology.boundaryEdges == 0 ? 0 : countBoundaryLoops(mesh);
  if (!(options.maxSliverShare >= 0.0) || !(options.maxSliverShare <= 1.0)) {
    throw InvalidArgument("check: the sliver share must be in [0, 1]");
  }
  r.quality = triangleQuality(mesh, options.sliverAngle);
  r.tooManySlivers =
      static_cast<double>(r.quality.slivers) > options.maxSliverShare * static_cast<double>(r.quality.faces);
  if (r.manifold && r.oriented && !r.empty()) {
    const long long twice = 2 * static_cast<long long>(r.topology.components) - r.topology.eulerCharacteristic -
                            static_cast<long long>(r.boundaryLoops);
    if (twice >= 0 && twice % 2 == 0) {
      r.genusKnown = true;
      r.genus = twice / 2;
    }
  }
  if (!options.selfIntersections) return r;
  r.selfIntersectionsChecked = true;
  SelfIntersections x = selfIntersectionsOf(mesh, options, nullptr);
  r.selfIntersections = x.count;
  r.selfIntersectionsComplete = x.complete;
  r.pairs = std::move(x.pairs);
  return r;
}

SelfIntersections findSelfIntersections(const Mesh& mesh, const CheckOptions& options,
                                        const std::vector<std::int64_t>* faces) {
  if (mesh.faces.rows() == 0) return {};
  validateMesh(mesh, "self-intersections");
  return selfIntersectionsOf(mesh, options, faces);
}

namespace {

/// The faces whose boxes can meet an asked face's query box (its box grown by its tolerance), in face
/// order: the asked faces go into a box tree of their own, and each face's box, grown by twice the largest
/// tolerance of an asked face, is looked up there; a face kept by neither cannot be a candidate of an asked
/// face. So a subset query builds its tree over a neighbourhood of the faces asked about instead of the
/// whole mesh (the projection's undo asks about a few hundred faces of millions; fandisk_550k's offset
/// mesh: 3.5 s a round before). The pairs found are the same; only where a face has more candidates than
/// its per-face bound (CheckOptions::candidatePairBudget, at least 1024) can the prefix examined, and so an
/// incomplete count, differ.
std::vector<std::int64_t> nearAsked(const FaceSource& faces, const std::vector<char>& asked) {
  std::vector<std::int64_t> askedFaces;
  double grow = 0.0;
  for (std::size_t i = 0; i < asked.size(); ++i) {
    if (!asked[i]) continue;
    askedFaces.push_back(static_cast<std::int64_t>(i));
    grow = std::max(grow, faces.tolOf(i));
  }
  if (askedFaces.empty()) return {};
  const BoxTree near(faces, askedFaces);
  std::vector<char> keep(asked.size(), 0);
  const auto n = static_cast<long long>(asked.size());
  measure_detail::ParallelErrors errors;
#pragma omp parallel default(none) shared(faces, near, keep, n, grow, errors)
  {
    std::vector<std::int64_t> hit;  // one per thread: at most one face a query
#pragma omp for schedule(dynamic, 4096)
    for (long long k = 0; k < n; ++k) {
      errors.run([&] {
        double lo[3], hi[3];
        faces.box(static_cast<std::size_t>(k), lo, hi);
        for (int c = 0; c < 3; ++c) {
          lo[c] -= 2.0 * grow;
          hi[c] += 2.0 * grow;
        }
        hit.clear();
        near.overlapping(lo, hi, hit, 1);
        keep[static_cast<std::size_t>(k)] = hit.empty() ? 0 : 1;
      });
    }
  }
  errors.rethrow();
  std::vector<std::int64_t> out;
  for (std::size_t k = 0; k < keep.size(); ++k) {
    if (keep[k]) out.push_back(static_cast<std::int64_t>(k));
  }
  return out;
}

/// findSelfIntersections on a mesh validateMesh has accepted.
SelfIntersections selfIntersectionsOf(const Mesh& mesh, const CheckOptions& options,
                                      const std::vector<std::int64_t>* faces) {
  SelfIntersections r;
  const auto nf = static_cast<std::size_t>(mesh.faces.rows());
  // The faces asked about (every face when `faces` is null); a pair with both faces asked about is counted
  // by the one that owns it, a pair with one by that one.
  std::vector<char> asked;
  if (faces) {
    asked.assign(nf, 0);
    for (const std::int64_t i : *faces) {
      if (i < 0 || static_cast<std::size_t>(i) >= nf) {
        throw InvalidArgument("self-intersections: face " + std::to_string(i) + " asked about is outside [0, " +
                              std::to_string(nf) + ")");
      }
      asked[static_cast<std::size_t>(i)] = 1;
    }
  }
  if (nf == 0 || (faces && faces->empty())) return r;
  // Tolerances and the tested list (16 bytes a face), the welded ids, and the box tree: sort keys (16),
  // leaf boxes, faces and codes (36), nodes (32 each, fewer than one a face on meshes, at most two).
  requireMemory(options.limits, "self-intersection test", 140.0 * static_cast<double>(nf),
                "the mesh's " + std::to_string(nf) + " faces", "check a simplified mesh (mesh --max-triangles)");
  // A small subset (the projection's later undo rounds) is looked at only within its faces'
  // neighbourhood: the tree, the tolerances and the welded ids cover those faces only. A large one (its
  // first round: the faces around every moved vertex) takes every face, as the neighbourhood search would
  // cost more than it saves.
  const bool local = faces && faces->size() <= nf / 16;
  std::vector<std::int64_t> tested;
  std::vector<char> usedVertex;
  if (local) {
    tested = nearAsked(FaceSource{mesh.faces.data(), mesh.vertices.data(), nullptr}, asked);
    usedVertex.assign(static_cast<std::size_t>(mesh.vertices.rows()), 0);
    for (const std::int64_t i : tested) {
      for (Eigen::Index k = 0; k < 3; ++k) usedVertex[static_cast<std::size_t>(mesh.faces(static_cast<Eigen::Index>(i), k))] = 1;
    }
  } else {
    tested.resize(nf);
    std::iota(tested.begin(), tested.end(), std::int64_t{0});
  }
  const std::vector<std::int32_t> welded = weldedIds(mesh, local ? &usedVertex : nullptr);
  const FaceSource source{mesh.faces.data(), mesh.vertices.data(), welded.data()};
  // The tree holds only the triangles tested (degenerate ones are skipped), so that the per-face bound
  // below is spent on real candidates. Each face's tolerance (negative: degenerate or not looked at)
  // decides a pair's owner before the candidate is prepared.
  std::vector<double> tol(nf, -1.0);
  std::size_t kept = 0;
  for (const std::int64_t i : tested) {
    const Tri t = source.tri(static_cast<std::size_t>(i));
    if (t.skip) continue;
    tol[static_cast<std::size_t>(i)] = t.tol;
    tested[kept++] = i;
  }
  tested.resize(kept);
  if (tested.empty()) return r;
  const BoxTree tree(source, tested);
  // Each face examines at most `perFace` candidates (a deterministic prefix in tree order), so the work is
  // at most max(1024·#F, budget) pair tests. Pairs are counted, not stored: each thread keeps only its
  // smallest `listed` pairs for the examples.
  const std::size_t perFace = std::max<std::size_t>(1024, options.candidatePairBudget / tested.size());
  const std::size_t listed = options.listedPairs;
  using Pair = std::pair<std::int64_t, std::int64_t>;
  std::vector<Pair> examples;
  std::size_t count = 0;
  bool complete = true;
  measure_detail::ParallelErrors errors;
  // Queries by groups of up to four consecutive tested faces in the tree's leaf (Morton) order, close
  // together: the asked faces of a group share one walk of the tree with the union of their query boxes,
  // and each keeps the hits that meet its own box. Those are the hits, in the same depth-first order and
  // under the same bound, of a walk of its own, which each face takes when the union has more than perFace
  // hits a face. The walks were 60% of the search on fandisk_550k's 3.7M-face mesh.
  const std::vector<std::int64_t>& order = tree.leafFaces();
  const auto ngroups = static_cast<long long>((order.size() + kQueryGroup - 1) / kQueryGroup);
  const bool subset = faces != nullptr;
#pragma omp parallel default(none) shared(source, tol, order, tree, examples, ngroups, perFace, listed, errors, asked, subset) \
    reduction(+ : count) reduction(&& : complete)
  {
    // Exceptions (bad_alloc) are caught per iteration: one leaving the loop would skip its barrier.
    std::vector<Pair> mine;
    std::vector<BoxTree::Hit> hits;
    // Keeps the `listed` smallest of `mine` once it has grown to twice that.
    auto trim = [&mine, listed] {
      if (mine.size() <= listed) return;
      std::nth_element(mine.begin(), mine.begin() + static_cast<std::ptrdiff_t>(listed), mine.end());
      mine.resize(listed);
    };
    // Candidate j of face ii (prepared as s): the owner tests the pair.
    const auto consider = [&](const Tri& s, std::int64_t ii, std::int64_t j) {
      if (j == ii) return;
      // The triangle with the larger tolerance (its box query is the wider one) owns the pair; with a
      // subset, a face not asked about owns nothing.
      const bool tAsked = !subset || asked[static_cast<std::size_t>(j)];
      const double tTol = tol[static_cast<std::size_t>(j)];
      if (tAsked && (tTol > s.tol || (tTol == s.tol && j < ii))) return;
      const Tri t = source.tri(static_cast<std::size_t>(j));
      if (!pairIntersect(s, t, tAsked ? s.tol : std::max(s.tol, t.tol))) return;
      ++count;
      if (listed == 0) return;
      mine.emplace_back(std::min<std::int64_t>(ii, j), std::max<std::int64_t>(ii, j));
      if (mine.size() / 2 >= listed) trim();
    };
#pragma omp for schedule(dynamic, 128)
    for (long long g = 0; g < ngroups; ++g) {
      errors.run([&] {
        Tri qs[kQueryGroup];
        std::int64_t qf[kQueryGroup];
        double qlo[kQueryGroup][3], qhi[kQueryGroup][3];
        double ulo[3] = {HUGE_VAL, HUGE_VAL, HUGE_VAL}, uhi[3] = {-HUGE_VAL, -HUGE_VAL, -HUGE_VAL};
        std::size_t nq = 0;
        const std::size_t begin = static_cast<std::size_t>(g) * kQueryGroup;
        for (std::size_t k = begin; k < std::min(order.size(), begin + kQueryGroup); ++k) {
          const std::int64_t ii = order[k];
          if (subset && !asked[static_cast<std::size_t>(ii)]) continue;
          const Tri& s = qs[nq] = source.tri(static_cast<std::size_t>(ii));
          qf[nq] = ii;
          for (int c = 0; c < 3; ++c) {
            qlo[nq][c] = std::min({s.p[c], s.p[3 + c], s.p[6 + c]}) - s.tol;
            qhi[nq][c] = std::max({s.p[c], s.p[3 + c], s.p[6 + c]}) + s.tol;
            ulo[c] = std::min(ulo[c], qlo[nq][c]);
            uhi[c] = std::max(uhi[c], qhi[nq][c]);
          }
          ++nq;
        }
        if (nq == 0) return;
        hits.clear();
        if (!tree.overlapping(ulo, uhi, hits, perFace * nq)) {
          // More hits than the group's bound: each face walks alone, under its own.
          for (std::size_t a = 0; a < nq; ++a) {
            hits.clear();
            if (!tree.overlapping(qlo[a], qhi[a], hits, perFace)) complete = false;
            for (const BoxTree::Hit& h : hits) consider(qs[a], qf[a], h.face);
          }
          return;
        }
        for (std::size_t a = 0; a < nq; ++a) {
          std::size_t taken = 0;
          for (const BoxTree::Hit& h : hits) {
            bool miss = false;
            for (int c = 0; c < 3; ++c) miss = miss || h.lo[c] > qhi[a][c] || h.hi[c] < qlo[a][c];
            if (miss) continue;
            if (taken == perFace) {
              complete = false;
              break;
            }
            ++taken;
            consider(qs[a], qf[a], h.face);
          }
        }
      });
    }
    errors.run(trim);
#pragma omp critical(duplexfit_check_pairs)
    errors.run([&] { examples.insert(examples.end(), mine.begin(), mine.end()); });
  }
  errors.rethrow();
  std::sort(examples.begin(), examples.end());
  examples.resize(std::min(examples.size(), listed));
  r.count = count;
  r.complete = complete;
  r.pairs = std::move(examples);
  return r;
}

}  // namespace

bool geom::anyTrianglesMeet(const double* corners, const std::int32_t* ids, std::size_t n, std::size_t m) {
  struct Prepared {
    Tri t;
    double lo[3], hi[3];
  };
  std::vector<Prepared> tris(n + m);
  for (std::size_t i = 0; i < n + m; ++i) {
    Prepared& x = tris[i];
    x.t = preparedTri(corners + 9 * i, ids + 3 * i);
    for (int c = 0; c < 3; ++c) {
      x.lo[c] = std::min({x.t.p[c], x.t.p[3 + c], x.t.p[6 + c]});
      x.hi[c] = std::max({x.t.p[c], x.t.p[3 + c], x.t.p[6 + c]});
    }
  }
  for (std::size_t i = 0; i < n; ++i) {
    const Prepared& s = tris[i];
    if (s.t.skip) continue;
    for (std::size_t j = i + 1; j < n + m; ++j) {
      const Prepared& t = tris[j];
      if (t.t.skip) continue;
      const double tol = std::max(s.t.tol, t.t.tol);
      bool apart = false;
      for (int c = 0; c < 3; ++c) apart = apart || s.lo[c] > t.hi[c] + tol || t.lo[c] > s.hi[c] + tol;
      if (!apart && pairIntersect(s.t, t.t, tol)) return true;
    }
  }
  return false;
}

}  // namespace duplexfit
