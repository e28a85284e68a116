// cleanMesh: edge collapses of short edges (needles, near-duplicate vertices) and edge flips of caps, with
// the checks that keep a closed 2-manifold one (link condition, no merged triangles, no flipped or
// float32-degenerate neighbour), so that no triangle is degenerate once written in float32.
#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <functional>
#include <iterator>
#include <queue>
#include <tuple>
#include <vector>

#include <Eigen/Cholesky>
#include <Eigen/Geometry>

#include "duplexfit/error.hpp"
#include "duplexfit/measure.hpp"
#include "duplexfit/mesh_finish.hpp"
#include "measure/geometry.hpp"
#include "surfaces/collapse.hpp"

namespace duplexfit {

namespace {

using Vec = Eigen::Vector3d;
using Tri = std::array<int, 3>;

double cosDegrees(double degrees) { return std::cos(degrees * M_PI / 180.0); }

/// A collapse whose surviving faces turn more than 60 degrees from the local normal (cosine below this)
/// is tested for crossings with the faces around it (Cleaner::crossesNearby).
constexpr double kSharpCos = 0.5;

/// Whether the triangle has an interior angle above the one whose cosine is cosCap (an angle in (90, 180)
/// degrees), and its corner. Only the corner opposite the longest edge can hold an angle above 90 degrees, so
/// one cosine decides it (no arc tangent a corner: this test runs on every face of a fine mesh).
bool isCap(const Vec& a, const Vec& b, const Vec& c, double cosCap, int& corner) {
  const Vec p[3] = {a, b, c};
  const double opposite[3] = {(c - b).squaredNorm(), (a - c).squaredNorm(), (b - a).squaredNorm()};
  corner = 0;
  for (int k = 1; k < 3; ++k) {
    if (opposite[k] > opposite[corner]) corner = k;
  }
  const Vec e1 = p[(corner + 1) % 3] - p[corner], e2 = p[(corner + 2) % 3] - p[corner];
  // A zero-length side gives NaN here: no angle, not a cap (as atan2(0, 0) = 0 would say).
  const double cosine = e1.dot(e2) / std::sqrt(e1.squaredNorm() * e2.squaredNorm());
  return cosine < cosCap;
}

class Cleaner {
 public:
  Cleaner(const Mesh& mesh, const CleanOptions& options) : o_(options), cosCap_(cosDegrees(options.capAngle)) {
    const auto nv = static_cast<std::size_t>(mesh.vertices.rows());
    const auto nf = static_cast<std::size_t>(mesh.faces.rows());
    p_.resize(nv);
    for (std::size_t v = 0; v < nv; ++v) p_[v] = mesh.vertices.row(static_cast<Eigen::Index>(v));
    f_.resize(nf);
    alive_.assign(nf, 1);
    vf_.resize(nv);
    // Each vertex's face list reserved at its degree first: one allocation a vertex instead of the
    // doubling's four (the allocations were a tenth of fandisk_550k's cleaning).
    {
      std::vector<int> degree(nv, 0);
      for (Eigen::Index i = 0; i < mesh.faces.rows(); ++i) {
        for (int k = 0; k < 3; ++k) {
          const Index v = mesh.faces(i, k);
          if (v >= 0 && static_cast<std::size_t>(v) < nv) ++degree[static_cast<std::size_t>(v)];
        }
      }
      for (std::size_t v = 0; v < nv; ++v) vf_[v].reserve(static_cast<std::size_t>(degree[v]));
    }
    for (std::size_t i = 0; i < nf; ++i) {
      Tri& t = f_[i];
      for (int k = 0; k < 3; ++k) {
        t[static_cast<std::size_t>(k)] = mesh.faces(static_cast<Eigen::Index>(i), k);
        if (t[static_cast<std::size_t>(k)] < 0 || static_cast<std::size_t>(t[static_cast<std::size_t>(k)]) >= nv) {
          throw InvalidArgument("cleanMesh: face " + std::to_string(i) + " has an index out of range");
        }
      }
      if (t[0] == t[1] || t[1] == t[2] || t[0] == t[2]) {
        alive_[i] = 0;  // a repeated index: no triangle at all
        continue;
      }
      for (int v : t) vf_[static_cast<std::size_t>(v)].push_back(static_cast<int>(i));
      ++aliveFaces_;
    }
    lockNonManifold();
  }

