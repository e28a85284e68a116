// Compute devices: the plain C++ reference path and OpenCL devices, one spec syntax everywhere
// (CLI --device, DUPLEXFIT_DEVICE, tests, benchmarks).
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "duplexfit/timer.hpp"
#include "duplexfit/types.hpp"

namespace duplexfit {

namespace detail {
class DeviceImpl;
}

enum class DeviceKind { Reference, OpenCL };
enum class DeviceType { Cpu, Gpu, Accelerator, Other };

/// "cpu", "gpu", "accelerator" or "other".
const char* deviceTypeName(DeviceType type) noexcept;

/// What a device is and what it can do. For the reference device, indices are −1 and sizes describe the host.
struct DeviceInfo {
  std::string spec;              ///< "ref" or "P:D" (platform and device index): opens this device again
  int platformIndex = -1;        ///< index in clGetPlatformIDs order, −1 for the reference device
  int deviceIndex = -1;          ///< index within the platform, −1 for the reference device
  std::string platform;          ///< platform name, e.g. "Portable Computing Language"
  std::string name;              ///< device name
  std::string vendor;
  std::string driverVersion;     ///< CL_DRIVER_VERSION
  std::string deviceVersion;     ///< CL_DEVICE_VERSION
  std::string openclCVersion;    ///< CL_DEVICE_OPENCL_C_VERSION
  DeviceType type = DeviceType::Cpu;
  unsigned computeUnits = 0;
  std::uint64_t globalMemBytes = 0;
  std::uint64_t maxAllocBytes = 0;  ///< CL_DEVICE_MAX_MEM_ALLOC_SIZE: the largest single buffer
  std::uint64_t localMemBytes = 0;
  std::size_t maxWorkGroupSize = 0;
  unsigned nativeFloatWidth = 0;    ///< CL_DEVICE_NATIVE_VECTOR_WIDTH_FLOAT (16 on a CPU with AVX-512, 8 with AVX2)
  bool fp64 = true;                 ///< cl_khr_fp64 (or OpenCL ≥ 1.2 double-fp-config) is reported
};

/// A parsed device spec. Syntax (case-insensitive):
///   ""/"default"  first GPU, else first CPU OpenCL device, else the reference device
///   "ref"         the plain C++ reference path (also "reference", "host")
///   "P:D"         platform P, device D, as listed by `duplexfit devices`
///   "cpu"/"gpu"/"accelerator"  the first OpenCL device of that type
///   anything else a substring of the device name, platform name or vendor (first match)
struct DeviceSpec {
  enum class Kind { Default, Reference, Indices, Type, Name };
  Kind kind = Kind::Default;
  int platform = -1;
  int device = -1;
  DeviceType type = DeviceType::Cpu;
  std::string name;  ///< the substring for Kind::Name, lower-cased

