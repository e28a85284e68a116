// The level system assembled on an OpenCL device (kernels/assemble.cl, program "assemble"): the host
// counting-sorts the centres into σ cells (CellGrid, as its own assembly does), one kernel counts each row's
// entries, the host turns the counts into row pointers (and checks the memory budget with the exact
// count), a second kernel writes each row's columns and values, and the matrix stays on the device for the
// solve; its double copy comes back for the host's FSAI set-up. See wendland_detail.hpp.
#include <algorithm>
#include <cstdint>
#include <limits>
#include <string>
#include <utility>
#include <vector>

#include "device/device_impl.hpp"
#include "duplexfit/error.hpp"
#include "field/wendland_detail.hpp"
#include "linalg/storage.hpp"
#include "spatial/cell_grid.hpp"

namespace duplexfit::detail {

namespace {

constexpr std::int64_t kMaxNonZeros = std::numeric_limits<Index>::max();

DeviceAssembly onHost(const Device& device, Precision precision, const Points& centres, double sigma, double lambda,
                      const NonZeroCheck& beforeAllocating, Interrupter* interrupter, std::size_t maxGridCells,
                      CsrMatrix* storage, DeviceCsr* recycled) {
  DeviceAssembly out;
  out.host = assembleWendland(centres, sigma, lambda, beforeAllocating, interrupter, maxGridCells, storage);
  out.device = recycled != nullptr ? DeviceCsr::upload(device, out.host, precision, std::move(*recycled))
                                   : DeviceCsr::upload(device, out.host, precision);
  return out;
}

void pollInterrupter(Interrupter* interrupter) {
  if (interrupter != nullptr && interrupter->wasInterrupted()) throw Cancelled("cancelled during the assembly");
}

}  // namespace

bool deviceAssemblyAvailable(const Device& device) { return !device.isReference() && device.supportsDouble(); }

DeviceAssembly assembleOnDevice(const Device& device, Precision precision, const Points& centres, double sigma,
                                double lambda, const NonZeroCheck& beforeAllocating, Interrupter* interrupter,
                                std::size_t maxGridCells, CsrMatrix* storage, DeviceCsr* recycled) {
  checkAssemblyArguments(centres, sigma, lambda);
  device.requirePrecision(precision);
  if (!deviceAssemblyAvailable(device)) {
    return onHost(device, precision, centres, sigma, lambda, beforeAllocating, interrupter, maxGridCells, storage,
                  recycled);
  }
  const auto n = static_cast<std::size_t>(centres.rows());
  if (n >= std::numeric_limits<std::uint32_t>::max() / 4) {
    throw InvalidArgument("assembly on the device: " + std::to_string(n) + " centres is too many for 32-bit kernel indices");
  }
  const CellGrid grid(centres, sigma, maxGridCells);
  if (!grid.usable() || n == 0) {
    return onHost(device, precision, centres, sigma, lambda, beforeAllocating, interrupter, maxGridCells, storage,
                  recycled);
  }
  // The level before's matrix: its host arrays are handed over (their pages are there already), its device
  // buffers released before this level's exist.
  CsrMatrix a;
  if (storage != nullptr) {
    a = std::move(*storage);
    *storage = CsrMatrix{};
  }
  if (recycled != nullptr) *recycled = DeviceCsr{};
  a.rows = static_cast<Index>(n);
  a.cols = static_cast<Index>(n);

  DeviceImpl& impl = *device.impl();
  const std::string what = "the assembly of " + std::to_string(n) + " centres";
  const double geom[7] = {grid.origin()[0], grid.origin()[1], grid.origin()[2], grid.inverseCell(), sigma,
                          CellGrid::reachFor(sigma), CellGrid::boundFor(sigma)};
  const cl::Buffer qBuf = uploadArray(device, centres.data(), 3 * n, "the centres of " + what);
  const cl::Buffer xyzBuf = uploadArray(device, grid.sortedPoints().data(), grid.sortedPoints().size(),
                                        "the sorted centres of " + what);
  const cl::Buffer idBuf = uploadArray(device, grid.sortedIds().data(), grid.sortedIds().size(), "the cell order of " + what);
  const cl::Buffer startBuf = uploadArray(device, grid.cellStarts().data(), grid.cellStarts().size(),
                                          "the cell table of " + what);
  const cl::Buffer geomBuf = uploadArray(device, geom, 7, "the grid of " + what);
  const cl::Buffer dimsBuf = uploadArray(device, grid.cellsPerAxis(), 3, "the grid of " + what);
  const cl::Buffer countBuf = createBuffer(device, n * sizeof(std::uint32_t), "the row counts of " + what);
  const auto rows = static_cast<cl_uint>(n);
  {
    const char* name = "assemble_count";
    const std::lock_guard<std::mutex> lock(impl.launchMutex());
    cl::Kernel& k = impl.kernel("assemble", precision, name);
    setArgs(k, name, rows, qBuf, xyzBuf, startBuf, idBuf, geomBuf, dimsBuf, countBuf);
    impl.launch(k, n, impl.params().workGroup, name);
  }
  std::vector<std::uint32_t> count(n);
  readArray(device, countBuf, count.data(), n);
  pollInterrupter(interrupter);
  a.rowPtr.resize(n + 1);
  a.rowPtr[0] = 0;
  std::int64_t total = 0;
  for (std::size_t i = 0; i < n; ++i) {
    total += count[i];
    if (total > kMaxNonZeros) {
      throw InvalidArgument("assembleWendland: more than 2^31 - 1 non-zeros (sigma " + std::to_string(sigma) +
                            " is too large for " + std::to_string(n) + " centres)");
    }
    a.rowPtr[i + 1] = static_cast<Index>(total);
  }
  const auto nnz = static_cast<std::size_t>(total);
  if (static_cast<std::uint64_t>(nnz) * sizeof(double) > device.maxAllocBytes()) {
    // The double values would exceed one buffer where the system's own values may not (float): the host
    // assembles and uploads, as it would have without the device assembly.
    return onHost(device, precision, centres, sigma, lambda, beforeAllocating, interrupter, maxGridCells, &a, nullptr);
  }
  if (beforeAllocating) beforeAllocating(nnz);
  const cl::Buffer rowPtrBuf = uploadArray(device, a.rowPtr.data(), n + 1, "the row pointers of " + what);
  const cl::Buffer colBuf = createBuffer(device, std::max<std::size_t>(nnz, 1) * sizeof(Index), "the column indices of " + what);
  const cl::Buffer valDBuf = createBuffer(device, std::max<std::size_t>(nnz, 1) * sizeof(double), "the values of " + what);
  const bool single = precision == Precision::Float;
  const cl::Buffer valBuf =
      single ? createBuffer(device, std::max<std::size_t>(nnz, 1) * sizeof(float), "the float values of " + what) : valDBuf;
  {
    const char* name = "assemble_fill";
    const std::lock_guard<std::mutex> lock(impl.launchMutex());
    cl::Kernel& k = impl.kernel("assemble", precision, name);
    setArgs(k, name, rows, qBuf, xyzBuf, startBuf, idBuf, geomBuf, dimsBuf, rowPtrBuf, sigma, 1.0 + lambda,
            static_cast<cl_uint>(single ? 1 : 0), colBuf, valDBuf, valBuf);
    impl.launch(k, n, impl.params().workGroup, name);
  }
  a.colIdx.resize(nnz);
  a.values.resize(nnz);
  readArray(device, colBuf, a.colIdx.data(), nnz);
  readArray(device, valDBuf, a.values.data(), nnz);
  pollInterrupter(interrupter);

  auto s = std::make_unique<CsrStorage>(CsrStorage{device, n, n, nnz, precision, a.diagonal(), {}, {}, {}, {}, {}, {}, {}});
  s->rowPtrBuf = rowPtrBuf;
  s->colBuf = colBuf;
  s->valBuf = valBuf;
  DeviceAssembly out;
  out.host = std::move(a);
  out.device = adoptCsr(std::move(s));
  out.onDevice = true;
  return out;
}

}  // namespace duplexfit::detail
