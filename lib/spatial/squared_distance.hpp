// The squared Euclidean distance every neighbour structure of the library computes (NeighborIndex's k-d
// tree, CellGrid, PointBvh): the query minus the point, the squares summed in x, y, z order (as FLANN's
// L2_3D did when the k-d tree was FLANN's). One definition, so that the structures find the same points at
// bit-identical distances (the assembly's matrix, the validity test's answers).
#pragma once

namespace duplexfit::detail {

inline double squaredDistance(const double* q, const double* p) noexcept {
  const double dx = q[0] - p[0], dy = q[1] - p[1], dz = q[2] - p[2];
  return dx * dx + dy * dy + dz * dz;
}

}  // namespace duplexfit::detail