  /// @throws InvalidArgument on malformed index specs such as "1:" or "a:b".
  static DeviceSpec parse(std::string_view text);
  /// The spec in DUPLEXFIT_DEVICE, or Default when it is unset or empty.
  static DeviceSpec fromEnvironment();
  std::string toString() const;
};

/// Options that restrict what an opened device may do.
struct DeviceOptions {
  bool allowFp64 = true;           ///< false: treat the device as having no fp64 (forces Precision::Float)
  std::uint64_t maxAllocBytes = 0; ///< 0: the device's own limit; else a lower cap on any one buffer
};

/// The launch configuration chosen for an OpenCL device from its type and limits (benchmark headers,
/// tests of the GPU-style path); all zero for the reference device.
struct DeviceTuning {
  std::size_t workGroup = 0;     ///< local size of every launch (element-wise and group reductions)
  std::size_t chunk = 0;         ///< elements per work-item in the barrier-free chunk kernels
  std::size_t lanes = 0;         ///< work-items per row in the row-per-group SpMV
  std::size_t groups = 0;        ///< work-groups of the group reductions
  bool chunkReductions = false;  ///< CPU style: chunk reductions and the fused row-per-item SpMV
  /// Float field evaluation by the SIMD kernels, fieldWidth centres a step (a CPU device's vector units;
  /// DUPLEXFIT_FIELD_KERNEL=vector|vector8|vector16|scalar; double always runs the scalar kernel).
  bool fieldVector = false;
  /// Centres a step of the SIMD field kernels: 16 where the device's native float vector is 16 wide (AVX-512),
  /// else 8; 1 with the scalar kernel.
  int fieldWidth = 0;
  /// The SIMD kernels sum the coarse levels with large weights (at most 256 centres, largest |w| above 0.25)
  /// in double, the others in float (devices with fp64; DUPLEXFIT_FIELD_COARSE=double|float overrides):
  /// fandisk_550k's largest error 2.85e-6 → 3.7e-7 of the box; a field with large weights at finer levels
  /// keeps more (wheel_118k 9.5e-6; docs/method.md §6).
  bool fieldCoarseDouble = false;
  /// Values and gradients from the SIMD kernels sum all but the two finest levels for a tile of fieldWidth
  /// neighbouring queries at once (FieldEvaluator evaluates a batch in Morton order; DUPLEXFIT_FIELD_TILES=0|1
  /// overrides): 1.3-1.9x faster per point on fandisk_550k's and wheel_29k's fields (docs/method.md §6).
  bool fieldTiles = false;
  /// "wg=… chunk=… lanes=… groups=… reductions=chunk|group field=vector16|vector8|scalar" (with "+double"
  /// where fieldCoarseDouble, "+tiles" where fieldTiles), or "reference" for the reference device.
  std::string describe() const;
};

/// A compute device. Cheap to copy: copies share one OpenCL context, in-order queue and program cache.
class Device {
 public:
  /// The plain C++ path: always available; the oracle that tests compare the OpenCL path with.
  static Device reference();
  /// Opens the device a spec selects.
  /// @throws DeviceError listing every available device when nothing matches.
  static Device open(const DeviceSpec& spec, const DeviceOptions& options = {});
  static Device open(std::string_view spec, const DeviceOptions& options = {});
  /// Opens DeviceSpec::fromEnvironment().
  static Device openDefault(const DeviceOptions& options = {});
  /// Every OpenCL device of every platform; empty (not an error) when no ICD or platform exists.
  static std::vector<DeviceInfo> enumerate();

  DeviceKind kind() const noexcept;
  bool isReference() const noexcept { return kind() == DeviceKind::Reference; }
  const DeviceInfo& info() const noexcept;
  /// Whether Precision::Double can be used here.
  bool supportsDouble() const noexcept;
  /// @throws DeviceError when the precision cannot be used on this device.
  void requirePrecision(Precision precision) const;
  /// "name (platform, driver)" for logs and benchmark headers.
  std::string description() const;
  /// Builds every OpenCL program for the precision now (otherwise each builds at its first use, about
  /// 1 s uncached on PoCL). No-op on the reference device. @throws BuildError, DeviceError.
  void compileKernels(Precision precision) const;
  /// Waits for all queued work (no-op on the reference device).
  void finish() const;
  /// The largest single buffer this Device may allocate (device limit or DeviceOptions cap).
  std::uint64_t maxAllocBytes() const noexcept { return maxAllocBytes_; }
  /// @throws DeviceError "<what> needs N MiB but device X allows at most M MiB in one buffer".
  void checkAllocation(std::uint64_t bytes, const std::string& what) const;

  /// The launch configuration in use (all zero on the reference device).
  DeviceTuning tuning() const;

  /// Internal: the OpenCL implementation (null for the reference device).
  detail::DeviceImpl* impl() const noexcept { return impl_.get(); }

 private:
  Device() = default;
  std::shared_ptr<detail::DeviceImpl> impl_;
  std::shared_ptr<const DeviceInfo> info_;
  bool fp64Allowed_ = true;
  std::uint64_t maxAllocBytes_ = 0;
};

/// Times queued work on a device: wall time from start() (after finish()) to stop() (after finish()), and
/// on OpenCL the device span between two profiling markers enqueued at start() and stop(); for a single
/// kernel that span is its run time.
class DeviceStopwatch {
 public:
  explicit DeviceStopwatch(const Device& device);
  DeviceStopwatch(DeviceStopwatch&&) noexcept;
  DeviceStopwatch& operator=(DeviceStopwatch&&) noexcept;
  ~DeviceStopwatch();
  void start();
  void stop();
  double wallMs() const noexcept { return wallMs_; }
  /// NaN on the reference device, or when the device reports no profiling times.
  double deviceMs() const noexcept { return deviceMs_; }

 private:
  struct Markers;
  Device device_;
  std::unique_ptr<Markers> markers_;
  SteadyClock::time_point t0_{};
  double wallMs_ = 0.0;
  double deviceMs_ = 0.0;
};

}  // namespace duplexfit
