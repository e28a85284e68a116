// OpenCL context, queue, program/kernel caches and launches of one device.
#include "device/device_impl.hpp"

#include <algorithm>
#include <cstdlib>
#include <sstream>

#include "device/cl_check.hpp"
#include "device/kernel_sources.hpp"
#include "duplexfit/error.hpp"

namespace duplexfit::detail {

namespace {

std::size_t envSize(const char* name, std::size_t fallback) {
  const char* v = std::getenv(name);
  if (v == nullptr || *v == '\0') return fallback;
  char* end = nullptr;
  const unsigned long long x = std::strtoull(v, &end, 10);
  if (end == v || *end != '\0' || x == 0) {
    throw InvalidArgument(std::string("environment variable ") + name + "='" + v +
                          "' is not a positive integer");
  }
  return static_cast<std::size_t>(x);
}

bool isPowerOfTwo(std::size_t x) { return x != 0 && (x & (x - 1)) == 0; }

/// Centres a step of the SIMD field kernels at the device's native float vector: 16 (AVX-512) or 8.
int nativeFieldWidth(const DeviceInfo& info) { return info.nativeFloatWidth >= 16 ? 16 : 8; }

LaunchParams chooseParams(const DeviceInfo& info, bool fp64Allowed) {
  LaunchParams p;
  if (info.type == DeviceType::Cpu) {
    // PoCL's CPU device: barriers are slow and there are no sub-groups (docs/pocl-notes.md), so
    // reductions are barrier-free chunks and SpMV maps one row to one work-item.
    p.workGroup = 64;
    p.chunk = 512;
    p.lanes = 4;
    p.groups = std::max<std::size_t>(4, 4 * info.computeUnits);
    p.chunkReductions = true;
    // The field sum's inner loop over a row of centres runs 8 centres a step in SIMD registers (float):
    // 1.6-1.9x (value) and 1.7x (value and gradient) faster than one centre a step on PoCL; 16 a step
    // where the device's native float vector is that wide (AVX-512): another 1.25x (value) and 1.3x
    // (value and gradient) on this project's Zen 5 machine (docs/benchmarks.md).
    p.fieldVector = true;
    p.fieldWidth = nativeFieldWidth(info);
    // The coarse levels with large weights summed in double (kernels/eval_field.cl): the float sum's error
    // floor was 2.85e-6 of the box on fandisk_550k, 5e-5 on thin_torus_20k (docs/method.md section 6).
    p.fieldCoarseDouble = info.fp64;
    // The coarse levels a tile of fieldWidth queries at a time (kernels/eval_field.cl, the _tile kernels):
    // 1.3-1.9x faster per point at mesh vertices and grid nodes of fandisk_550k and wheel_29k
    // (docs/benchmarks.md).
    p.fieldTiles = true;
  } else {
    p.workGroup = 256;
    p.chunk = 512;
    p.lanes = 16;
    p.groups = std::max<std::size_t>(64, 8 * info.computeUnits);
    p.chunkReductions = false;
    p.fieldVector = false;  // a GPU's lanes are its work-items: one query a work-item
  }
  if (const char* v = std::getenv("DUPLEXFIT_REDUCTIONS"); v != nullptr && *v != '\0') {
    const std::string mode = v;
    if (mode != "chunk" && mode != "group") {
      throw InvalidArgument("DUPLEXFIT_REDUCTIONS='" + mode + "' must be chunk or group");
    }
    p.chunkReductions = mode == "chunk";
  }
  if (const char* v = std::getenv("DUPLEXFIT_FIELD_KERNEL"); v != nullptr && *v != '\0') {
    const std::string mode = v;
    if (mode != "vector" && mode != "vector8" && mode != "vector16" && mode != "scalar") {
      throw InvalidArgument("DUPLEXFIT_FIELD_KERNEL='" + mode + "' must be vector, vector8, vector16 or scalar");
    }
    p.fieldVector = mode != "scalar";
    if (mode == "vector") p.fieldWidth = nativeFieldWidth(info);
    if (mode == "vector8") p.fieldWidth = 8;
    if (mode == "vector16") p.fieldWidth = 16;
  }
  if (const char* v = std::getenv("DUPLEXFIT_FIELD_TILES"); v != nullptr && *v != '\0') {
    const std::string mode = v;
    if (mode != "0" && mode != "1") throw InvalidArgument("DUPLEXFIT_FIELD_TILES='" + mode + "' must be 0 or 1");
    p.fieldTiles = mode == "1";
  }
  if (const char* v = std::getenv("DUPLEXFIT_FIELD_COARSE"); v != nullptr && *v != '\0') {
    const std::string mode = v;
    if (mode != "double" && mode != "float") {
      throw InvalidArgument("DUPLEXFIT_FIELD_COARSE='" + mode + "' must be double or float");
    }
    if (mode == "double" && !info.fp64) {
      throw InvalidArgument("DUPLEXFIT_FIELD_COARSE=double: device '" + info.name + "' has no fp64");
    }
    p.fieldCoarseDouble = mode == "double";
  }
  // The scalar kernel (GPUs) stays float, and so does a handle that may not use double
  // (DeviceOptions::allowFp64): its field program then has no double code at all.
  p.fieldCoarseDouble = p.fieldCoarseDouble && p.fieldVector && fp64Allowed;
  p.fieldTiles = p.fieldTiles && p.fieldVector;  // the tile kernels are SIMD kernels
  p.workGroup = envSize("DUPLEXFIT_WG_SIZE", p.workGroup);
  p.chunk = envSize("DUPLEXFIT_CHUNK", p.chunk);
  p.lanes = envSize("DUPLEXFIT_LANES", p.lanes);
  if (info.maxWorkGroupSize != 0) p.workGroup = std::min(p.workGroup, info.maxWorkGroupSize);
  if (!isPowerOfTwo(p.workGroup) || !isPowerOfTwo(p.lanes) || p.lanes > p.workGroup) {
    throw InvalidArgument("work-group size " + std::to_string(p.workGroup) + " and lanes " +
                          std::to_string(p.lanes) +
                          " must be powers of two with lanes <= work-group size");
  }
  return p;
}

}  // namespace

DeviceTuning LaunchParams::tuning() const {
  DeviceTuning t;
  t.workGroup = workGroup;
  t.chunk = chunk;
  t.lanes = lanes;
  t.groups = groups;
  t.chunkReductions = chunkReductions;
  t.fieldVector = fieldVector;
  t.fieldWidth = fieldVector ? fieldWidth : 1;
  t.fieldCoarseDouble = fieldCoarseDouble;
  t.fieldTiles = fieldTiles;
  return t;
}

std::string LaunchParams::describe() const { return tuning().describe(); }

const std::vector<std::pair<std::string, std::vector<std::string>>>& programTable() {
  static const std::vector<std::pair<std::string, std::vector<std::string>>> table = {
      {"blas1", {"common", "blas1"}},
      {"spmv", {"common", "spmv_csr"}},
      {"cg", {"common", "cg_fused"}},
      {"field", {"common", "field_point", "eval_field"}},
      {"precond", {"common", "precond"}},
      {"preprocess", {"common", "preprocess"}},
      {"assemble", {"common", "assemble"}},
  };
  return table;
}

void throwKernelArgError(cl_int status, const char* kernelName, cl_uint index) {
  throwClError(status, std::string("clSetKernelArg(") + kernelName + ", " + std::to_string(index) + ")");
}

DeviceImpl::DeviceImpl(const cl::Device& device, const DeviceInfo& info, bool fp64Allowed)
    : device_(device), info_(info), params_(chooseParams(info, fp64Allowed)) {
  cl_int status = CL_SUCCESS;
  context_ = cl::Context(device_, nullptr, nullptr, nullptr, &status);
  DUPLEXFIT_CL_CHECK(status);
  queue_ = cl::CommandQueue(context_, device_, CL_QUEUE_PROFILING_ENABLE, &status);
  DUPLEXFIT_CL_CHECK(status);
}

std::string DeviceImpl::buildOptions(const std::string& extra) const {
  std::string options = "-cl-std=CL1.2";
  if (const char* env = std::getenv("DUPLEXFIT_CL_BUILD_OPTIONS"); env != nullptr && *env != '\0') {
    options += " ";
    options += env;
  }
  if (!extra.empty()) options += " " + extra;
  return options;
}

std::string DeviceImpl::programSource(const std::string& program, Precision precision) const {
  const auto& table = programTable();
  const auto it = std::find_if(table.begin(), table.end(),
                               [&](const auto& entry) { return entry.first == program; });
  if (it == table.end()) throw DeviceError("unknown OpenCL program '" + program + "'");
  std::ostringstream src;
  if (precision == Precision::Double) {
    src << "#pragma OPENCL EXTENSION cl_khr_fp64 : enable\n#define REAL double\n#define REAL_IS_DOUBLE 1\n";
  } else {
    src << "#define REAL float\n";
  }
  src << "#define WG " << params_.workGroup << "\n#define CHUNK " << params_.chunk << "\n#define LANES "
      << params_.lanes << "\n#define FIELD_WIDTH " << params_.fieldWidth << "\n";
  if (program == "field" && precision == Precision::Float && params_.fieldCoarseDouble) {
    src << "#define DPX_COARSE_DOUBLE 1\n";
  }
  for (const std::string& file : it->second) {
    src << "// ---- " << file << ".cl\n" << kernelSource(file) << "\n";
  }
  return src.str();
}

cl::Program DeviceImpl::program(const std::string& name, Precision precision, const std::string& extraOptions) {
  if (precision == Precision::Double && !info_.fp64) {
    throw DeviceError("device '" + info_.name + "' (" + info_.spec +
                      ") does not support double precision (no cl_khr_fp64); use float");
  }
  const std::lock_guard<std::mutex> lock(mutex_);
  const auto key = std::make_tuple(name, precision, extraOptions);
  if (auto it = programs_.find(key); it != programs_.end()) return it->second;

  const std::string source = programSource(name, precision);
  const std::string options = buildOptions(extraOptions);
  cl_int status = CL_SUCCESS;
  cl::Program prog(context_, source, false, &status);
  DUPLEXFIT_CL_CHECK(status);
  const cl_int buildStatus = prog.build(std::vector<cl::Device>{device_}, options.c_str());
  std::string log;
  prog.getBuildInfo(device_, CL_PROGRAM_BUILD_LOG, &log);
  if (buildStatus != CL_SUCCESS) {
    std::ostringstream msg;
    msg << "OpenCL program '" << name << "' (" << precisionName(precision) << ") failed to build on device '"
        << info_.name << "' (" << info_.spec << ", " << info_.platform << " " << info_.driverVersion
        << ") with options '" << options << "': " << clErrorName(buildStatus) << "\nbuild log:\n"
        << log;
    throw BuildError(msg.str(), log, buildStatus);
  }
  programs_.emplace(key, prog);
  return prog;
}

cl::Kernel& DeviceImpl::kernel(const std::string& programName, Precision precision,
                               const std::string& kernelName) {
  {
    const std::lock_guard<std::mutex> lock(mutex_);
    const auto key = std::make_tuple(programName, precision, kernelName);
    if (auto it = kernels_.find(key); it != kernels_.end()) return it->second;
  }
  cl::Program prog = program(programName, precision);
  cl_int status = CL_SUCCESS;
  cl::Kernel k(prog, kernelName.c_str(), &status);
  if (status != CL_SUCCESS) throwClError(status, "clCreateKernel(" + kernelName + ")");
  const std::lock_guard<std::mutex> lock(mutex_);
  return kernels_.emplace(std::make_tuple(programName, precision, kernelName), k).first->second;
}

cl::Buffer& DeviceImpl::scratch(std::size_t bytes) {
  if (bytes > scratchBytes_) {
    const std::size_t size = std::max<std::size_t>(bytes, 4096);
    cl_int status = CL_SUCCESS;
    scratch_ = cl::Buffer(context_, CL_MEM_READ_WRITE, size, nullptr, &status);
    if (status != CL_SUCCESS) throwClError(status, "clCreateBuffer(reduction scratch)");
    scratchBytes_ = size;
  }
  return scratch_;
}

void DeviceImpl::launch(cl::Kernel& k, std::size_t global, std::size_t local, const char* name) {
  if (global == 0) return;
  const std::size_t rounded = (global + local - 1) / local * local;
  const cl_int status =
      queue_.enqueueNDRangeKernel(k, cl::NullRange, cl::NDRange(rounded), cl::NDRange(local));
  if (status != CL_SUCCESS) throwClError(status, std::string("clEnqueueNDRangeKernel(") + name + ")");
}

}  // namespace duplexfit::detail