  /// Quadric-error simplification with the same safe collapses (Garland–Heckbert: each vertex carries the
  /// sum of the squared distances to the planes of its original faces; an edge costs the smallest sum at
  /// the optimal point, the midpoint or either end): cheapest first, until at most `target` faces remain
  /// (0: no budget) or the cheapest collapse would move the surface by more than maxError (0: no bound).
  void simplify(std::size_t target, double maxError) {
    quadrics_.assign(p_.size(), Quadric{});
    version_.assign(p_.size(), 0);
    for (std::size_t i = 0; i < f_.size(); ++i) {
      if (!alive_[i]) continue;
      const Tri& t = f_[i];
      const Vec n = normal(t);
      const double len = n.norm();
      if (!(len > 0.0)) continue;
      const Vec u = n / len;
      for (int v : t) quadrics_[static_cast<std::size_t>(v)].addPlane(u, u.dot(pos(t[0])));
    }
    // A bucket queue on the cost's logarithm (a quarter octave a bucket, last in first out inside one): a
    // binary heap of 24-byte entries spent most of the simplification in its sift-downs on fine meshes (about
    // four entries a face, far beyond the caches), and the order within a factor 2^(1/4) of cost hardly
    // matters. An entry is stale when an end's version moved since the push: versions only grow, so their
    // sum says so exactly.
    struct Entry {
      std::uint32_t a, b, stamp;
    };
    constexpr int kMinExp = -120, kMaxExp = 40, kPerOctave = 4;
    std::vector<std::vector<Entry>> buckets(static_cast<std::size_t>((kMaxExp - kMinExp) * kPerOctave + 2));
    std::size_t lowest = buckets.size();
    const auto bucketOf = [&](double cost) -> std::size_t {
      if (!(cost > 0.0)) return 0;
      const double x = std::floor(kPerOctave * (std::log2(cost) - kMinExp));
      return static_cast<std::size_t>(std::clamp(x + 1.0, 1.0, static_cast<double>(buckets.size() - 1)));
    };
    // Squared costs above the bound are never collapsed (costs only grow as quadrics add up, and an edge
    // whose ends change is pushed again), so they are not queued.
    const double maxCost = maxError > 0.0 ? maxError * maxError : HUGE_VAL;
    std::vector<Vec> positions;
    const auto stampOf = [&](int a, int b) {
      return static_cast<std::uint32_t>(version_[static_cast<std::size_t>(a)] + version_[static_cast<std::size_t>(b)]);
    };
    const auto push = [&](int a, int b) {
      if (a > b) std::swap(a, b);
      const double cost = edgeCost(a, b, positions);
      if (!(std::max(cost, 0.0) <= maxCost)) return;
      const std::size_t k = bucketOf(cost);
      buckets[k].push_back(Entry{static_cast<std::uint32_t>(a), static_cast<std::uint32_t>(b), stampOf(a, b)});
      lowest = std::min(lowest, k);
    };
    for (std::size_t i = 0; i < f_.size(); ++i) {
      if (!alive_[i]) continue;
      for (int k = 0; k < 3; ++k) {
        const int a = f_[i][static_cast<std::size_t>(k)], b = f_[i][static_cast<std::size_t>((k + 1) % 3)];
        if (a < b) push(a, b);
      }
    }
    std::vector<int> around;
    while (target == 0 || aliveFaces_ > target) {
      while (lowest < buckets.size() && buckets[lowest].empty()) ++lowest;
      if (lowest == buckets.size()) break;
      const Entry top = buckets[lowest].back();
      buckets[lowest].pop_back();
      const int a = static_cast<int>(top.a), b = static_cast<int>(top.b);
      if (top.stamp != stampOf(a, b)) continue;
      if (!vAlive(a) || !vAlive(b) || !hasEdge(a, b)) continue;
      const double cost = edgeCost(a, b, positions);
      if (maxError > 0.0 && std::sqrt(std::max(cost, 0.0)) > maxError) continue;
      if (!tryCollapse(a, b, &positions)) continue;
      quadrics_[static_cast<std::size_t>(a)] += quadrics_[static_cast<std::size_t>(b)];
      ++version_[static_cast<std::size_t>(a)];
      ++version_[static_cast<std::size_t>(b)];
      neighbours(a, around);
      for (int n : around) push(a, n);
    }
  }

