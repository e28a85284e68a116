// Triangle meshes: the value type produced by polygonization and consumed by the writers and the
// measurement tools, plus topology statistics (watertight, 2-manifold, components, Euler characteristic).
#pragma once

#include <vector>

#include <cstdint>

#include <Eigen/Core>

#include "duplexfit/types.hpp"

namespace duplexfit {

/// Faces as an #F×3 row-major matrix of vertex indices.
using Faces = Eigen::Matrix<std::int32_t, Eigen::Dynamic, 3, Eigen::RowMajor>;

/// An indexed triangle mesh. Faces are counter-clockwise seen from outside (normals point outward).
struct Mesh {
  Points vertices;  ///< #V×3, model units
  Faces faces;      ///< #F×3, indices into vertices
};

/// Topological facts about a mesh (edges are undirected vertex pairs).
struct MeshTopology {
  std::size_t vertices = 0, faces = 0, edges = 0;
  std::size_t boundaryEdges = 0;         ///< edges with one incident face
  std::size_t nonManifoldEdges = 0;      ///< edges with more than two incident faces
  std::size_t nonManifoldVertices = 0;   ///< vertices whose incident faces form more than one fan
  std::size_t inconsistentEdges = 0;     ///< two-face edges traversed in the same direction by both
  std::size_t degenerateFaces = 0;       ///< faces with a repeated vertex index
  std::size_t components = 0;            ///< connected components of the face graph (via shared edges)
  long long eulerCharacteristic = 0;     ///< V − E + F over the referenced vertices
  /// Closed: at least one edge (an empty mesh, or one of only degenerate faces, is not watertight), no
  /// boundary and no non-manifold edges.
  bool watertight() const noexcept { return edges > 0 && boundaryEdges == 0 && nonManifoldEdges == 0; }
  bool manifold() const noexcept { return nonManifoldEdges == 0 && nonManifoldVertices == 0; }
  bool oriented() const noexcept { return inconsistentEdges == 0; }
};

/// Computes the topology of a mesh. @throws InvalidArgument naming a face with an out-of-range index.
MeshTopology analyzeTopology(const Mesh& mesh);

/// Connected components of a mesh's faces (faces sharing a vertex are connected): the component of each
/// face, numbered 0..count−1 in the order of each component's first face. Faces with an index out of
/// range are an InvalidArgument.
std::vector<Index> faceComponents(const Mesh& mesh, std::size_t* count = nullptr);

/// Signed volume enclosed by the mesh (positive for outward-oriented closed meshes).
double signedVolume(const Mesh& mesh);

/// Total triangle area.
double surfaceArea(const Mesh& mesh);

/// The mesh with only the faces f where keep[f] is non-zero (keep has one entry per face); the vertices no
/// kept face uses are removed, and vertices and faces keep their order.
Mesh keepFaces(const Mesh& mesh, const std::vector<char>& keep);

}  // namespace duplexfit
