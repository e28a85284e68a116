// Triangle quality: degeneracy once the corners are rounded to float32 (what STL and binary PLY store),
// minimum angles, slivers and the angle histogram that `duplexfit check` reports.
#include <algorithm>
#include <cmath>
#include <limits>

#include <Eigen/Geometry>

#include "duplexfit/error.hpp"
#include "duplexfit/measure.hpp"

namespace duplexfit {

namespace {

// The rule as stated, on the rounded corners.
bool float32DegenerateRounded(const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c) {
  const Eigen::Vector3f fa = a.cast<float>(), fb = b.cast<float>(), fc = c.cast<float>();
  if (fa == fb || fb == fc || fa == fc) return true;
  const Eigen::Vector3f n = (fb - fa).cross(fc - fa);
  if (n.x() == 0.0f && n.y() == 0.0f && n.z() == 0.0f) return true;
  const Eigen::Vector3d da = fa.cast<double>(), db = fb.cast<double>(), dc = fc.cast<double>();
  const double longest2 = std::max({(db - da).squaredNorm(), (dc - da).squaredNorm(), (dc - db).squaredNorm()});
  return !((db - da).cross(dc - da).norm() > 1e-12 * longest2);
}

}  // namespace

bool float32Degenerate(const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c) {
  // Most triangles of a mesh are far from degenerate, and rounding to float cannot make them so: decide
  // those from the double corners (this runs for every face, several times, in cleaning and projection).
  // Rounding moves a corner by at most eta = sqrt(3) 2^-24 m (+ 1e-44 for subnormal floats), m the largest
  // |coordinate|; an edge then moves by 2 eta, so the rounded triangle's cross product is within
  // 2 eta (|e1| + |e2|) + 4 eta^2 of this one's. With s >= the perimeter (s^2 = 3 P, P the sum of squared
  // edges), |e1 x e2| > 1e-5 s^2 + 16 eta s + 16 eta^2 + 1e-43 leaves the rounded cross product above
  // 6e-7 |e1'| |e2'| + 1e-44, more than float arithmetic's rounding can cancel to zero in all three
  // components, and far above the rule's 1e-12 (longest edge)^2; the corners are then distinct too (equal
  // ones give a zero cross product). The slack covers the double rounding here. Anything else, NaN and
  // coordinates beyond float's range included, takes the rule as stated (test_check: both agree).
  const double e1x = b.x() - a.x(), e1y = b.y() - a.y(), e1z = b.z() - a.z();
  const double e2x = c.x() - a.x(), e2y = c.y() - a.y(), e2z = c.z() - a.z();
  const double e3x = c.x() - b.x(), e3y = c.y() - b.y(), e3z = c.z() - b.z();
  const double nx = e1y * e2z - e1z * e2y, ny = e1z * e2x - e1x * e2z, nz = e1x * e2y - e1y * e2x;
  const double cross2 = nx * nx + ny * ny + nz * nz;
  const double p = e1x * e1x + e1y * e1y + e1z * e1z + e2x * e2x + e2y * e2y + e2z * e2z + e3x * e3x +
                   e3y * e3y + e3z * e3z;
  const double m = std::max({std::abs(a.x()), std::abs(a.y()), std::abs(a.z()), std::abs(b.x()), std::abs(b.y()),
                             std::abs(b.z()), std::abs(c.x()), std::abs(c.y()), std::abs(c.z())});
  if (m < 1e37 && p > 1e-30 && p < 1e60) {
    const double eta = 1.1e-7 * m + 1e-44;
    const double s = std::sqrt(3.0 * p);
    const double t = 3e-5 * p + 16.0 * eta * s + 16.0 * eta * eta + 1e-43;
    if (cross2 > t * t) return false;
  }
  return float32DegenerateRounded(a, b, c);
}

namespace {

/// The two parts of a triangle's smallest angle, atan2(|e1 × e2|, e1 · e2) at the corner opposite its
/// shortest side (law of sines); false for a zero-length side (angle 0).
bool smallestAngleParts(const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c, double& cross,
                        double& dot) {
  const Eigen::Vector3d p[3] = {a, b, c};
  const double opposite[3] = {(c - b).squaredNorm(), (a - c).squaredNorm(), (b - a).squaredNorm()};
  if (opposite[0] == 0.0 || opposite[1] == 0.0 || opposite[2] == 0.0) return false;
  int k = 0;
  for (int j = 1; j < 3; ++j) {
    if (opposite[j] < opposite[k]) k = j;
  }
  const Eigen::Vector3d e1 = p[(k + 1) % 3] - p[k], e2 = p[(k + 2) % 3] - p[k];
  cross = e1.cross(e2).norm();
  dot = e1.dot(e2);
  return true;
}

/// An angle bound for triangleQuality's counts, as a tangent with a relative margin: a face whose
/// |e1 × e2| / (e1 · e2) lies below `below` has its angle under `degrees` whatever the roundings of the arc
/// tangent (about 1e-16), above `above` not; in between the arc tangent decides.
struct TangentBound {
  double below, above;
  explicit TangentBound(double deg) {
    const double t = deg > 0.0 && deg < 90.0 ? std::tan(deg * M_PI / 180.0) : -1.0;
    below = t > 0.0 ? t * (1.0 - 1e-9) : -1.0;  // -1: never sure (0 and 90 degrees and beyond)
    above = t > 0.0 ? t * (1.0 + 1e-9) : -1.0;
  }
};

}  // namespace

double minAngleDegrees(const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c) {
  // The smallest angle is the one opposite the shortest side (law of sines), so one arc tangent is enough:
  // this runs for every face of a fine mesh, several times (cleaning, projection, quality reports).
  double cross = 0.0, dot = 0.0;
  if (!smallestAngleParts(a, b, c, cross, dot)) return 0.0;
  // atan2 of |e1 × e2| and e1 · e2 is accurate for angles near 0 and 180° alike.
  return std::atan2(cross, dot) * (180.0 / M_PI);
}

bool minAngleBelow(const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c, double degrees) {
  double cross = 0.0, dot = 0.0;
  if (!smallestAngleParts(a, b, c, cross, dot)) return 0.0 < degrees;
  // The smallest angle is at most 60 degrees, so dot > 0 unless the triangle is degenerate (cross 0 and a
  // negative dot: 180 degrees from atan2); those, and angles near the bound, take minAngleDegrees' way.
  const TangentBound bound(degrees);
  if (dot > 0.0 && bound.below > 0.0) {
    if (cross < bound.below * dot) return true;
    if (cross > bound.above * dot) return false;
  }
  return std::atan2(cross, dot) * (180.0 / M_PI) < degrees;
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
  // The arc tangent only where a bound or the running minimum cannot be decided from the tangent
  // |e1 × e2| / (e1 · e2) itself (most faces of a fine mesh are far from 1, 5, 10 degrees and from the
  // smallest angle so far): the same counts and minimum, without an arc tangent a face (which was half of
  // this pass). Every count below compares the angle with its bound exactly as before.
  const TangentBound bounds[4] = {TangentBound(sliverAngle), TangentBound(1.0), TangentBound(5.0), TangentBound(10.0)};
  double minTangent = std::numeric_limits<double>::infinity();  // above it: an angle above the minimum so far
  for (Eigen::Index i = 0; i < nf; ++i) {
    const std::int32_t ia = mesh.faces(i, 0), ib = mesh.faces(i, 1), ic = mesh.faces(i, 2);
    const Eigen::Vector3d a = mesh.vertices.row(ia), b = mesh.vertices.row(ib), c = mesh.vertices.row(ic);
    const bool repeated = ia == ib || ib == ic || ia == ic;
    if (!repeated) shortest = std::min({shortest, (b - a).norm(), (c - b).norm(), (a - c).norm()});
    const bool degenerate = repeated || float32Degenerate(a, b, c);
    double cross = 0.0, dot = 0.0;
    if (!degenerate && smallestAngleParts(a, b, c, cross, dot) && dot > 0.0) {
      const double r = cross / dot;
      bool decided = r >= minTangent && std::isfinite(r);
      for (const TangentBound& t : bounds) decided = decided && (r < t.below || r > t.above);
      if (decided) {  // above the minimum so far; each count from the tangent
        q.slivers += r < bounds[0].below ? 1 : 0;
        q.below1 += r < bounds[1].below ? 1 : 0;
        q.below5 += r < bounds[2].below ? 1 : 0;
        q.below10 += r < bounds[3].below ? 1 : 0;
        continue;
      }
    }
    const double angle = repeated ? 0.0 : minAngleDegrees(a, b, c);
    if (degenerate) {
      ++q.float32DegenerateFaces;
      if (q.firstFloat32DegenerateFace < 0) q.firstFloat32DegenerateFace = i;
    } else {
      if (angle < sliverAngle) ++q.slivers;
      if (angle < minAngle) {
        minAngle = angle;
        q.worstFace = i;
        // Tangents above this have angles above the new minimum (the margin covers the roundings).
        minTangent = angle < 90.0 ? std::tan(angle * M_PI / 180.0) * (1.0 + 1e-9) + 1e-300 : std::numeric_limits<double>::infinity();
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
