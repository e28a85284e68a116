// Marching tetrahedra with edge-keyed vertex welding. Cells are visited in global (k, j, i) order,
// split into z-ranges processed in parallel; vertices get ids in order of first appearance, which
// makes the output independent of the chunking, the thread count and the sampled region.
#include "extract.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <exception>
#include <limits>
#include <unordered_map>
#include <utility>
#include <vector>

#include "duplexfit/error.hpp"
#include "duplexfit/timer.hpp"
#include "kuhn_cases.hpp"
#include "refine.hpp"
#include "sampling.hpp"

#ifdef _OPENMP
#include <omp.h>
#endif

namespace duplexfit::detail {

namespace {

/// Open-addressing hash map from edge keys (start node id · 8 + direction bits) to local vertex
/// ids, linear probing, at most half full; key and id share a slot so that a probe touches one
/// line.
class EdgeMap {
 public:
  static constexpr std::uint64_t kEmpty = ~std::uint64_t{0};

  EdgeMap() { rehash(10); }

  std::int32_t find(std::uint64_t key) const {
    for (std::size_t s = slot(key);; s = (s + 1) & mask_) {
      if (slots_[s].key == key) return slots_[s].id;
      if (slots_[s].key == kEmpty) return -1;
    }
  }
  /// The id stored for key; stores `id` first when key is absent (inserted = true).
  std::int32_t insert(std::uint64_t key, std::int32_t id, bool& inserted) {
    if (2 * (size_ + 1) > slots_.size()) rehash(bits_ + 1);
    for (std::size_t s = slot(key);; s = (s + 1) & mask_) {
      if (slots_[s].key == key) {
        inserted = false;
        return slots_[s].id;
      }
      if (slots_[s].key == kEmpty) {
        slots_[s] = {key, id};
        ++size_;
        inserted = true;
        return id;
      }
    }
  }

 private:
  struct Slot {
    std::uint64_t key;
    std::int32_t id;
  };
  std::size_t slot(std::uint64_t key) const {
    return static_cast<std::size_t>((key * 0x9E3779B97F4A7C15ull) >> (64 - bits_));
  }
  void rehash(int bits) {
    std::vector<Slot> old(std::size_t{1} << bits, Slot{kEmpty, -1});
    old.swap(slots_);
    bits_ = bits;
    mask_ = slots_.size() - 1;
    for (const Slot& o : old) {
      if (o.key == kEmpty) continue;
      std::size_t t = slot(o.key);
      while (slots_[t].key != kEmpty) t = (t + 1) & mask_;
      slots_[t] = o;
    }
  }

  std::vector<Slot> slots_;
  std::size_t size_ = 0, mask_ = 0;
  int bits_ = 0;
};

using Cell = std::array<int, 3>;

/// Least distance of a vertex from either node of its edge, in single-precision ulps of the grid's
/// largest coordinate: the meshes are written in single precision, and vertices closer to a node
/// than a few ulps round onto each other, leaving zero-area or folded triangles around that node.
constexpr double kMinNodeDistanceUlps = 64.0;

/// The contour of one iso value over one z-range of cells, with chunk-local vertex ids.
struct ChunkMesh {
  std::vector<std::uint64_t> keys;  ///< edge key of each local vertex
  std::vector<double> xyz;          ///< 3 per vertex
  std::vector<std::int32_t> tris;   ///< 3 local ids per triangle
  /// (key, local id) of the vertices in the chunk's top plane (shared with the next chunk), sorted.
  std::vector<std::pair<std::uint64_t, std::int32_t>> top;
};

/// Edge keys of the edges lying in node plane z: start node in the plane, no z direction bit.
bool inPlane(std::uint64_t key, int z, std::int64_t planeNodes) {
  const std::uint64_t lo = static_cast<std::uint64_t>(z * planeNodes) * 8;
  return (key & 4) == 0 && key >= lo && key < lo + static_cast<std::uint64_t>(planeNodes) * 8;
}

class Extractor {
 public:
  /// regions: per iso value, the cells left to the refined contour (skipped here); null: none.
  Extractor(const NodeStore& store, const GridSpec& grid, const std::vector<double>& isos,
            const std::vector<RefinedRegion>* regions)
      : store_(store), isos_(isos), regions_(regions), coords_(nodeCoordinates(grid)), table_(kuhnTable()) {
    double largest = 0.0;
    for (const auto& c : coords_) {
      for (double x : c) largest = std::max(largest, std::abs(x));
    }
    minNodeDistance_ = kMinNodeDistanceUlps * largest *
                       static_cast<double>(std::numeric_limits<float>::epsilon());
  }

