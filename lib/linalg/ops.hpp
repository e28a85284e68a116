// Fused operations of the CG iteration (internal), each with its reference twin; see kernels/cg_fused.cl.
#pragma once

#include <utility>

#include "duplexfit/linalg.hpp"

namespace duplexfit::detail {

/// y ← A·x and returns x·y (one pass on CPU devices: spmv_csr_row_dot_chunk).
double spmvDot(const DeviceCsr& a, const DeviceVector& x, DeviceVector& y, SpmvKernel kernel);
/// x ← x + αp, r ← r − αq; returns (rᵀ D r, rᵀ r) with D = dinv (one pass).
std::pair<double, double> cgUpdate(double alpha, const DeviceVector& p, const DeviceVector& q,
                                   const DeviceVector& dinv, DeviceVector& x, DeviceVector& r);
/// p ← D r + βp (β = 0 overwrites p without reading it).
void cgDirection(double beta, const DeviceVector& r, const DeviceVector& dinv, DeviceVector& p);
/// z ← d .* r
void vmul(const DeviceVector& d, const DeviceVector& r, DeviceVector& z);
/// a ← b + s·c (STREAM triad, for bandwidth measurements).
void triad(DeviceVector& a, const DeviceVector& b, const DeviceVector& c, double s);
/// Resolves SpmvKernel::Auto for a device.
SpmvKernel resolveSpmvKernel(const Device& device, SpmvKernel kernel);

}  // namespace duplexfit::detail
