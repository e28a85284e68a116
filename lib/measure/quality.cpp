// Triangle quality: degeneracy once the corners are rounded to float32 (what STL and binary PLY store),
// minimum angles, slivers and the angle histogram that `duplexfit check` reports.
#include <algorithm>
#include <cmath>
#include <limits>

#include <Eigen/Geometry>

#include "duplexfit/error.hpp"
#include "duplexfit/measure.hpp"

namespace duplexfit {

bool float32Degenerate(const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c) {
  const Eigen::Vector3f fa = a.cast<float>(), fb = b.cast<float>(), fc = c.cast<float>();
  if (fa == fb || fb == fc || fa == fc) return true;
  const Eigen::Vector3f n = (fb - fa).cross(fc - fa);
  if (n.x() == 0.0f && n.y() == 0.0f && n.z() == 0.0f) return true;
  const Eigen::Vector3d da = fa.cast<double>(), db = fb.cast<double>(), dc = fc.cast<double>();
  const double longest2 = std::max({(db - da).squaredNorm(), (dc - da).squaredNorm(), (dc - db).squaredNorm()});
  return !((db - da).cross(dc - da).norm() > 1e-12 * longest2);
}

double minAngleDegrees(const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c) {
  const Eigen::Vector3d p[3] = {a, b, c};
  // The smallest angle is the one opposite the shortest side (law of sines), so one arc tangent is enough:
  // this runs for every face of a fine mesh, several times (cleaning, projection, quality reports).
  const double opposite[3] = {(c - b).squaredNorm(), (a - c).squaredNorm(), (b - a).squaredNorm()};
  if (opposite[0] == 0.0 || opposite[1] == 0.0 || opposite[2] == 0.0) return 0.0;
  int k = 0;
  for (int j = 1; j < 3; ++j) {
    if (opposite[j] < opposite[k]) k = j;
  }
  const Eigen::Vector3d e1 = p[(k + 1) % 3] - p[k], e2 = p[(k + 2) % 3] - p[k];
  // atan2 of |e1 × e2| and e1 · e2 is accurate for angles near 0 and 180° alike.
  return std::atan2(e1.cross(e2).norm(), e1.dot(e2)) * (180.0 / M_PI);
}

TriangleQuality triangleQuality(const Mesh& mesh, double sliverAngle) {
  if (!(sliverAngle >= 0.0) || !(sliverAngle <= 60.0)) {
    throw InvalidArgument("triangle quality: the sliver angle must be in [0, 60] degrees");
  }
  TriangleQuality q;
  q.sliverAngle = sliverAngle;
  const Eigen::Index nf = mesh.faces.rows();
  q.faces = static_cast<std::size_t>(nf);
  double minAngle = std::numeric_limits<double>::infinity();
  double shortest = std::numeric_limits<double>::infinity();
  for (Eigen::Index i = 0; i < nf; ++i) {
    const std::int32_t ia = mesh.faces(i, 0), ib = mesh.faces(i, 1), ic = mesh.faces(i, 2);
    const Eigen::Vector3d a = mesh.vertices.row(ia), b = mesh.vertices.row(ib), c = mesh.vertices.row(ic);
    const bool repeated = ia == ib || ib == ic || ia == ic;
    if (!repeated) shortest = std::min({shortest, (b - a).norm(), (c - b).norm(), (a - c).norm()});
    const bool degenerate = repeated || float32Degenerate(a, b, c);
    const double angle = repeated ? 0.0 : minAngleDegrees(a, b, c);
    if (degenerate) {
      ++q.float32DegenerateFaces;
      if (q.firstFloat32DegenerateFace < 0) q.firstFloat32DegenerateFace = i;
    } else {
      if (angle < sliverAngle) ++q.slivers;
      if (angle < minAngle) {
        minAngle = angle;
        q.worstFace = i;
      }
    }
    const double counted = degenerate ? 0.0 : angle;
    q.below1 += counted < 1.0 ? 1 : 0;
    q.below5 += counted < 5.0 ? 1 : 0;
    q.below10 += counted < 10.0 ? 1 : 0;
  }
  q.minAngle = std::isfinite(minAngle) ? minAngle : 0.0;
  q.shortestEdge = std::isfinite(shortest) ? shortest : 0.0;
  return q;
}

}  // namespace duplexfit