  /// Contours the marked cells with z index in [z0, z1): out has one entry per iso value; open
  /// collects unmarked cells that the surface enters from a contoured one.
  void run(int z0, int z1, std::vector<ChunkMesh>& out, std::vector<Cell>& open) const {
    std::vector<EdgeMap> maps(isos_.size());
    cells(z0, z1, out, maps, open);
    const std::int64_t planeNodes =
        static_cast<std::int64_t>(store_.cells(0) + 1) * (store_.cells(1) + 1);
    for (ChunkMesh& m : out) {
      for (std::size_t v = 0; v < m.keys.size(); ++v) {
        if (inPlane(m.keys[v], z1, planeNodes)) {
          m.top.emplace_back(m.keys[v], static_cast<std::int32_t>(v));
        }
      }
      std::sort(m.top.begin(), m.top.end());
      m.keys.shrink_to_fit();
      m.xyz.shrink_to_fit();
      m.tris.shrink_to_fit();
    }
  }

  /// Cells of [z0, z1) whose node values show a layer one node thick, per iso value (out[q]; see
  /// PolygonizeOptions::refineLevels).
  void thin(int z0, int z1, std::vector<std::vector<Cell>>& out) const {
    forEachCell(z0, z1, [&](int i, int j, int k, const float* v, const std::vector<char>& active) {
      for (std::size_t q = 0; q < isos_.size(); ++q) {
        if (!active[q]) continue;
        const double iso = isos_[q];
        int mask = 0;
        for (int c = 0; c < 8; ++c) mask |= (static_cast<double>(v[c]) >= iso) << c;
        if (mask == 0 || mask == 255) continue;
        bool found = false;
        for (int c = 0; c < 8 && !found; ++c) {
          const bool side = (mask >> c) & 1;
          for (int a = 0; a < 3 && !found; ++a) {
            // The corner's neighbours along axis a: one in the cell, one outside it.
            if (((mask >> (c ^ (1 << a))) & 1) == side) continue;
            const int step = ((c >> a) & 1) != 0 ? 1 : -1;
            int n[3] = {i + (c & 1), j + ((c >> 1) & 1), k + ((c >> 2) & 1)};
            n[a] += step;
            if (n[a] < 0 || n[a] > store_.cells(a)) continue;
            const float w = store_.value(n[0], n[1], n[2]);
            if (std::isnan(w) || std::isinf(w)) continue;
            found = (static_cast<double>(w) >= iso) != side;
          }
        }
        if (found) out[q].push_back({i, j, k});
      }
    });
  }

 private:
  void cells(int z0, int z1, std::vector<ChunkMesh>& out, std::vector<EdgeMap>& maps,
             std::vector<Cell>& open) const {
    const std::int64_t nx = store_.cells(0), ny = store_.cells(1);
    forEachCell(z0, z1, [&](int i, int j, int k, const float* v, const std::vector<char>& active) {
      bool crossed = false;
      for (std::size_t q = 0; q < isos_.size(); ++q) {
        if (!active[q]) continue;
        if (regions_ != nullptr && (*regions_)[q].contains(i + nx * (j + ny * std::int64_t{k}))) continue;
        const double iso = isos_[q];
        int mask = 0;
        for (int c = 0; c < 8; ++c) mask |= (static_cast<double>(v[c]) >= iso) << c;
        if (mask != 0 && mask != 255) {
          emitCell(i, j, k, v, mask, iso, out[q], maps[q]);
          crossed = true;
        }
      }
      // Where the surface leaves through a face into an unmarked cell, the Lipschitz bound
      // was violated; report the cell so that the caller can continue the surface.
      if (crossed) appendOpenNeighbours(store_, {i, j, k}, v, isos_, open);
    });
  }

  /// Calls fn(i, j, k, v, active) for every marked cell of [z0, z1) that some iso value may cross
  /// (v: its 8 node values, active[q]: iso value q lies within the values of the cell's row of tiles).
  template <class Fn>
  void forEachCell(int z0, int z1, Fn&& fn) const {
    const int t = store_.tile();
    const int nx = store_.cells(0), ny = store_.cells(1);
    const std::size_t stride = static_cast<std::size_t>(t) + 1;
    std::vector<float> rows(4 * stride);
    std::vector<char> active(isos_.size());
    float v[8];
    for (int k = z0; k < z1; ++k) {
      for (int j = 0; j < ny; ++j) {
        for (int tx = 0; tx * t < nx; ++tx) {
          const std::uint64_t marks = store_.rowMarks(tx * t, j, k);
          if (marks == 0) continue;
          const int i0 = tx * t, i1 = std::min(i0 + t, nx);
          const int w = i1 - i0 + 1;
          float lo = std::numeric_limits<float>::infinity(), hi = -lo;
          for (int r = 0; r < 4; ++r) {
            float* row = rows.data() + static_cast<std::size_t>(r) * stride;
            fetchRow(i0, w, j + (r & 1), k + (r >> 1), row);
            for (int l = 0; l < w; ++l) {
              lo = std::min(lo, row[l]);  // NaN (unsampled) compares false and is ignored
              hi = std::max(hi, row[l]);
            }
          }
          bool any = false;
          for (std::size_t q = 0; q < isos_.size(); ++q) {
            active[q] = static_cast<double>(lo) < isos_[q] && static_cast<double>(hi) >= isos_[q];
            any = any || active[q];
          }
          if (!any) continue;
          for (int i = i0; i < i1; ++i) {
            if (((marks >> (i - i0)) & 1) == 0) continue;
            bool sampled = true;
            for (int c = 0; c < 8; ++c) {
              v[c] = rows[static_cast<std::size_t>((c >> 1) & 3) * stride +
                          static_cast<std::size_t>(i - i0 + (c & 1))];
              sampled = sampled && !std::isnan(v[c]);
            }
            if (!sampled) continue;  // cannot happen: marked cells have all nodes sampled
            fn(i, j, k, v, active);
          }
        }
      }
    }
  }

