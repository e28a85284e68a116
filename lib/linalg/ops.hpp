// Fused operations of the CG iteration (internal), each with its reference twin; see kernels/cg_fused.cl.
#pragma once

#include <CL/opencl.hpp>

#include <utility>
#include <vector>

#include "duplexfit/linalg.hpp"

namespace duplexfit::detail {

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
/// Launches a reduction kernel whose arguments before `partialArg` are set, over n elements with
/// `perItem` partial values per chunk/group, and returns the partials combined per slot (perItem values):
/// summed, except slot `maxSlot` (if < perItem), which takes the maximum.
std::vector<double> reduceLaunch(const Device& device, Precision precision, cl::Kernel& kernel,
                                 unsigned partialArg, std::size_t n, std::size_t perItem, const char* name,
                                 std::size_t maxSlot = static_cast<std::size_t>(-1));
/// Resolves SpmvKernel::Auto for a device.
SpmvKernel resolveSpmvKernel(const Device& device, SpmvKernel kernel);

}  // namespace duplexfit::detail