  /// Phase 1: collapse edges shorter than the collapse length or with float32-coincident ends, shortest
  /// first; repeated while a pass collapses something (a refusal can go away when a neighbour collapses).
  void collapseShort() {
    std::vector<int> around;
    for (int pass = 0; pass < 4; ++pass) {
      const std::size_t before = report.collapses;
      // Shortest first: the pass's edges sorted once, the edges around each collapse in a heap, the two
      // taken in one order (the order of one heap over both, so the same collapses). The sorted edges are
      // read ahead, their ends' data fetched before they are needed: a heap of all of them (fandisk_50k_
      // noise0.5pct's zero level: 591k) spent its pops waiting for the ends' face lists and positions.
      using Entry = std::tuple<double, int, int>;
      std::vector<Entry> sorted;
      std::priority_queue<Entry, std::vector<Entry>, std::greater<Entry>> heap;
      const auto lengthIfShort = [&](int a, int b, double& len) {
        len = (p_[static_cast<std::size_t>(a)] - p_[static_cast<std::size_t>(b)]).norm();
        return isShort(a, b, len);
      };
      const auto consider = [&](int a, int b) {
        if (a > b) std::swap(a, b);
        double len = 0.0;
        if (lengthIfShort(a, b, len)) heap.emplace(len, a, b);
      };
      for (std::size_t i = 0; i < f_.size(); ++i) {
        if (!alive_[i]) continue;
        const Tri& t = f_[i];
        for (int k = 0; k < 3; ++k) {
          const int a = t[static_cast<std::size_t>(k)], b = t[static_cast<std::size_t>((k + 1) % 3)];
          double len = 0.0;
          // each interior edge once (its other face traverses it b → a)
          if (a < b && lengthIfShort(a, b, len)) sorted.emplace_back(len, a, b);
        }
      }
      std::sort(sorted.begin(), sorted.end());
      constexpr std::size_t kAhead = 8;
      std::size_t next = 0;
      while (next < sorted.size() || !heap.empty()) {
        Entry e;
        if (next < sorted.size() && (heap.empty() || !(heap.top() < sorted[next]))) {
          if (next + kAhead < sorted.size()) {
            const auto& [l, u, w] = sorted[next + kAhead];
            (void)l;
            __builtin_prefetch(&vf_[static_cast<std::size_t>(u)]);
            __builtin_prefetch(&vf_[static_cast<std::size_t>(w)]);
            __builtin_prefetch(&p_[static_cast<std::size_t>(u)]);
            __builtin_prefetch(&p_[static_cast<std::size_t>(w)]);
          }
          if (next + kAhead / 2 < sorted.size()) {  // the face lists, their headers fetched above
            const auto& [l, u, w] = sorted[next + kAhead / 2];
            (void)l;
            (void)w;
            const std::vector<int>& faces = vf_[static_cast<std::size_t>(u)];
            if (!faces.empty()) {
              __builtin_prefetch(faces.data());
              __builtin_prefetch(&f_[static_cast<std::size_t>(faces.front())]);
            }
          }
          e = sorted[next++];
        } else {
          e = heap.top();
          heap.pop();
        }
        const auto [len, a, b] = e;
        if (!vAlive(a) || !vAlive(b)) continue;
        if ((p_[static_cast<std::size_t>(a)] - p_[static_cast<std::size_t>(b)]).norm() != len) continue;  // stale
        if (!hasEdge(a, b)) continue;
        if (!tryCollapse(a, b)) continue;
        neighbours(a, around);
        for (int n : around) consider(a, n);
      }
      if (report.collapses == before) break;
    }
  }

  /// Phase 2: flip the edge opposite a cap's large angle when that improves the pair.
  void flipCaps() {
    if (!o_.flips) return;
    for (int pass = 0; pass < 3; ++pass) {
      std::size_t flipped = 0;
      for (std::size_t i = 0; i < f_.size(); ++i) {
        if (alive_[i] && tryFlip(static_cast<int>(i))) ++flipped;
      }
      report.flips += flipped;
      if (flipped == 0) break;
    }
  }

  /// Phase 3: a triangle still degenerate in float32 (collinear corners, or a refused short edge):
  /// collapse its edges, shortest first, whatever their length.
  void collapseDegenerate() {
    for (int pass = 0; pass < 3; ++pass) {
      bool changed = false;
      for (std::size_t i = 0; i < f_.size(); ++i) {
        if (!alive_[i]) continue;
        const Tri t = f_[i];
        if (!float32Degenerate(pos(t[0]), pos(t[1]), pos(t[2]))) continue;
        std::array<std::pair<double, int>, 3> edges;
        for (int k = 0; k < 3; ++k) {
          edges[static_cast<std::size_t>(k)] = {(pos(t[static_cast<std::size_t>(k)]) -
                                                 pos(t[static_cast<std::size_t>((k + 1) % 3)]))
                                                    .norm(),
                                                k};
        }
        std::sort(edges.begin(), edges.end());
        for (const auto& e : edges) {
          const int a = t[static_cast<std::size_t>(e.second)], b = t[static_cast<std::size_t>((e.second + 1) % 3)];
          if (tryCollapse(std::min(a, b), std::max(a, b))) {
            changed = true;
            break;
          }
        }
      }
      if (!changed) break;
    }
  }

  Mesh result() const {
    std::vector<int> id(p_.size(), -1);
    std::size_t nf = 0;
    for (std::size_t i = 0; i < f_.size(); ++i) {
      if (!alive_[i]) continue;
      ++nf;
      for (int v : f_[i]) id[static_cast<std::size_t>(v)] = 0;
    }
    int next = 0;
    for (int& x : id) {
      if (x == 0) x = next++;
    }
    Mesh m;
    m.vertices.resize(next, 3);
    for (std::size_t v = 0; v < p_.size(); ++v) {
      if (id[v] >= 0) m.vertices.row(id[v]) = p_[v].transpose();
    }
    m.faces.resize(static_cast<Eigen::Index>(nf), 3);
    Eigen::Index row = 0;
    for (std::size_t i = 0; i < f_.size(); ++i) {
      if (!alive_[i]) continue;
      for (int k = 0; k < 3; ++k) m.faces(row, k) = id[static_cast<std::size_t>(f_[i][static_cast<std::size_t>(k)])];
      ++row;
    }
    return m;
  }

