// Mesh queries: topology statistics (edges from sorted vertex pairs, face fans per vertex,
// components by union-find over edge-adjacent faces), signed volume and surface area.
#include "duplexfit/mesh.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <numeric>
#include <string>
#include <vector>

#include <Eigen/Geometry>

#include "core/disjoint_sets.hpp"
#include "duplexfit/error.hpp"

namespace duplexfit {

namespace {

using detail::DisjointSets;

/// Throws InvalidArgument naming the first face with an index outside [0, #V).
void checkIndices(const Mesh& mesh, const char* caller) {
  const Eigen::Index nv = mesh.vertices.rows();
  const std::int32_t* faces = mesh.faces.data();
  for (Eigen::Index f = 0; f < mesh.faces.rows(); ++f) {
    for (int k = 0; k < 3; ++k) {
      const std::int32_t v = faces[3 * f + k];
      if (v < 0 || v >= nv) {
        throw InvalidArgument(std::string(caller) + ": face " + std::to_string(f) +
                              " has vertex index " + std::to_string(v) + " out of range [0, " +
                              std::to_string(nv) + ")");
      }
    }
  }
}

}  // namespace

MeshTopology analyzeTopology(const Mesh& mesh) {
  checkIndices(mesh, "analyzeTopology");
  MeshTopology topo;
  const std::int32_t* faces = mesh.faces.data();  // row-major #F×3
  const auto nf = static_cast<std::size_t>(mesh.faces.rows());
  const auto nv = static_cast<std::size_t>(mesh.vertices.rows());
  topo.faces = nf;

  // Degenerate faces (a repeated index) are counted and otherwise ignored: they add no edges, fans,
  // components, vertices or faces to the Euler characteristic.
  std::vector<bool> valid(nf);
  std::vector<std::size_t> degree(nv + 1, 0);
  for (std::size_t f = 0; f < nf; ++f) {
    const std::int32_t* t = faces + 3 * f;
    if (t[0] == t[1] || t[1] == t[2] || t[2] == t[0]) {
      ++topo.degenerateFaces;
      continue;
    }
    valid[f] = true;
    for (int k = 0; k < 3; ++k) ++degree[static_cast<std::size_t>(t[k]) + 1];
  }
  // The faces around each vertex (compressed rows, in face order).
  std::partial_sum(degree.begin(), degree.end(), degree.begin());
  std::vector<std::uint32_t> incident(degree[nv]);
  {
    std::vector<std::size_t> fill(degree.begin(), degree.end() - 1);
    for (std::size_t f = 0; f < nf; ++f) {
      if (!valid[f]) continue;
      for (int k = 0; k < 3; ++k) {
        const auto v = static_cast<std::size_t>(faces[3 * f + static_cast<std::size_t>(k)]);
        incident[fill[v]++] = static_cast<std::uint32_t>(f);
      }
    }
  }
  // Around each vertex v, the spokes (other vertex w, local face): the runs of equal w are the edges
  // {v, w}, each counted at its smaller end (a run of one: boundary; of more than two: non-manifold; two
  // traversing it the same way: inconsistent). Faces sharing an edge belong to one component. Incident
  // faces linked by an edge at v form fans; more than one means v is pinched (a bow-tie or touching cones).
  DisjointSets faceSets(nf);
  std::vector<std::pair<std::int32_t, std::uint32_t>> spokes;  // (other vertex, local face index)
  for (std::size_t v = 0; v < nv; ++v) {
    const std::size_t begin = degree[v], end = degree[v + 1];
    if (begin == end) continue;  // not referenced by a valid face
    ++topo.vertices;
    spokes.clear();
    for (std::size_t i = begin; i < end; ++i) {
      const std::int32_t* t = faces + 3 * std::size_t{incident[i]};
      for (int k = 0; k < 3; ++k) {
        const std::int32_t w = t[k];
        if (static_cast<std::size_t>(w) != v) {
          spokes.emplace_back(w, static_cast<std::uint32_t>(i - begin));
        }
      }
    }
    std::sort(spokes.begin(), spokes.end());
    // Whether local face i traverses the edge from v to w (else from w to v).
    const auto fromV = [&](std::uint32_t i, std::int32_t w) {
      const std::int32_t* t = faces + 3 * std::size_t{incident[begin + i]};
      for (int k = 0; k < 3; ++k) {
        if (static_cast<std::size_t>(t[k]) == v) return t[(k + 1) % 3] == w;
      }
      return false;
    };
    DisjointSets fan(end - begin);
    for (std::size_t i = 0; i < spokes.size();) {
      std::size_t j = i + 1;
      while (j < spokes.size() && spokes[j].first == spokes[i].first) ++j;
      for (std::size_t k = i + 1; k < j; ++k) fan.unite(spokes[k].second, spokes[i].second);
      if (static_cast<std::size_t>(spokes[i].first) > v) {
        const std::size_t count = j - i;
        ++topo.edges;
        if (count == 1) {
          ++topo.boundaryEdges;
        } else if (count > 2) {
          ++topo.nonManifoldEdges;
        } else if (fromV(spokes[i].second, spokes[i].first) == fromV(spokes[i + 1].second, spokes[i].first)) {
          ++topo.inconsistentEdges;
        }
        for (std::size_t k = i + 1; k < j; ++k) {
          faceSets.unite(incident[begin + spokes[i].second], incident[begin + spokes[k].second]);
        }
      }
      i = j;
    }
    std::size_t fans = 0;
    for (std::size_t i = 0; i < end - begin; ++i) {
      if (fan.find(i) == i) ++fans;
    }
    if (fans > 1) ++topo.nonManifoldVertices;
  }
  for (std::size_t f = 0; f < nf; ++f) {
    if (valid[f] && faceSets.find(f) == f) ++topo.components;
  }

  topo.eulerCharacteristic = static_cast<long long>(topo.vertices) -
                             static_cast<long long>(topo.edges) +
                             static_cast<long long>(nf - topo.degenerateFaces);
  return topo;
}

double signedVolume(const Mesh& mesh) {
  checkIndices(mesh, "signedVolume");
  if (mesh.faces.rows() == 0) return 0.0;
  // Tetrahedra against the box centre rather than the origin: the same value for a closed mesh,
  // with less cancellation when the model sits far from the origin.
  const Eigen::RowVector3d centre =
      0.5 * (mesh.vertices.colwise().minCoeff() + mesh.vertices.colwise().maxCoeff());
  const double* v = mesh.vertices.data();  // row-major #V×3
  const std::int32_t* f = mesh.faces.data();
  double sum = 0.0;
  for (Eigen::Index i = 0; i < mesh.faces.rows(); ++i, f += 3) {
    double a[3], b[3], c[3];
    for (int k = 0; k < 3; ++k) {
      a[k] = v[3 * f[0] + k] - centre(k);
      b[k] = v[3 * f[1] + k] - centre(k);
      c[k] = v[3 * f[2] + k] - centre(k);
    }
    sum += a[0] * (b[1] * c[2] - b[2] * c[1]) + a[1] * (b[2] * c[0] - b[0] * c[2]) +
           a[2] * (b[0] * c[1] - b[1] * c[0]);
  }
  return sum / 6.0;
}

double surfaceArea(const Mesh& mesh) {
  checkIndices(mesh, "surfaceArea");
  const double* v = mesh.vertices.data();  // row-major #V×3
  const std::int32_t* f = mesh.faces.data();
  double sum = 0.0;
  for (Eigen::Index i = 0; i < mesh.faces.rows(); ++i, f += 3) {
    double u[3], w[3];
    for (int k = 0; k < 3; ++k) {
      u[k] = v[3 * f[1] + k] - v[3 * f[0] + k];
      w[k] = v[3 * f[2] + k] - v[3 * f[0] + k];
    }
    const double x = u[1] * w[2] - u[2] * w[1];
    const double y = u[2] * w[0] - u[0] * w[2];
    const double z = u[0] * w[1] - u[1] * w[0];
    sum += std::sqrt(x * x + y * y + z * z);
  }
  return 0.5 * sum;
}

std::vector<Index> faceComponents(const Mesh& mesh, std::size_t* count) {
  const auto nv = static_cast<std::size_t>(mesh.vertices.rows());
  std::vector<std::size_t> parent(nv);
  std::iota(parent.begin(), parent.end(), std::size_t{0});
  auto find = [&parent](std::size_t x) {
    while (parent[x] != x) {
      parent[x] = parent[parent[x]];
      x = parent[x];
    }
    return x;
  };
  for (Eigen::Index f = 0; f < mesh.faces.rows(); ++f) {
    for (int c = 0; c < 3; ++c) {
      const Index v = mesh.faces(f, c);
      if (v < 0 || static_cast<std::size_t>(v) >= nv) {
        throw InvalidArgument("face " + std::to_string(f) + ": vertex index " + std::to_string(v) +
                              " out of range (mesh has " + std::to_string(nv) + " vertices)");
      }
    }
    const std::size_t a = find(static_cast<std::size_t>(mesh.faces(f, 0)));
    parent[find(static_cast<std::size_t>(mesh.faces(f, 1)))] = a;
    parent[find(static_cast<std::size_t>(mesh.faces(f, 2)))] = a;
  }
  std::vector<Index> label(nv, -1), out(static_cast<std::size_t>(mesh.faces.rows()));
  Index next = 0;
  for (Eigen::Index f = 0; f < mesh.faces.rows(); ++f) {
    const std::size_t r = find(static_cast<std::size_t>(mesh.faces(f, 0)));
    if (label[r] < 0) label[r] = next++;
    out[static_cast<std::size_t>(f)] = label[r];
  }
  if (count != nullptr) *count = static_cast<std::size_t>(next);
  return out;
}

Mesh keepFaces(const Mesh& mesh, const std::vector<char>& keep) {
  if (keep.size() != static_cast<std::size_t>(mesh.faces.rows())) {
    throw InvalidArgument("keepFaces: " + std::to_string(keep.size()) + " flags for " + std::to_string(mesh.faces.rows()) +
                          " faces");
  }
  std::vector<Index> map(static_cast<std::size_t>(mesh.vertices.rows()), -1);
  Eigen::Index faces = 0;
  for (Eigen::Index f = 0; f < mesh.faces.rows(); ++f) faces += keep[static_cast<std::size_t>(f)] ? 1 : 0;
  for (Eigen::Index f = 0; f < mesh.faces.rows(); ++f) {
    if (!keep[static_cast<std::size_t>(f)]) continue;
    for (int k = 0; k < 3; ++k) map[static_cast<std::size_t>(mesh.faces(f, k))] = 0;
  }
  Index vertices = 0;
  for (Index& m : map) {
    if (m >= 0) m = vertices++;
  }
  Mesh out;
  out.vertices.resize(vertices, 3);
  for (std::size_t v = 0; v < map.size(); ++v) {
    if (map[v] >= 0) out.vertices.row(map[v]) = mesh.vertices.row(static_cast<Eigen::Index>(v));
  }
  out.faces.resize(faces, 3);
  Eigen::Index row = 0;
  for (Eigen::Index f = 0; f < mesh.faces.rows(); ++f) {
    if (!keep[static_cast<std::size_t>(f)]) continue;
    for (int k = 0; k < 3; ++k) {
      out.faces(row, k) = static_cast<std::int32_t>(map[static_cast<std::size_t>(mesh.faces(f, k))]);
    }
    ++row;
  }
  return out;
}

}  // namespace duplexfit