  /// Values of nodes i0 .. i0 + w − 1 of row (j, k), NaN where unsampled.
  void fetchRow(int i0, int w, int j, int k, float* dst) const {
    const int t = store_.tile();
    const float* tile = store_.tileOf(i0, j, k);
    const int inTile = std::min(w, t);
    if (tile != nullptr) {
      const float* src = tile + store_.local(i0, j, k);
      for (int l = 0; l < inTile; ++l) dst[l] = src[l];
    } else {
      for (int l = 0; l < inTile; ++l) dst[l] = store_.value(i0 + l, j, k);
    }
    if (w > t) dst[t] = store_.value(i0 + t, j, k);
  }

  void emitCell(int i, int j, int k, const float* v, int mask, double iso, ChunkMesh& out,
                EdgeMap& map) const {
    std::int32_t vid[kKuhnEdgeCount];
    std::fill(vid, vid + kKuhnEdgeCount, -1);
    const KuhnCase& cs = table_.cases[mask];
    for (int p = 0; p < cs.count; ++p) {
      const KuhnPolygon& poly = cs.polygons[p];
      std::int32_t ids[4];
      for (int s = 0; s < poly.size; ++s) {
        const int e = poly.edges[s];
        if (vid[e] < 0) vid[e] = vertex(i, j, k, v, e, iso, out, map);
        ids[s] = vid[e];
      }
      if (poly.size == 3) {
        out.tris.insert(out.tris.end(), {ids[0], ids[1], ids[2]});
      } else if (distance2(out, ids[0], ids[2]) <= distance2(out, ids[1], ids[3])) {
        out.tris.insert(out.tris.end(), {ids[0], ids[1], ids[2], ids[0], ids[2], ids[3]});
      } else {
        out.tris.insert(out.tris.end(), {ids[0], ids[1], ids[3], ids[1], ids[2], ids[3]});
      }
    }
  }

  /// The vertex on cell edge e, created on first use: linear interpolation from the edge's start
  /// node (lower corner) to its end node, so that every cell sharing the edge computes it alike.
  std::int32_t vertex(int i, int j, int k, const float* v, int e, double iso, ChunkMesh& out,
                      EdgeMap& map) const {
    const KuhnEdge& edge = table_.edges[e];
    const int a[3] = {i + (edge.from & 1), j + ((edge.from >> 1) & 1), k + ((edge.from >> 2) & 1)};
    const std::uint64_t key =
        static_cast<std::uint64_t>(store_.nodeId(a[0], a[1], a[2])) * 8 + (edge.from ^ edge.to);
    bool inserted = false;
    const std::int32_t id = map.insert(key, static_cast<std::int32_t>(out.keys.size()), inserted);
    if (!inserted) return id;
    const double f0 = static_cast<double>(v[edge.from]), f1 = static_cast<double>(v[edge.to]);
    // f0 and f1 straddle iso, so f1 ≠ f0. The vertex is kept minNodeDistance_ away from both
    // nodes: a node value at or within rounding of iso would otherwise put the vertices of all its
    // edges on or next to the node, where the triangles between them are degenerate (zero area, or
    // folded once written in single precision). Every vertex stays strictly inside its edge, so the
    // contour inside each tetrahedron is still an embedded triangle or quad.
    double x0[3], x1[3], length2 = 0.0;
    for (int d = 0; d < 3; ++d) {
      const std::size_t n0 = static_cast<std::size_t>(a[d]);
      const std::size_t n1 = n0 + static_cast<std::size_t>(((edge.from ^ edge.to) >> d) & 1);
      x0[d] = coords_[d][n0];
      x1[d] = coords_[d][n1];
      length2 += (x1[d] - x0[d]) * (x1[d] - x0[d]);
    }
    const double margin = std::min(0.25, minNodeDistance_ / std::sqrt(length2));
    const double s = std::clamp((iso - f0) / (f1 - f0), margin, 1.0 - margin);
    out.keys.push_back(key);
    for (int d = 0; d < 3; ++d) out.xyz.push_back(x0[d] + s * (x1[d] - x0[d]));
    return id;
  }