  CleanReport report;

 private:
  const Vec& pos(int v) const { return p_[static_cast<std::size_t>(v)]; }
  bool vAlive(int v) const { return !vf_[static_cast<std::size_t>(v)].empty(); }
  static bool contains(const Tri& t, int v) { return t[0] == v || t[1] == v || t[2] == v; }

  bool isShort(int a, int b, double len) const {
    return len < o_.collapseLength || pos(a).cast<float>() == pos(b).cast<float>();
  }

  bool hasEdge(int a, int b) const {
    for (int f : vf_[static_cast<std::size_t>(a)]) {
      if (contains(f_[static_cast<std::size_t>(f)], b)) return true;
    }
    return false;
  }

  std::vector<int> neighbours(int v) const {
    std::vector<int> n;
    neighbours(v, n);
    return n;
  }
  /// The same into `n` (its storage reused).
  void neighbours(int v, std::vector<int>& n) const {
    n.clear();
    for (int f : vf_[static_cast<std::size_t>(v)]) {
      for (int w : f_[static_cast<std::size_t>(f)]) {
        if (w != v) n.push_back(w);
      }
    }
    std::sort(n.begin(), n.end());
    n.erase(std::unique(n.begin(), n.end()), n.end());
  }

  /// Locks the ends of every edge without exactly two faces traversing it in opposite directions, and
  /// every vertex whose faces do not form a single closed fan.
  void lockNonManifold() {
    locked_.assign(p_.size(), 0);
    // Every edge {a, b} with a < b, from a's faces: a manifold edge has exactly two directed copies, one
    // each way; any other count locks both ends. (A mesh-wide sort of the directed edges took 0.4 s of
    // cleaning a 4M-face mesh.)
    std::vector<std::pair<int, int>> around;  // (b, +1 for a → b / −1 for b → a)
    for (std::size_t a = 0; a < p_.size(); ++a) {
      around.clear();
      const int va = static_cast<int>(a);
      for (const int f : vf_[a]) {
        const Tri& t = f_[static_cast<std::size_t>(f)];
        for (int k = 0; k < 3; ++k) {
          if (t[static_cast<std::size_t>(k)] != va) continue;
          const int next = t[static_cast<std::size_t>((k + 1) % 3)], prev = t[static_cast<std::size_t>((k + 2) % 3)];
          if (next > va) around.emplace_back(next, 1);
          if (prev > va) around.emplace_back(prev, -1);
        }
      }
      std::sort(around.begin(), around.end());
      for (std::size_t i = 0; i < around.size();) {
        std::size_t j = i;
        int sum = 0;
        while (j < around.size() && around[j].first == around[i].first) sum += around[j++].second;
        if (j - i != 2 || sum != 0) {
          locked_[a] = 1;
          locked_[static_cast<std::size_t>(around[i].first)] = 1;
        }
        i = j;
      }
    }
    for (std::size_t v = 0; v < p_.size(); ++v) {
      if (!locked_[v] && !vf_[v].empty() && !closedFan(static_cast<int>(v))) locked_[v] = 1;
    }
    report.lockedVertices = static_cast<std::size_t>(std::count(locked_.begin(), locked_.end(), 1));
  }

  /// The faces around v form one closed, consistently oriented fan.
  bool closedFan(int v) const {
    const std::vector<int>& faces = vf_[static_cast<std::size_t>(v)];
    // Face (v, b, c) leads to the face (v, c, d): follow "next" from each face's last corner.
    std::vector<std::pair<int, int>>& nextPrev = scratchFan_;  // (b, c) per face
    nextPrev.clear();
    for (int f : faces) {
      const Tri& t = f_[static_cast<std::size_t>(f)];
      const int k = t[0] == v ? 0 : (t[1] == v ? 1 : 2);
      nextPrev.emplace_back(t[static_cast<std::size_t>((k + 1) % 3)], t[static_cast<std::size_t>((k + 2) % 3)]);
    }
    std::size_t steps = 0, cur = 0;
    do {
      const int want = nextPrev[cur].second;
      std::size_t found = nextPrev.size();
      for (std::size_t j = 0; j < nextPrev.size(); ++j) {
        if (nextPrev[j].first == want) {
          if (found != nextPrev.size()) return false;  // two faces continue the fan
          found = j;
        }
      }
      if (found == nextPrev.size()) return false;
      cur = found;
      ++steps;
    } while (cur != 0 && steps <= nextPrev.size());
    return cur == 0 && steps == nextPrev.size();
  }

