// The fused steps of one PCG iteration on a device (each one pass over its vectors, with a reference twin;
// kernels/cg_fused.cl): what solveCg is made of, public so that benchmarks and custom solvers can run and
// time them one by one.
#pragma once

#include "duplexfit/linalg.hpp"

namespace duplexfit::steps {

/// y ← A·x and returns x·y (one pass on CPU devices: spmv_csr_row_dot_chunk).
double spmvDot(const DeviceCsr& a, const DeviceVector& x, DeviceVector& y, SpmvKernel kernel);
/// Reductions computed by the fused CG updates.
struct CgSums {
  double rz = 0.0;    ///< rᵀ D r (cgUpdate only)
  double rr = 0.0;    ///< rᵀ r
  double rmax = 0.0;  ///< max |r_i|
};
/// x ← x + αp, r ← r − αq; returns rᵀ D r, rᵀ r and max|r_i| with D = dinv (one pass).
CgSums cgUpdate(double alpha, const DeviceVector& p, const DeviceVector& q, const DeviceVector& dinv,
                DeviceVector& x, DeviceVector& r);
/// x ← x + αp, r ← r − αq; returns rᵀr and max|r_i| (one pass; for non-diagonal preconditioners).
CgSums cgUpdateXR(double alpha, const DeviceVector& p, const DeviceVector& q, DeviceVector& x, DeviceVector& r);
/// p ← D r + βp (β = 0 overwrites p without reading it).
void cgDirection(double beta, const DeviceVector& r, const DeviceVector& dinv, DeviceVector& p);
/// z ← d .* r
void vmul(const DeviceVector& d, const DeviceVector& r, DeviceVector& z);
/// a ← b + s·c (STREAM triad, for bandwidth measurements).
void triad(DeviceVector& a, const DeviceVector& b, const DeviceVector& c, double s);
/// The SpMV kernel SpmvKernel::Auto stands for on a device.
SpmvKernel resolveSpmvKernel(const Device& device, SpmvKernel kernel);

}  // namespace duplexfit::steps
