// Assembly of the level system with the fit's memory check and interrupter (private to the library).
#pragma once

#include <cstddef>
#include <functional>

#include "duplexfit/device.hpp"
#include "duplexfit/interrupter.hpp"
#include "duplexfit/linalg.hpp"
#include "duplexfit/sparse.hpp"
#include "duplexfit/types.hpp"
#include "spatial/cell_grid.hpp"

namespace duplexfit::detail {

/// Called with the sampled estimate of the non-zeros before the CSR arrays are reserved: the fit's memory
/// check (ResourceLimits), which may throw.
using NonZeroCheck = std::function<void(std::size_t estimatedNonZeros)>;

/// assembleWendland(centres, sigma, lambda) with `beforeAllocating` (when set) called as above; the
/// searches poll `interrupter` (may be null; @throws Cancelled). The searches run on a grid of σ cells
/// when its table has at most `maxGridCells` cells, else on a k-d tree: the matrix is the same. With
/// `storage`, the matrix is built in its arrays (their capacity taken over, `storage` left empty): a fit
/// hands each level's matrix on to the next level's assembly, whose pages are then already there.
CsrMatrix assembleWendland(const Points& centres, double sigma, double lambda, const NonZeroCheck& beforeAllocating,
                           Interrupter* interrupter = nullptr,
                           std::size_t maxGridCells = CellGrid::kDefaultMaxCells, CsrMatrix* storage = nullptr);

/// @throws InvalidArgument unless σ > 0 and λ ≥ 0 are finite and every centre is finite (naming its row).
void checkAssemblyArguments(const Points& centres, double sigma, double lambda);

/// Whether assembleOnDevice can run the kernels on `device`: an OpenCL device with double precision (the
/// kernels' geometry is double, so that their matrix is the host's bit for bit).
bool deviceAssemblyAvailable(const Device& device);

/// A level's matrix assembled on the device (kernels/assemble.cl): `device` holds it in `precision`, ready
/// for the solve, and `host` is its copy in double (the FSAI set-up and the mixed-precision refinement read
/// it): the same matrix as assembleWendland gives, bit for bit, and rounded to `precision` as an upload
/// rounds it. The centres' grid (σ cells) is built on the host; `beforeAllocating` gets the exact non-zero
/// count before the matrix's buffers exist. Where the grid's table would exceed `maxGridCells`, the double
/// values one buffer, or the device is the reference device or has no double precision, the host assembles
/// and uploads (`onDevice` false). With `storage` and `recycled`, the host arrays and the device buffers of the level before are
/// released or reused as assembleWendland and DeviceCsr::upload do.
struct DeviceAssembly {
  CsrMatrix host;
  DeviceCsr device;
  bool onDevice = false;
};
DeviceAssembly assembleOnDevice(const Device& device, Precision precision, const Points& centres, double sigma,
                                double lambda, const NonZeroCheck& beforeAllocating, Interrupter* interrupter = nullptr,
                                std::size_t maxGridCells = CellGrid::kDefaultMaxCells, CsrMatrix* storage = nullptr,
                                DeviceCsr* recycled = nullptr);

}  // namespace duplexfit::detail