  /// Collapses edge (a, b) into a (at the first of `positions` that passes the checks; default: the
  /// midpoint, else a's or b's position) when that is safe.
  bool tryCollapse(int a, int b, const std::vector<Vec>* positions = nullptr) {
    if (locked_[static_cast<std::size_t>(a)] || locked_[static_cast<std::size_t>(b)]) {
      ++report.refusedTopology;
      return false;
    }
    int shared[2] = {-1, -1}, count = 0;
    for (int f : vf_[static_cast<std::size_t>(a)]) {
      if (contains(f_[static_cast<std::size_t>(f)], b)) {
        if (count < 2) shared[count] = f;
        ++count;
      }
    }
    if (count != 2) {
      ++report.refusedTopology;
      return false;
    }
    const auto third = [&](int f) {
      const Tri& t = f_[static_cast<std::size_t>(f)];
      for (int v : t) {
        if (v != a && v != b) return v;
      }
      return -1;
    };
    const int w0 = third(shared[0]), w1 = third(shared[1]);
    // Link condition: a and b have exactly the two opposite vertices as common neighbours.
    std::vector<int>& na = scratchA_;
    std::vector<int>& nb = scratchB_;
    std::vector<int>& common = scratchCommon_;
    neighbours(a, na);
    neighbours(b, nb);
    common.clear();
    std::set_intersection(na.begin(), na.end(), nb.begin(), nb.end(), std::back_inserter(common));
    if (w0 == w1 || common.size() != 2 || !(std::find(common.begin(), common.end(), w0) != common.end() &&
                                             std::find(common.begin(), common.end(), w1) != common.end())) {
      ++report.refusedTopology;
      return false;
    }
    // The surviving faces around the merged vertex, with b renamed a: no two may be the same triangle.
    std::vector<int>& ring = scratchRing_;
    ring.clear();
    for (int f : vf_[static_cast<std::size_t>(a)]) {
      if (f != shared[0] && f != shared[1]) ring.push_back(f);
    }
    for (int f : vf_[static_cast<std::size_t>(b)]) {
      if (f != shared[0] && f != shared[1]) ring.push_back(f);
    }
    std::vector<Tri>& keys = scratchKeys_;
    keys.clear();
    for (int f : ring) {
      Tri t = f_[static_cast<std::size_t>(f)];
      for (int& v : t) {
        if (v == b) v = a;
      }
      std::sort(t.begin(), t.end());
      keys.push_back(t);
    }
    std::sort(keys.begin(), keys.end());
    if (std::adjacent_find(keys.begin(), keys.end()) != keys.end()) {
      ++report.refusedTopology;
      return false;
    }
    // The local surface normal: the area-weighted normal of every face around the edge's ends.
    Vec ringNormal = Vec::Zero();
    for (int f : ring) ringNormal += normal(f_[static_cast<std::size_t>(f)]);
    ringNormal += normal(f_[static_cast<std::size_t>(shared[0])]) + normal(f_[static_cast<std::size_t>(shared[1])]);
    const Vec defaults[3] = {0.5 * (pos(a) + pos(b)), pos(a), pos(b)};
    const Vec* first = positions ? positions->data() : defaults;
    const Vec* last = positions ? positions->data() + positions->size() : defaults + 3;
    bool crossed = false;
    for (const Vec* at = first; at != last; ++at) {
      const Vec& q = *at;
      double leastCos = 1.0;
      if (!geometryOk(ring, a, b, q, ringNormal, leastCos)) continue;
      // Where the surviving faces turn far from the local normal (a sharp crease, a tip, a thin fin), a
      // collapse can fold the surface through itself without any one face flipping: there they are tested
      // against the faces around them.
      if (leastCos < kSharpCos && crossesNearby(ring, a, b, q, shared)) {
        crossed = true;
        continue;
      }
      apply(a, b, q, shared);
      ++report.collapses;
      return true;
    }
    ++(crossed ? report.refusedCrossing : report.refusedGeometry);
    return false;
  }

  Vec normal(const Tri& t) const { return (pos(t[1]) - pos(t[0])).cross(pos(t[2]) - pos(t[0])); }

