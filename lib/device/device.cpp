// Device enumeration, spec parsing and selection, and the public Device handle.
#include "duplexfit/device.hpp"

#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <chrono>
#include <limits>
#include <cstdlib>
#include <mutex>
#include <sstream>
#include <thread>

#include "device/cl_check.hpp"
#include "device/device_impl.hpp"
#include "duplexfit/error.hpp"
#include "duplexfit/timer.hpp"

namespace duplexfit {

namespace detail {

const char* clErrorName(int status) noexcept {
  switch (status) {
#define DUPLEXFIT_CASE(x) \
  case x:                 \
    return #x;
    DUPLEXFIT_CASE(CL_SUCCESS)
    DUPLEXFIT_CASE(CL_DEVICE_NOT_FOUND)
    DUPLEXFIT_CASE(CL_DEVICE_NOT_AVAILABLE)
    DUPLEXFIT_CASE(CL_COMPILER_NOT_AVAILABLE)
    DUPLEXFIT_CASE(CL_MEM_OBJECT_ALLOCATION_FAILURE)
    DUPLEXFIT_CASE(CL_OUT_OF_RESOURCES)
    DUPLEXFIT_CASE(CL_OUT_OF_HOST_MEMORY)
    DUPLEXFIT_CASE(CL_PROFILING_INFO_NOT_AVAILABLE)
    DUPLEXFIT_CASE(CL_MEM_COPY_OVERLAP)
    DUPLEXFIT_CASE(CL_BUILD_PROGRAM_FAILURE)
    DUPLEXFIT_CASE(CL_MAP_FAILURE)
    DUPLEXFIT_CASE(CL_INVALID_VALUE)
    DUPLEXFIT_CASE(CL_INVALID_DEVICE_TYPE)
    DUPLEXFIT_CASE(CL_INVALID_PLATFORM)
    DUPLEXFIT_CASE(CL_INVALID_DEVICE)
    DUPLEXFIT_CASE(CL_INVALID_CONTEXT)
    DUPLEXFIT_CASE(CL_INVALID_QUEUE_PROPERTIES)
    DUPLEXFIT_CASE(CL_INVALID_COMMAND_QUEUE)
    DUPLEXFIT_CASE(CL_INVALID_HOST_PTR)
    DUPLEXFIT_CASE(CL_INVALID_MEM_OBJECT)
    DUPLEXFIT_CASE(CL_INVALID_BINARY)
    DUPLEXFIT_CASE(CL_INVALID_BUILD_OPTIONS)
    DUPLEXFIT_CASE(CL_INVALID_PROGRAM)
    DUPLEXFIT_CASE(CL_INVALID_PROGRAM_EXECUTABLE)
    DUPLEXFIT_CASE(CL_INVALID_KERNEL_NAME)
    DUPLEXFIT_CASE(CL_INVALID_KERNEL_DEFINITION)
    DUPLEXFIT_CASE(CL_INVALID_KERNEL)
    DUPLEXFIT_CASE(CL_INVALID_ARG_INDEX)
    DUPLEXFIT_CASE(CL_INVALID_ARG_VALUE)
    DUPLEXFIT_CASE(CL_INVALID_ARG_SIZE)
    DUPLEXFIT_CASE(CL_INVALID_KERNEL_ARGS)
    DUPLEXFIT_CASE(CL_INVALID_WORK_DIMENSION)
    DUPLEXFIT_CASE(CL_INVALID_WORK_GROUP_SIZE)
    DUPLEXFIT_CASE(CL_INVALID_WORK_ITEM_SIZE)
    DUPLEXFIT_CASE(CL_INVALID_GLOBAL_OFFSET)
    DUPLEXFIT_CASE(CL_INVALID_EVENT_WAIT_LIST)
    DUPLEXFIT_CASE(CL_INVALID_EVENT)
    DUPLEXFIT_CASE(CL_INVALID_OPERATION)
    DUPLEXFIT_CASE(CL_INVALID_BUFFER_SIZE)
    DUPLEXFIT_CASE(CL_INVALID_GLOBAL_WORK_SIZE)
#undef DUPLEXFIT_CASE
    case -1001:
      return "CL_PLATFORM_NOT_FOUND_KHR";
    default:
      return "unknown OpenCL error";
  }
}

void throwClError(int status, const std::string& call) {
  std::ostringstream msg;
  msg << call << " failed: " << clErrorName(status) << " (" << status << ")";
  if (status == CL_MEM_OBJECT_ALLOCATION_FAILURE || status == CL_OUT_OF_RESOURCES) {
    msg << "; the device ran out of memory (on PoCL raise POCL_MEMORY_LIMIT, in GiB)";
  }
  throw DeviceError(msg.str(), status, call);
}

}  // namespace detail

namespace {

std::string lower(std::string_view s) {
  std::string out(s);
  std::transform(out.begin(), out.end(), out.begin(), [](unsigned char c) { return std::tolower(c); });
  return out;
}

std::string trim(std::string_view s) {
  std::size_t b = 0, e = s.size();
  while (b < e && std::isspace(static_cast<unsigned char>(s[b])) != 0) ++b;
  while (e > b && std::isspace(static_cast<unsigned char>(s[e - 1])) != 0) --e;
  return std::string(s.substr(b, e - b));
}

std::uint64_t physicalMemory() {
  const long pages = sysconf(_SC_PHYS_PAGES);
  const long pageSize = sysconf(_SC_PAGE_SIZE);
  if (pages <= 0 || pageSize <= 0) return 0;
  return static_cast<std::uint64_t>(pages) * static_cast<std::uint64_t>(pageSize);
}

// Some PoCL builds cap their CPU device at 4 GiB in all (2 GiB a buffer) unless POCL_MEMORY_LIMIT (GiB)
// is set (docs/pocl-notes.md); others (PoCL 3.1 here) default higher and cap larger requests at their
// own limit. Ask for 3/4 of the host's memory unless the user chose a value; the device's reported
// limits are what buffers are checked against. Must happen before the first clGetPlatformIDs.
void preparePoclEnvironment() {
  static std::once_flag once;
  std::call_once(once, [] {
    if (std::getenv("POCL_MEMORY_LIMIT") != nullptr) return;
    const std::uint64_t gib = physicalMemory() * 3 / 4 >> 30;
    if (gib >= 4) setenv("POCL_MEMORY_LIMIT", std::to_string(gib).c_str(), 0);
  });
}

struct ClDeviceEntry {
  cl::Device device;
  DeviceInfo info;
};

template <cl_device_info Name, typename T>
T deviceInfo(const cl::Device& d, T fallback) {
  T value{};
  return d.getInfo(Name, &value) == CL_SUCCESS ? value : fallback;
}

DeviceInfo describe(const cl::Platform& platform, const cl::Device& d, int p, int i) {
  DeviceInfo info;
  info.platformIndex = p;
  info.deviceIndex = i;
  info.spec = std::to_string(p) + ":" + std::to_string(i);
  platform.getInfo(CL_PLATFORM_NAME, &info.platform);
  info.name = trim(deviceInfo<CL_DEVICE_NAME>(d, std::string("?")));
  info.vendor = trim(deviceInfo<CL_DEVICE_VENDOR>(d, std::string()));
  info.driverVersion = trim(deviceInfo<CL_DRIVER_VERSION>(d, std::string()));
  info.deviceVersion = trim(deviceInfo<CL_DEVICE_VERSION>(d, std::string()));
  info.openclCVersion = trim(deviceInfo<CL_DEVICE_OPENCL_C_VERSION>(d, std::string()));
  const auto type = deviceInfo<CL_DEVICE_TYPE>(d, cl_device_type{CL_DEVICE_TYPE_DEFAULT});
  info.type = (type & CL_DEVICE_TYPE_GPU) != 0             ? DeviceType::Gpu
              : (type & CL_DEVICE_TYPE_CPU) != 0           ? DeviceType::Cpu
              : (type & CL_DEVICE_TYPE_ACCELERATOR) != 0   ? DeviceType::Accelerator
                                                           : DeviceType::Other;
  info.computeUnits = deviceInfo<CL_DEVICE_MAX_COMPUTE_UNITS>(d, cl_uint{0});
  info.globalMemBytes = deviceInfo<CL_DEVICE_GLOBAL_MEM_SIZE>(d, cl_ulong{0});
  info.maxAllocBytes = deviceInfo<CL_DEVICE_MAX_MEM_ALLOC_SIZE>(d, cl_ulong{0});
  info.localMemBytes = deviceInfo<CL_DEVICE_LOCAL_MEM_SIZE>(d, cl_ulong{0});
  info.maxWorkGroupSize = deviceInfo<CL_DEVICE_MAX_WORK_GROUP_SIZE>(d, std::size_t{0});
  info.nativeFloatWidth = deviceInfo<CL_DEVICE_NATIVE_VECTOR_WIDTH_FLOAT>(d, cl_uint{0});
  const std::string extensions = deviceInfo<CL_DEVICE_EXTENSIONS>(d, std::string());
  const auto fpConfig = deviceInfo<CL_DEVICE_DOUBLE_FP_CONFIG>(d, cl_device_fp_config{0});
  info.fp64 = extensions.find("cl_khr_fp64") != std::string::npos || fpConfig != 0;
  return info;
}

std::vector<ClDeviceEntry> enumerateCl() {
  preparePoclEnvironment();
  std::vector<ClDeviceEntry> out;
  std::vector<cl::Platform> platforms;
  if (cl::Platform::get(&platforms) != CL_SUCCESS) return out;  // no ICD or no platform: not an error
  for (std::size_t p = 0; p < platforms.size(); ++p) {
    std::vector<cl::Device> devices;
    if (platforms[p].getDevices(CL_DEVICE_TYPE_ALL, &devices) != CL_SUCCESS) continue;
    for (std::size_t i = 0; i < devices.size(); ++i) {
      out.push_back({devices[i], describe(platforms[p], devices[i], static_cast<int>(p), static_cast<int>(i))});
    }
  }
  return out;
}

DeviceInfo referenceInfo() {
  DeviceInfo info;
  info.spec = "ref";
  info.platform = "duplexfit";
  info.name = "reference (C++/Eigen on the host)";
  info.vendor = "duplexfit";
  info.driverVersion = "-";
  info.deviceVersion = "-";
  info.openclCVersion = "-";
  info.type = DeviceType::Cpu;
  info.computeUnits = std::max(1u, std::thread::hardware_concurrency());
  info.globalMemBytes = physicalMemory();
  info.maxAllocBytes = physicalMemory();
  info.fp64 = true;
  return info;
}

std::string listDevices(const std::vector<ClDeviceEntry>& entries) {
  std::ostringstream s;
  if (entries.empty()) {
    s << "\n  (no OpenCL platform found: is an ICD such as pocl-opencl-icd installed?)";
  }
  for (const auto& e : entries) {
    s << "\n  " << e.info.spec << "  " << e.info.name << " (" << e.info.platform << ", "
      << deviceTypeName(e.info.type) << ")";
  }
  s << "\n  ref  " << referenceInfo().name;
  return s.str();
}

bool matches(const DeviceSpec& spec, const DeviceInfo& info) {
  switch (spec.kind) {
    case DeviceSpec::Kind::Indices:
      return info.platformIndex == spec.platform && info.deviceIndex == spec.device;
    case DeviceSpec::Kind::Type:
      return info.type == spec.type;
    case DeviceSpec::Kind::Name:
      return lower(info.name).find(spec.name) != std::string::npos ||
             lower(info.platform).find(spec.name) != std::string::npos ||
             lower(info.vendor).find(spec.name) != std::string::npos;
    default:
      return false;
  }
}

}  // namespace

const char* deviceTypeName(DeviceType type) noexcept {
  switch (type) {
    case DeviceType::Cpu:
      return "cpu";
    case DeviceType::Gpu:
      return "gpu";
    case DeviceType::Accelerator:
      return "accelerator";
    default:
      return "other";
  }
}

DeviceSpec DeviceSpec::parse(std::string_view text) {
  DeviceSpec spec;
  const std::string s = lower(trim(text));
  if (s.empty() || s == "default") return spec;
  if (s == "ref" || s == "reference" || s == "host") {
    spec.kind = Kind::Reference;
    return spec;
  }
  if (s == "cpu" || s == "gpu" || s == "accelerator") {
    spec.kind = Kind::Type;
    spec.type = s == "cpu" ? DeviceType::Cpu : s == "gpu" ? DeviceType::Gpu : DeviceType::Accelerator;
    return spec;
  }
  const std::size_t colon = s.find(':');
  const bool digitsAndColon = s.find_first_not_of("0123456789:") == std::string::npos;
  if (colon != std::string::npos && digitsAndColon) {
    const std::string a = s.substr(0, colon), b = s.substr(colon + 1);
    if (a.empty() || b.empty() || b.find(':') != std::string::npos || a.size() > 6 || b.size() > 6) {
      throw InvalidArgument("malformed device spec '" + std::string(text) +
                            "': expected P:D (platform and device index), e.g. 0:0");
    }
    spec.kind = Kind::Indices;
    spec.platform = std::stoi(a);
    spec.device = std::stoi(b);
    return spec;
  }
  spec.kind = Kind::Name;
  spec.name = s;
  return spec;
}

DeviceSpec DeviceSpec::fromEnvironment() {
  const char* env = std::getenv("DUPLEXFIT_DEVICE");
  return env != nullptr ? parse(env) : DeviceSpec{};
}

std::string DeviceSpec::toString() const {
  switch (kind) {
    case Kind::Default:
      return "default";
    case Kind::Reference:
      return "ref";
    case Kind::Indices:
      return std::to_string(platform) + ":" + std::to_string(device);
    case Kind::Type:
      return duplexfit::deviceTypeName(type);
    default:
      return name;
  }
}

Device Device::reference() {
  Device d;
  d.info_ = std::make_shared<const DeviceInfo>(referenceInfo());
  d.maxAllocBytes_ = d.info_->maxAllocBytes;
  return d;
}

Device Device::open(std::string_view spec, const DeviceOptions& options) {
  return open(DeviceSpec::parse(spec), options);
}

Device Device::openDefault(const DeviceOptions& options) {
  return open(DeviceSpec::fromEnvironment(), options);
}

Device Device::open(const DeviceSpec& spec, const DeviceOptions& options) {
  Device d;
  if (spec.kind == DeviceSpec::Kind::Reference) {
    d = reference();
  } else {
    const std::vector<ClDeviceEntry> entries = enumerateCl();
    const ClDeviceEntry* chosen = nullptr;
    if (spec.kind == DeviceSpec::Kind::Default) {
      for (DeviceType t : {DeviceType::Gpu, DeviceType::Cpu, DeviceType::Accelerator, DeviceType::Other}) {
        for (const auto& e : entries) {
          if (chosen == nullptr && e.info.type == t) chosen = &e;
        }
      }
      if (chosen == nullptr) d = reference();
    } else {
      for (const auto& e : entries) {
        if (chosen == nullptr && matches(spec, e.info)) chosen = &e;
      }
      if (chosen == nullptr) {
        throw DeviceError("no OpenCL device matches the spec '" + spec.toString() +
                          "'; available devices:" + listDevices(entries));
      }
    }
    if (chosen != nullptr) {
      d.impl_ = std::make_shared<detail::DeviceImpl>(chosen->device, chosen->info, options.allowFp64);
      d.info_ = std::make_shared<const DeviceInfo>(chosen->info);
      d.maxAllocBytes_ = chosen->info.maxAllocBytes;
    }
  }
  d.fp64Allowed_ = options.allowFp64;
  if (options.maxAllocBytes != 0) d.maxAllocBytes_ = std::min(d.maxAllocBytes_, options.maxAllocBytes);
  return d;
}

std::vector<DeviceInfo> Device::enumerate() {
  std::vector<DeviceInfo> out;
  for (auto& e : enumerateCl()) out.push_back(std::move(e.info));
  return out;
}

DeviceKind Device::kind() const noexcept { return impl_ ? DeviceKind::OpenCL : DeviceKind::Reference; }

const DeviceInfo& Device::info() const noexcept { return *info_; }

bool Device::supportsDouble() const noexcept { return fp64Allowed_ && info_->fp64; }

void Device::requirePrecision(Precision precision) const {
  if (precision != Precision::Double || supportsDouble()) return;
  const std::string why = info_->fp64 ? "double precision is disabled for it (DeviceOptions::allowFp64)"
                                      : "it reports no fp64 support (cl_khr_fp64)";
  throw DeviceError("device '" + info_->name + "' (" + info_->spec + ") cannot compute in double: " + why +
                    "; use float precision");
}

std::string Device::description() const {
  if (isReference()) return info_->name;
  return info_->name + " (" + info_->spec + ", " + info_->platform + ", driver " + info_->driverVersion + ")";
}

void Device::compileKernels(Precision precision) const {
  requirePrecision(precision);
  if (!impl_) return;
  for (const auto& entry : detail::programTable()) (void)impl_->program(entry.first, precision);
}

void Device::finish() const {
  if (impl_) DUPLEXFIT_CL_CHECK(impl_->queue().finish());
}

void Device::checkAllocation(std::uint64_t bytes, const std::string& what) const {
  if (bytes <= maxAllocBytes_) return;
  std::ostringstream msg;
  msg << what << " needs " << (bytes >> 20) << " MiB in one buffer but device '" << info_->name << "' ("
      << info_->spec << ") allows at most " << (maxAllocBytes_ >> 20)
      << " MiB per buffer; use a smaller system, float precision or another device";
  throw DeviceError(msg.str());
}

DeviceTuning Device::tuning() const { return impl_ == nullptr ? DeviceTuning{} : impl_->params().tuning(); }

std::string DeviceTuning::describe() const {
  if (workGroup == 0) return "reference";
  std::ostringstream s;
  s << "wg=" << workGroup << " chunk=" << chunk << " lanes=" << lanes << " groups=" << groups
    << " reductions=" << (chunkReductions ? "chunk" : "group") << " field=";
  if (fieldVector) {
    s << "vector" << fieldWidth << (fieldCoarseDouble ? "+double" : "") << (fieldTiles ? "+tiles" : "");
  } else {
    s << "scalar";
  }
  return s.str();
}

struct DeviceStopwatch::Markers {
  cl::Event begin, end;
};

DeviceStopwatch::DeviceStopwatch(const Device& device) : device_(device) {}
DeviceStopwatch::DeviceStopwatch(DeviceStopwatch&&) noexcept = default;
DeviceStopwatch& DeviceStopwatch::operator=(DeviceStopwatch&&) noexcept = default;
DeviceStopwatch::~DeviceStopwatch() = default;

void DeviceStopwatch::start() {
  device_.finish();
  if (!device_.isReference()) {
    if (!markers_) markers_ = std::make_unique<Markers>();
    DUPLEXFIT_CL_CHECK(device_.impl()->queue().enqueueMarkerWithWaitList(nullptr, &markers_->begin));
  }
  t0_ = SteadyClock::now();
}

void DeviceStopwatch::stop() {
  if (!device_.isReference() && markers_) {
    DUPLEXFIT_CL_CHECK(device_.impl()->queue().enqueueMarkerWithWaitList(nullptr, &markers_->end));
  }
  device_.finish();
  wallMs_ = secondsSince(t0_) * 1e3;
  deviceMs_ = std::numeric_limits<double>::quiet_NaN();
  if (!device_.isReference() && markers_) {
    cl_ulong b = 0, e = 0;
    if (markers_->begin.getProfilingInfo(CL_PROFILING_COMMAND_END, &b) == CL_SUCCESS &&
        markers_->end.getProfilingInfo(CL_PROFILING_COMMAND_END, &e) == CL_SUCCESS && e >= b) {
      deviceMs_ = static_cast<double>(e - b) * 1e-6;
    }
  }
}

}  // namespace duplexfit