  static double distance2(const ChunkMesh& m, std::int32_t a, std::int32_t b) {
    double d2 = 0.0;
    for (int d = 0; d < 3; ++d) {
      const double x = m.xyz[3 * static_cast<std::size_t>(a) + static_cast<std::size_t>(d)] -
                       m.xyz[3 * static_cast<std::size_t>(b) + static_cast<std::size_t>(d)];
      d2 += x * x;
    }
    return d2;
  }

  const NodeStore& store_;
  const std::vector<double>& isos_;
  const std::vector<RefinedRegion>* regions_;
  std::array<std::vector<double>, 3> coords_;
  const KuhnTable& table_;
  double minNodeDistance_ = 0.0;  ///< see kMinNodeDistanceUlps
};

/// Joins the chunks of one iso value, releasing them: a vertex in the plane between chunks c − 1
/// and c (chunk c's first z) is looked up among chunk c − 1's top-plane vertices.
Mesh merge(std::vector<ChunkMesh*>& chunks, const std::vector<int>& z0, std::int64_t planeNodes,
           int threads, const PatchMesh& patch, std::vector<std::uint64_t>* keys) {
  const std::size_t n = chunks.size();
  // The patch's vertices on unrefined grid edges are welded to the chunks' vertices of the same key.
  std::vector<std::pair<std::uint64_t, std::int32_t>> shared;
  for (std::size_t v = 0; v < patch.keys.size(); ++v) {
    if ((patch.keys[v] & PatchMesh::kFineKeyBit) == 0) shared.emplace_back(patch.keys[v], static_cast<std::int32_t>(v));
  }
  std::sort(shared.begin(), shared.end());
  std::vector<std::int32_t> patchGlobal(patch.keys.size(), -1);
  const std::uint64_t sharedLo = shared.empty() ? 1 : shared.front().first;
  const std::uint64_t sharedHi = shared.empty() ? 0 : shared.back().first;
  std::vector<std::vector<std::int32_t>> global(n);
  std::vector<std::int64_t> firstNew(n + 1, 0), firstTri(n + 1, 0);
  std::int64_t next = 0;
  for (std::size_t c = 0; c < n; ++c) {
    const ChunkMesh& m = *chunks[c];
    global[c].resize(m.keys.size());
    firstNew[c] = next;
    for (std::size_t v = 0; v < m.keys.size(); ++v) {
      const std::uint64_t key = m.keys[v];
      std::int32_t g = -1;
      if (c > 0 && inPlane(key, z0[c], planeNodes)) {
        const auto& top = chunks[c - 1]->top;
        const auto it =
            std::lower_bound(top.begin(), top.end(), std::make_pair(key, std::int32_t{0}));
        if (it != top.end() && it->first == key) {
          g = global[c - 1][static_cast<std::size_t>(it->second)];
        }
      }
      global[c][v] = g >= 0 ? g : static_cast<std::int32_t>(next++);
      if (key >= sharedLo && key <= sharedHi) {
        const auto it = std::lower_bound(shared.begin(), shared.end(), std::make_pair(key, std::int32_t{0}));
        if (it != shared.end() && it->first == key) {
          std::int32_t& p = patchGlobal[static_cast<std::size_t>(it->second)];
          if (p < 0) p = global[c][v];
        }
      }
    }
    if (c > 0) std::vector<std::pair<std::uint64_t, std::int32_t>>().swap(chunks[c - 1]->top);
    firstTri[c + 1] = firstTri[c] + static_cast<std::int64_t>(m.tris.size() / 3);
    if (next > std::numeric_limits<std::int32_t>::max()) {
      throw Error("polygonize: a mesh would have more than 2^31 - 1 vertices (Faces are int32)");
    }
  }
  const std::int64_t firstPatchVertex = next;
  for (std::int32_t& p : patchGlobal) {
    if (p < 0) p = static_cast<std::int32_t>(next++);
  }
  if (next > std::numeric_limits<std::int32_t>::max()) {
    throw Error("polygonize: a mesh would have more than 2^31 - 1 vertices (Faces are int32)");
  }
  Mesh mesh;
  mesh.vertices.resize(next, 3);
  mesh.faces.resize(firstTri[n] + static_cast<std::int64_t>(patch.tris.size() / 3), 3);
  if (keys != nullptr) keys->assign(static_cast<std::size_t>(next), 0);
  for (std::size_t v = 0; v < patch.keys.size(); ++v) {
    const std::int32_t g = patchGlobal[v];
    if (g < firstPatchVertex) continue;
    for (int d = 0; d < 3; ++d) mesh.vertices(g, d) = patch.xyz[3 * v + static_cast<std::size_t>(d)];
    if (keys != nullptr) (*keys)[static_cast<std::size_t>(g)] = patch.keys[v];
  }
  for (std::size_t f = 0; f < patch.tris.size() / 3; ++f) {
    for (int d = 0; d < 3; ++d) {
      mesh.faces(firstTri[n] + static_cast<std::int64_t>(f), d) =
          patchGlobal[static_cast<std::size_t>(patch.tris[3 * f + static_cast<std::size_t>(d)])];
    }
  }
  const int chunkCount = static_cast<int>(n);
#pragma omp parallel for schedule(dynamic, 1) num_threads(threads)
  for (int c = 0; c < chunkCount; ++c) {
    const std::size_t cc = static_cast<std::size_t>(c);
    ChunkMesh& m = *chunks[cc];
    for (std::size_t v = 0; v < m.keys.size(); ++v) {
      const std::int32_t g = global[cc][v];
      if (g < firstNew[cc]) continue;  // owned by the previous chunk
      for (int d = 0; d < 3; ++d) mesh.vertices(g, d) = m.xyz[3 * v + static_cast<std::size_t>(d)];
      if (keys != nullptr) (*keys)[static_cast<std::size_t>(g)] = m.keys[v];
    }
    const std::size_t tris = m.tris.size() / 3;
    for (std::size_t f = 0; f < tris; ++f) {
      for (int d = 0; d < 3; ++d) {
        mesh.faces(firstTri[cc] + static_cast<std::int64_t>(f), d) =
            global[cc][static_cast<std::size_t>(m.tris[3 * f + static_cast<std::size_t>(d)])];
      }
    }
    m = ChunkMesh();
    std::vector<std::int32_t>().swap(global[cc]);
  }
  return mesh;
}

/// The thin cells of one iso value whose contour is farther than tol from the level set somewhere: the
/// centre of each contour polygon (the mean of its crossings, placed as the extraction places them) is
/// evaluated, and |f − iso| > tol keeps the cell (f approximates a distance near its level sets).
/// known: the cells tested before (cell id → kept), consulted and extended (null: none).
std::vector<Cell> deviatingCells(const NodeStore& store, const GridSpec& grid, double iso, const std::vector<Cell>& thin,
                                 const FieldSampler& sampler, double tol, std::int64_t batchSize, PolygonizeStats& stats,
                                 std::unordered_map<std::int64_t, bool>* known) {
  const KuhnTable& table = kuhnTable();
  const std::array<std::vector<double>, 3> coords = nodeCoordinates(grid);
  const auto idOf = [&store](const Cell& c) {
    return c[0] + std::int64_t{store.cells(0)} * (c[1] + std::int64_t{store.cells(1)} * c[2]);
  };
  std::vector<Eigen::Vector3d> centres;
  std::vector<std::size_t> owner;
  std::vector<char> keep(thin.size(), 0), tested(thin.size(), 0);
  for (std::size_t t = 0; t < thin.size(); ++t) {
    const Cell& c = thin[t];
    if (known != nullptr) {
      const auto it = known->find(idOf(c));
      if (it != known->end()) {
        keep[t] = it->second ? 1 : 0;
        continue;
      }
    }
    tested[t] = 1;
    float v[8];
    int mask = 0;
    for (int k = 0; k < 8; ++k) {
      v[k] = store.value(c[0] + (k & 1), c[1] + ((k >> 1) & 1), c[2] + ((k >> 2) & 1));
      mask |= (static_cast<double>(v[k]) >= iso) << k;
    }
    const KuhnCase& cs = table.cases[mask];
    for (int p = 0; p < cs.count; ++p) {
      Eigen::Vector3d sum = Eigen::Vector3d::Zero();
      for (int e = 0; e < cs.polygons[p].size; ++e) {
        const KuhnEdge& edge = table.edges[cs.polygons[p].edges[e]];
        const double f0 = static_cast<double>(v[edge.from]), f1 = static_cast<double>(v[edge.to]);
        const double s = std::clamp((iso - f0) / (f1 - f0), 0.0, 1.0);
        for (int d = 0; d < 3; ++d) {
          const std::size_t n0 = static_cast<std::size_t>(c[static_cast<std::size_t>(d)] + ((edge.from >> d) & 1));
          const std::size_t n1 = static_cast<std::size_t>(c[static_cast<std::size_t>(d)] + ((edge.to >> d) & 1));
          sum(d) += coords[static_cast<std::size_t>(d)][n0] + s * (coords[static_cast<std::size_t>(d)][n1] - coords[static_cast<std::size_t>(d)][n0]);
        }
      }
      centres.push_back(sum / cs.polygons[p].size);
      owner.push_back(t);
    }
  }
  evaluateInBatches(sampler, centres, batchSize, stats, "contour centres", [&](std::size_t i, double f) {
    if (!(std::abs(f - iso) <= tol)) keep[owner[i]] = 1;  // NaN keeps the cell too
  });
  if (known != nullptr) {
    for (std::size_t t = 0; t < thin.size(); ++t) {
      if (tested[t] != 0) known->emplace(idOf(thin[t]), keep[t] != 0);
    }
  }
  std::vector<Cell> out;
  for (std::size_t t = 0; t < thin.size(); ++t) {
    if (keep[t] != 0) out.push_back(thin[t]);
  }
  return out;
}

}  // namespace

/// A round's chunks (see RefineCache::chunks): their z ranges, meshes and open cells.
struct ChunkCache {
  std::vector<int> z0, z1;
  std::vector<std::vector<ChunkMesh>> meshes;
  std::vector<std::vector<Cell>> open;
};

Extraction extractMeshes(NodeStore& store, const GridSpec& grid, const std::vector<double>& isoValues,
                         const PolygonizeOptions& options, const FieldSampler& sampler,
                         PolygonizeStats& stats, RefineCache* cache) {
#ifdef _OPENMP
  const int nt = options.threads > 0 ? options.threads : omp_get_max_threads();
#else
  const int nt = 1;
#endif
  const int nz = store.cells(2);
  // The slab's cells (all of them without a slab) and the sampled cells around it, which are scanned
  // for thin cells and open neighbours as the whole grid's extraction would, but not contoured.
  const ZRange slab = slabCells(options, nz), sampled = sampledCells(options, nz);
  // Several thin chunks per thread: load balance, and per-chunk edge maps that stay in cache (the
  // output does not depend on the split). Chunks [0, coreChunks) cover the slab, the others its halo.
  const int thickness = std::clamp((slab.end - slab.begin + 8 * nt - 1) / (8 * nt), 1, 4);
  std::vector<int> z0, z1;
  for (int z = slab.begin; z < slab.end; z += thickness) {
    z0.push_back(z);
    z1.push_back(std::min(z + thickness, slab.end));
  }
  const std::size_t coreChunks = z0.size();
  for (int z = sampled.begin; z < slab.begin; z += thickness) {
    z0.push_back(z);
    z1.push_back(std::min(z + thickness, slab.begin));
  }
  for (int z = slab.end; z < sampled.end; z += thickness) {
    z0.push_back(z);
    z1.push_back(std::min(z + thickness, sampled.end));
  }
  const int chunkCount = static_cast<int>(z0.size());
  std::vector<std::vector<ChunkMesh>> chunks(z0.size());
  std::vector<std::vector<Cell>> open(z0.size());
  std::exception_ptr error;

  // Where the grid is too coarse for the field (layers one node thick), a refined region per iso value.
  std::vector<RefinedRegion> ownRegions;
  if (cache != nullptr) {
    cache->deviating.resize(isoValues.size());
    cache->seeds.resize(isoValues.size());
    cache->regions.resize(isoValues.size());
    cache->built.resize(isoValues.size(), 0);
  } else {
    ownRegions.resize(isoValues.size());
  }
  std::vector<RefinedRegion>& regions = cache != nullptr ? cache->regions : ownRegions;
  bool refined = false;
  bool regionsRebuilt = false;  // some region differs from the previous round's
  const int deepest = options.refineLevels + (options.refineDeeperCells.empty() ? 0 : 1);
  if (options.refineLevels > 0 &&
      (options.refineThin || !options.refineCells.empty() || !options.refineDeeperCells.empty()) &&
      deepest <= maxRefineLevels(grid.cells)) {
    std::vector<std::vector<Cell>> seeds(isoValues.size());
    if (options.refineThin) {
      const Extractor detector(store, grid, isoValues, nullptr);
      std::vector<std::vector<std::vector<Cell>>> thin(z0.size(), std::vector<std::vector<Cell>>(isoValues.size()));
#pragma omp parallel for schedule(dynamic, 1) num_threads(nt)
      for (int c = 0; c < chunkCount; ++c) {
        try {
          const std::size_t cc = static_cast<std::size_t>(c);
          detector.thin(z0[cc], z1[cc], thin[cc]);
        } catch (...) {
#pragma omp critical(duplexfit_extract_error)
          if (!error) error = std::current_exception();
        }
      }
      if (error) std::rethrow_exception(error);
      for (const auto& chunk : thin) {
        for (std::size_t q = 0; q < isoValues.size(); ++q) seeds[q].insert(seeds[q].end(), chunk[q].begin(), chunk[q].end());
      }
    }
    stats.thinCells = stats.deviatingCells = stats.shallowCells = stats.refinedSeeds = stats.refinedCells =
        stats.refinedTetrahedra = 0;
    stats.refinementSkipped = false;
    std::vector<char> rebuild(isoValues.size(), 0);
    std::vector<std::size_t> thinSeeds(isoValues.size(), 0);
    for (std::size_t q = 0; q < isoValues.size(); ++q) {
      stats.thinCells += static_cast<std::int64_t>(seeds[q].size());
      if (options.refineTolerance > 0.0 && !seeds[q].empty()) {
        seeds[q] = deviatingCells(store, grid, isoValues[q], seeds[q], sampler, options.refineTolerance,
                                  options.batchSize, stats, cache != nullptr ? &cache->deviating[q] : nullptr);
      }
      stats.deviatingCells += static_cast<std::int64_t>(seeds[q].size());
      thinSeeds[q] = seeds[q].size();
      seeds[q].insert(seeds[q].end(), options.refineCells.begin(), options.refineCells.end());
      // The previous round's region when its seeds are the same (its cells' nodes have not changed).
      rebuild[q] = cache == nullptr || cache->built[q] == 0 || cache->seeds[q] != seeds[q] ? 1 : 0;
    }
    // The level sets' regions at once (each its own); one with more than twice the seeds of all the others
    // together is refined in two slabs on two threads (fandisk_50k_noise0.5pct: the zero level's 4,491
    // seeds against the offset's 246 kept one core busy for 1.4 s while the other idled).
    const auto levelCount = static_cast<int>(isoValues.size());
    std::size_t allSeeds = 0;
    for (std::size_t q = 0; q < isoValues.size(); ++q) allSeeds += rebuild[q] ? seeds[q].size() : 0;
    const auto slabsOf = [&](std::size_t q) {
      return nt > 1 && 2 * (allSeeds - seeds[q].size()) < seeds[q].size() ? 2 : 1;
    };
    // body(q) for each level set whose region is rebuilt, on up to nt threads; the first error rethrown.
    const auto onRebuiltLevels = [&](const auto& body) {
#pragma omp parallel for schedule(dynamic, 1) num_threads(std::min(nt, levelCount))
      for (int qi = 0; qi < levelCount; ++qi) {
        const auto q = static_cast<std::size_t>(qi);
        if (!rebuild[q]) continue;
        try {
          body(q);
        } catch (...) {
#pragma omp critical(duplexfit_extract_error)
          if (!error) error = std::current_exception();
        }
      }
      if (error) std::rethrow_exception(error);
    };
    // Refined as deep as the contour needs: the deviating cells refined one level less first, and only
    // those whose contour there is still beyond the tolerance refined fully, with their ring (the others stay
    // one level less, with none); the caller's cells are refined fully.
    std::vector<std::vector<Cell>> full(isoValues.size()), shallow(isoValues.size());
    std::vector<std::vector<std::uint64_t>> knownKeys(isoValues.size());
    std::vector<std::vector<float>> knownValues(isoValues.size());
    const bool adaptive = options.refineAsNeeded && options.refineLevels >= 2 && options.refineTolerance > 0.0;
    if (adaptive) {
      std::vector<RefinedRegion> coarser(isoValues.size());
      std::vector<std::vector<Cell>> thin(isoValues.size());
      for (std::size_t q = 0; q < isoValues.size(); ++q) {
        thin[q].assign(seeds[q].begin(), seeds[q].begin() + static_cast<std::ptrdiff_t>(thinSeeds[q]));
      }
      onRebuiltLevels([&](std::size_t q) {
        if (!thin[q].empty()) {
          coarser[q] = refineCells(grid.cells, thin[q], options.refineLevels - 1, 0, options.maxRefinedCells, {}, slabsOf(q));
        }
      });
      for (std::size_t q = 0; q < isoValues.size(); ++q) {
        if (!rebuild[q]) continue;
        full[q] = thin[q].empty() ? thin[q]
                                  : refinedDeviatingCells(coarser[q], thin[q], store, grid, isoValues[q], sampler,
                                                          options.refineTolerance, options.batchSize, stats,
                                                          std::int32_t{1} << deepest, knownKeys[q], knownValues[q],
                                                          &shallow[q]);
        coarser[q] = RefinedRegion();
        stats.shallowCells += static_cast<std::int64_t>(shallow[q].size());
        full[q].insert(full[q].end(), options.refineCells.begin(), options.refineCells.end());
      }
    } else {
      full = seeds;
    }
    onRebuiltLevels([&](std::size_t q) {
      regions[q] = refineCells(grid.cells, full[q], options.refineLevels, options.refineDilation, options.maxRefinedCells,
                               options.refineDeeperCells, slabsOf(q), shallow[q]);
      regions[q].knownKeys = std::move(knownKeys[q]);
      regions[q].knownValues = std::move(knownValues[q]);
    });
    for (std::size_t q = 0; q < isoValues.size(); ++q) {
      regionsRebuilt = regionsRebuilt || rebuild[q] != 0;
      if (rebuild[q] && cache != nullptr) {
        cache->seeds[q] = seeds[q];
        cache->built[q] = 1;
      }
      stats.refinementSkipped = stats.refinementSkipped || regions[q].skipped;
      stats.refinedCells += static_cast<std::int64_t>(regions[q].cells.size());
      stats.refinedSeeds += regions[q].seeds;
      stats.refinedTetrahedra += static_cast<std::int64_t>(regions[q].tets.size());
      refined = refined || !regions[q].empty();
    }
  }

  // A chunk of the previous round is still right when no cell was marked in its layers or the layers
  // next to them (its cells' node values never change, and only the marks of its cells' neighbours
  // decide its open cells) and the refined regions are the same (fandisk_550k: every chunk was contoured
  // again for 2 new cells).
  std::vector<char> reuse(z0.size(), 0);
  if (cache != nullptr && cache->chunks && !regionsRebuilt && cache->chunks->z0 == z0 && cache->chunks->z1 == z1 &&
      cache->changedZ.size() == static_cast<std::size_t>(nz)) {
    for (std::size_t c = 0; c < z0.size(); ++c) {
      bool changed = false;
      for (int z = std::max(0, z0[c] - 1); z <= std::min(nz - 1, z1[c]) && !changed; ++z) {
        changed = cache->changedZ[static_cast<std::size_t>(z)] != 0;
      }
      if (!changed) {
        reuse[c] = 1;
        ++stats.reusedChunks;
        chunks[c] = std::move(cache->chunks->meshes[c]);
        open[c] = std::move(cache->chunks->open[c]);
      }
    }
  }
  if (cache != nullptr) cache->chunks.reset();
  const Extractor extractor(store, grid, isoValues, refined ? &regions : nullptr);
#pragma omp parallel for schedule(dynamic, 1) num_threads(nt)
  for (int c = 0; c < chunkCount; ++c) {
    try {
      const std::size_t cc = static_cast<std::size_t>(c);
      if (reuse[cc]) continue;
      chunks[cc].resize(isoValues.size());
      extractor.run(z0[cc], z1[cc], chunks[cc], open[cc]);
      if (cc >= coreChunks) chunks[cc].clear();  // a halo chunk: only its open neighbours count
    } catch (...) {
#pragma omp critical(duplexfit_extract_error)
      if (!error) error = std::current_exception();
    }
  }
  if (error) std::rethrow_exception(error);

  Extraction result;
  // Open cells outside the sampled range are another slab's (sampled there as in the whole grid).
  const auto takeOpen = [&](const std::vector<Cell>& cells) {
    for (const Cell& c : cells) {
      if (sampled.contains(c[2])) result.openCells.push_back(c);
    }
  };
  for (const auto& o : open) takeOpen(o);
  // The caller samples more and extracts again: keep the chunks for that round.
  const auto keepChunks = [&] {
    if (cache == nullptr) return;
    cache->chunks = std::make_shared<ChunkCache>();
    cache->chunks->z0 = z0;
    cache->chunks->z1 = z1;
    cache->chunks->meshes = std::move(chunks);
    cache->chunks->open = std::move(open);
  };
  if (!result.openCells.empty()) {
    keepChunks();
    return result;
  }
  std::vector<PatchMesh> patches(isoValues.size());
  for (std::size_t q = 0; q < isoValues.size(); ++q) {
    if (regions[q].empty()) continue;
    const auto start = std::chrono::steady_clock::now();
    std::vector<Cell> patchOpen;
    patches[q] = std::move(extractRefined(regions[q], store, grid, {isoValues[q]}, sampler, options.batchSize, stats,
                                          patchOpen, slab.begin, slab.end).front());
    takeOpen(patchOpen);
    stats.refinedSeconds += secondsSince(start);
  }
  if (!result.openCells.empty()) {
    keepChunks();
    return result;
  }

  const std::int64_t planeNodes =
      static_cast<std::int64_t>(store.cells(0) + 1) * (store.cells(1) + 1);
  store.release();  // the node values are no longer needed: make room for the meshes
  const bool keys = options.keepVertexKeys || slab.begin != 0 || slab.end != nz;
  const std::vector<int> coreZ0(z0.begin(), z0.begin() + static_cast<std::ptrdiff_t>(coreChunks));
  for (std::size_t q = 0; q < isoValues.size(); ++q) {
    std::vector<ChunkMesh*> perIso;
    for (std::size_t c = 0; c < coreChunks; ++c) perIso.push_back(&chunks[c][q]);
    if (keys) result.vertexKeys.emplace_back();
    result.meshes.push_back(merge(perIso, coreZ0, planeNodes, nt, patches[q], keys ? &result.vertexKeys.back() : nullptr));
    patches[q] = PatchMesh();
  }
  return result;
}

}  // namespace duplexfit::detail