  /// Whether a surviving face (in `ring`, with a and b at q) touches or crosses a face around it: another
  /// surviving face or one with a corner on a surviving face (the two faces on the edge go).
  bool crossesNearby(const std::vector<int>& ring, int a, int b, const Vec& q, const int* shared) {
    // The faces with a corner on a surviving face, less the surviving ones and the two that go (a few dozen:
    // sorted and deduplicated in place).
    std::vector<int>& around = scratchAround_;
    around.clear();
    for (int f : ring) {
      for (int v : f_[static_cast<std::size_t>(f)]) {
        for (int g : vf_[static_cast<std::size_t>(v == b ? a : v)]) {
          if (g != shared[0] && g != shared[1]) around.push_back(g);
        }
      }
    }
    std::sort(around.begin(), around.end());
    around.erase(std::unique(around.begin(), around.end()), around.end());
    std::vector<int>& sortedRing = scratchSortedRing_;
    sortedRing.assign(ring.begin(), ring.end());
    std::sort(sortedRing.begin(), sortedRing.end());
    around.erase(std::remove_if(around.begin(), around.end(),
                                [&](int g) { return std::binary_search(sortedRing.begin(), sortedRing.end(), g); }),
                 around.end());
    // The surviving faces (a and b at q, b renamed a), then the faces around them.
    std::vector<double>& p = scratchCorners_;
    std::vector<std::int32_t>& id = scratchIds_;
    p.clear();
    id.clear();
    const auto add = [&](int f) {
      for (int v : f_[static_cast<std::size_t>(f)]) {
        const bool moved = v == a || v == b;
        const Vec& x = moved ? q : pos(v);
        p.insert(p.end(), {x[0], x[1], x[2]});
        id.push_back(moved ? a : v);
      }
    };
    for (int f : ring) add(f);
    for (int g : around) add(g);
    return geom::anyTrianglesMeet(p.data(), id.data(), ring.size(), around.size());
  }

  /// Whether the flip's new triangles t1 and t2 (replacing faces f and g) touch or cross each other beyond
  /// their shared edge, or a triangle with a corner on them.
  bool flipCrosses(int f, int g, const Tri& t1, const Tri& t2) {
    std::vector<int>& around = scratchAround_;
    around.clear();
    for (const Tri* t : {&t1, &t2}) {
      for (int v : *t) {
        for (int h : vf_[static_cast<std::size_t>(v)]) {
          if (h != f && h != g) around.push_back(h);
        }
      }
    }
    std::sort(around.begin(), around.end());
    around.erase(std::unique(around.begin(), around.end()), around.end());
    std::vector<double>& p = scratchCorners_;
    std::vector<std::int32_t>& id = scratchIds_;
    p.clear();
    id.clear();
    const auto add = [&](const Tri& t) {
      for (int v : t) {
        const Vec& x = pos(v);
        p.insert(p.end(), {x[0], x[1], x[2]});
        id.push_back(v);
      }
    };
    add(t1);
    add(t2);
    for (int h : around) add(f_[static_cast<std::size_t>(h)]);
    return geom::anyTrianglesMeet(p.data(), id.data(), 2, around.size());
  }

  /// Moving a and b to q keeps every surviving face well formed and facing the same way; leastCos receives
  /// the least cosine of a surviving face's normal with the ring's (−1 when that is zero).
  bool geometryOk(const std::vector<int>& ring, int a, int b, const Vec& q, const Vec& ringNormal,
                  double& leastCos) const {
    const double maxCos = cosDegrees(o_.maxNormalChange);
    const double ringLength = ringNormal.norm();
    leastCos = ringLength > 0.0 ? 1.0 : -1.0;
    for (int f : ring) {
      const Tri& t = f_[static_cast<std::size_t>(f)];
      Vec before[3], after[3];
      for (int k = 0; k < 3; ++k) {
        const int v = t[static_cast<std::size_t>(k)];
        before[k] = pos(v);
        after[k] = v == a || v == b ? q : pos(v);
      }
      if (float32Degenerate(after[0], after[1], after[2])) return false;
      const Vec nb = (before[1] - before[0]).cross(before[2] - before[0]);
      const Vec na = (after[1] - after[0]).cross(after[2] - after[0]);
      const double la = na.norm(), lb = nb.norm();
      if (!(la > 0.0)) return false;
      // A sliver's own normal is noise: it must only face the way the surface around it does.
      const bool sliver = !(lb > 0.0) || minAngleBelow(before[0], before[1], before[2], 1.0);
      if (sliver) {
        if (!(na.dot(ringNormal) > 0.0)) return false;
      } else if (!(na.dot(nb) >= maxCos * la * lb)) {
        return false;
      }
      if (ringLength > 0.0) leastCos = std::min(leastCos, na.dot(ringNormal) / (la * ringLength));
    }
    return true;
  }

  void removeFace(int f) {
    alive_[static_cast<std::size_t>(f)] = 0;
    for (int v : f_[static_cast<std::size_t>(f)]) {
      std::vector<int>& list = vf_[static_cast<std::size_t>(v)];
      list.erase(std::find(list.begin(), list.end(), f));
    }
  }

