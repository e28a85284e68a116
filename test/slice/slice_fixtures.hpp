// Shared fixtures of the slice tests: analytic tori as FieldFunctions (exact f, ∇f, Hessian) and fitted
// fields of small generated clouds, fitted once per test process.
#pragma once

#include <cmath>
#include <map>
#include <tuple>

#include "duplexfit/field.hpp"
#include "duplexfit/fit.hpp"
#include "duplexfit/slice.hpp"
#include "shapes.hpp"
#include "test_device.hpp"

namespace duplexfit::slicetest {

/// The §10.6 torus: R = 0.3, r = 0.2 (unit width), inward offset δ = 0.1.
constexpr double kR = 0.3, kr = 0.2, kDelta = 0.1;

/// Signed distance (> 0 inside) of an upright torus (axis y, centre at the origin), with exact ∇f and a
/// central-difference Hessian of the exact gradient.
inline Eigen::Vector3d torusGradient(const Eigen::Vector3d& p, double R, double r, double* value) {
  const double s = std::max(std::hypot(p.x(), p.z()), 1e-300);
  const double w = s - R;
  const double d = std::max(std::hypot(w, p.y()), 1e-300);
  if (value) *value = r - d;
  return -Eigen::Vector3d(w / d * p.x() / s, p.y() / d, w / d * p.z() / s);
}

inline FieldFunction analyticUprightTorus(double R = kR, double r = kr) {
  return [R, r](const Points& q, FieldDerivatives derivatives) {
    FieldSamples s;
    s.values.resize(q.rows());
    if (derivatives != FieldDerivatives::None) s.gradients.resize(q.rows(), 3);
    if (derivatives == FieldDerivatives::Hessian) s.hessians.resize(q.rows(), 6);
    for (Eigen::Index i = 0; i < q.rows(); ++i) {
      const Eigen::Vector3d p = q.row(i).transpose();
      double f = 0.0;
      const Eigen::Vector3d g = torusGradient(p, R, r, &f);
      s.values[i] = f;
      if (derivatives != FieldDerivatives::None) s.gradients.row(i) = g.transpose();
      if (derivatives == FieldDerivatives::Hessian) {
        Eigen::Matrix3d h;
        const double e = 1e-5;
        for (int k = 0; k < 3; ++k) {
          Eigen::Vector3d d = Eigen::Vector3d::Zero();
          d[k] = e;
          h.col(k) = (torusGradient(p + d, R, r, nullptr) - torusGradient(p - d, R, r, nullptr)) / (2 * e);
        }
        h = 0.5 * (h + h.transpose()).eval();
        s.hessians.row(i) << h(0, 0), h(0, 1), h(0, 2), h(1, 1), h(1, 2), h(2, 2);
      }
    }
    return s;
  };
}

inline Eigen::AlignedBox3d uprightTorusBox(double R = kR, double r = kr) {
  return {Eigen::Vector3d(-R - r, -r, -R - r), Eigen::Vector3d(R + r, r, R + r)};
}

/// The upright §10.6 torus (axis y) fitted from n generated points with δ = 0.1, once per process.
inline const ImplicitField& fittedUprightTorus() {
  static const ImplicitField field = [] {
    Points normals;
    const Points p = testing::sampledTorus(3000, kR, kr, &normals);
    // Axis z → axis y: (x, y, z) ↦ (x, z, −y), a rotation (normals rotate alike and stay outward).
    Points q(p.rows(), 3), n(p.rows(), 3);
    q.col(0) = p.col(0);
    q.col(1) = p.col(2);
    q.col(2) = -p.col(1);
    n.col(0) = normals.col(0);
    n.col(1) = normals.col(2);
    n.col(2) = -normals.col(1);
    FitOptions o;
    o.offsets = {kDelta};
    const Device* d = testing::openclTestDevice();
    return fit(d != nullptr ? *d : Device::reference(), PointSet(q, n), o).field;
  }();
  return field;
}

/// The §10.6 setting: τ = 0.01, t_max = 0.05, t_min = 0.0025, and Fig. 21's torus grid 0.01.
inline SliceOptions paperOptions(SliceMode mode, int axis = 2, CuspRule rule = CuspRule::Geometric) {
  SliceOptions o;
  o.mode = mode;
  o.axis = axis;
  o.rule = rule;
  o.cusp = 0.01;
  o.maxLayer = 0.05;
  o.minLayer = 0.0025;
  o.grid = 0.01;
  return o;
}

/// The device the fitted fields are sliced on: the OpenCL test device, else the reference device.
inline Device sliceDevice() {
  const Device* d = testing::openclTestDevice();
  return d != nullptr ? *d : Device::reference();
}

/// slice(sliceDevice(), fittedUprightTorus(), paperOptions(mode, axis, rule)), computed once per process.
inline const SliceResult& fittedSlice(SliceMode mode, int axis, CuspRule rule = CuspRule::Geometric) {
  static std::map<std::tuple<int, int, int>, SliceResult> cache;
  const auto key = std::make_tuple(static_cast<int>(mode), axis, static_cast<int>(rule));
  auto it = cache.find(key);
  if (it == cache.end()) {
    it = cache.emplace(key, slice(sliceDevice(), fittedUprightTorus(), paperOptions(mode, axis, rule))).first;
  }
  return it->second;
}

}  // namespace duplexfit::slicetest