  void apply(int a, int b, const Vec& q, const int* shared) {
    removeFace(shared[0]);
    removeFace(shared[1]);
    aliveFaces_ -= 2;
    std::vector<int>& fa = vf_[static_cast<std::size_t>(a)];
    for (int f : vf_[static_cast<std::size_t>(b)]) {
      for (int& v : f_[static_cast<std::size_t>(f)]) {
        if (v == b) v = a;
      }
      fa.push_back(f);
    }
    vf_[static_cast<std::size_t>(b)].clear();
    p_[static_cast<std::size_t>(a)] = q;
  }

  /// Flips the edge opposite the largest angle of face f when f is a cap and the flip is safe and better.
  bool tryFlip(int f) {
    const Tri& t = f_[static_cast<std::size_t>(f)];
    int corner = 0;
    if (!isCap(pos(t[0]), pos(t[1]), pos(t[2]), cosCap_, corner)) return false;
    const int v = t[static_cast<std::size_t>(corner)];
    const int a = t[static_cast<std::size_t>((corner + 1) % 3)], b = t[static_cast<std::size_t>((corner + 2) % 3)];
    if (locked_[static_cast<std::size_t>(a)] || locked_[static_cast<std::size_t>(b)] ||
        locked_[static_cast<std::size_t>(v)]) {
      return false;
    }
    // The other face on edge a → b traverses it b → a: (b, a, w).
    int g = -1, count = 0;
    for (int h : vf_[static_cast<std::size_t>(a)]) {
      if (h != f && contains(f_[static_cast<std::size_t>(h)], b)) {
        g = h;
        ++count;
      }
    }
    if (count != 1) return false;
    const Tri& s = f_[static_cast<std::size_t>(g)];
    int w = -1;
    for (int x : s) {
      if (x != a && x != b) w = x;
    }
    if (w < 0 || w == v || locked_[static_cast<std::size_t>(w)] || hasEdge(v, w)) return false;
    // (a, b, v) and (b, a, w) become (v, a, w) and (w, b, v).
    const Vec &pa = pos(a), &pb = pos(b), &pv = pos(v), &pw = pos(w);
    if (float32Degenerate(pv, pa, pw) || float32Degenerate(pw, pb, pv)) return false;
    const double oldMin = std::min(minAngleDegrees(pa, pb, pv), minAngleDegrees(pb, pa, pw));
    const double newMin = std::min(minAngleDegrees(pv, pa, pw), minAngleDegrees(pw, pb, pv));
    if (!(newMin > oldMin)) return false;
    const Vec n1 = (pa - pv).cross(pw - pv), n2 = (pb - pw).cross(pv - pw);
    const Vec sum = (pb - pa).cross(pv - pa) + (pa - pb).cross(pw - pb);
    const double c = cosDegrees(o_.flipNormalAngle);
    if (!(n1.dot(n2) >= c * n1.norm() * n2.norm()) || !(n1.dot(sum) >= c * n1.norm() * sum.norm()) ||
        !(n2.dot(sum) >= c * n2.norm() * sum.norm())) {
      return false;
    }
    // Two caps' new pair can pass through a triangle around them without either turning far (a thin
    // tip's flips made wheel_29k's offset at δ = 0.025 cross itself): tested as the collapses' positions are.
    if (flipCrosses(f, g, {v, a, w}, {w, b, v})) {
      ++report.refusedFlips;
      return false;
    }
    f_[static_cast<std::size_t>(f)] = {v, a, w};
    f_[static_cast<std::size_t>(g)] = {w, b, v};
    std::vector<int>& la = vf_[static_cast<std::size_t>(a)];
    la.erase(std::find(la.begin(), la.end(), g));
    std::vector<int>& lb = vf_[static_cast<std::size_t>(b)];
    lb.erase(std::find(lb.begin(), lb.end(), f));
    vf_[static_cast<std::size_t>(v)].push_back(g);
    vf_[static_cast<std::size_t>(w)].push_back(f);
    return true;
  }

  /// Σ (n·x − d)² over a set of planes.
  struct Quadric {
    Eigen::Matrix3d a = Eigen::Matrix3d::Zero();
    Vec b = Vec::Zero();
    double c = 0.0;
    void addPlane(const Vec& n, double d) {
      a += n * n.transpose();
      b += d * n;
      c += d * d;
    }
    double operator()(const Vec& x) const { return x.dot(a * x) - 2.0 * b.dot(x) + c; }
    Quadric& operator+=(const Quadric& o) {
      a += o.a;
      b += o.b;
      c += o.c;
      return *this;
    }
  };

  /// The cost of collapsing (a, b) and its candidate positions, cheapest first: the quadric's minimum
  /// (when it is well defined and within one edge length of the midpoint), the midpoint, a and b.
  double edgeCost(int a, int b, std::vector<Vec>& positions) const {
    Quadric q = quadrics_[static_cast<std::size_t>(a)];
    q += quadrics_[static_cast<std::size_t>(b)];
    const Vec mid = 0.5 * (pos(a) + pos(b));
    positions.assign({mid, pos(a), pos(b)});
    const Eigen::LDLT<Eigen::Matrix3d> ldlt(q.a);
    if (ldlt.info() == Eigen::Success && ldlt.isPositive()) {
      const Vec best = ldlt.solve(q.b);
      if (best.allFinite() && (best - mid).norm() <= (pos(a) - pos(b)).norm()) positions.push_back(best);
    }
    // Cheapest first (each candidate's cost evaluated once).
    std::array<std::pair<double, int>, 4> order{};
    const auto m = static_cast<int>(positions.size());
    for (int i = 0; i < m; ++i) order[static_cast<std::size_t>(i)] = {q(positions[static_cast<std::size_t>(i)]), i};
    for (int i = 1; i < m; ++i) {  // insertion sort of at most four
      for (int j = i; j > 0 && order[static_cast<std::size_t>(j)] < order[static_cast<std::size_t>(j - 1)]; --j) {
        std::swap(order[static_cast<std::size_t>(j)], order[static_cast<std::size_t>(j - 1)]);
      }
    }
    std::array<Vec, 4> sorted;
    for (int i = 0; i < m; ++i) sorted[static_cast<std::size_t>(i)] = positions[static_cast<std::size_t>(order[static_cast<std::size_t>(i)].second)];
    for (int i = 0; i < m; ++i) positions[static_cast<std::size_t>(i)] = sorted[static_cast<std::size_t>(i)];
    return order[0].first;
  }

  CleanOptions o_;
  double cosCap_;  ///< cos(capAngle)
  std::size_t aliveFaces_ = 0;
  std::vector<Quadric> quadrics_;
  std::vector<unsigned> version_;
  std::vector<Vec> p_;
  std::vector<Tri> f_;
  std::vector<char> alive_, locked_;
  std::vector<std::vector<int>> vf_;
  std::vector<int> scratchA_, scratchB_, scratchCommon_, scratchRing_;  ///< tryCollapse's, reused
  std::vector<int> scratchAround_, scratchSortedRing_;                  ///< crossesNearby's, reused
  std::vector<double> scratchCorners_;                                  ///< crossesNearby's, reused
  std::vector<std::int32_t> scratchIds_;                                ///< crossesNearby's, reused
  std::vector<Tri> scratchKeys_;
  mutable std::vector<std::pair<int, int>> scratchFan_;  ///< closedFan's (next, previous) per face
};

}  // namespace

CleanResult cleanMesh(const Mesh& mesh, const CleanOptions& options) {
  const auto start = std::chrono::steady_clock::now();
  if (!(options.collapseLength >= 0.0) || !std::isfinite(options.collapseLength) ||
      !(options.capAngle > 90.0 && options.capAngle < 180.0) ||
      !(options.flipNormalAngle >= 0.0 && options.flipNormalAngle <= 90.0) ||
      !(options.maxNormalChange >= 0.0 && options.maxNormalChange <= 180.0)) {
    throw InvalidArgument("cleanMesh: collapseLength must be >= 0, capAngle in (90, 180), flipNormalAngle in "
                          "[0, 90] and maxNormalChange in [0, 180]");
  }
  validateMesh(mesh, "cleanMesh");
  Cleaner cleaner(mesh, options);
  CleanReport& r = cleaner.report;
  const TriangleQuality before = triangleQuality(mesh, 1.0);
  cleaner.collapseShort();
  cleaner.flipCaps();
  cleaner.collapseDegenerate();
  CleanResult out;
  out.mesh = cleaner.result();
  const TriangleQuality after = triangleQuality(out.mesh, 1.0);
  r.verticesBefore = static_cast<std::size_t>(mesh.vertices.rows());
  r.facesBefore = static_cast<std::size_t>(mesh.faces.rows());
  r.verticesAfter = static_cast<std::size_t>(out.mesh.vertices.rows());
  r.facesAfter = static_cast<std::size_t>(out.mesh.faces.rows());
  r.float32DegenerateBefore = before.float32DegenerateFaces;
  r.float32DegenerateAfter = after.float32DegenerateFaces;
  r.sliversBefore = before.slivers;
  r.sliversAfter = after.slivers;
  r.minAngleBefore = before.minAngle;
  r.minAngleAfter = after.minAngle;
  r.shortestEdgeBefore = before.shortestEdge;
  r.shortestEdgeAfter = after.shortestEdge;
  r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  out.report = r;
  return out;
}

namespace detail {

Mesh collapseSimplify(const Mesh& mesh, std::size_t target, double maxError, std::size_t* collapses) {
  validateMesh(mesh, "simplification");
  Cleaner cleaner(mesh, CleanOptions{});
  cleaner.simplify(target, maxError);
  if (collapses) *collapses = cleaner.report.collapses;
  return cleaner.result();
}

}  // namespace detail

}  // namespace duplexfit
