// Launchers of kernels/preprocess.cl (program "preprocess") and their reference-device path.
#include "preprocess/preprocess_device.hpp"

#include <limits>
#include <string>

#include "device/cl_check.hpp"
#include "device/device_impl.hpp"
#include "duplexfit/error.hpp"
#include "linalg/storage.hpp"
#include "preprocess/preprocess_ref.hpp"

namespace duplexfit::detail {

namespace {

template <typename T, typename S>
std::vector<T> convert(const std::vector<S>& v) {
  return std::vector<T>(v.begin(), v.end());
}

template <typename T>
cl::Buffer upload(const Device& device, const std::vector<T>& data, const std::string& what) {
  return uploadArray(device, data.data(), data.size(), what);
}

template <typename T>
std::vector<double> download(const Device& device, const cl::Buffer& b, std::size_t count) {
  std::vector<T> out(count);
  readArray(device, b, out.data(), count);
  return std::vector<double>(out.begin(), out.end());
}

void checkSize(std::size_t n, const char* what) {
  if (n >= std::numeric_limits<std::uint32_t>::max() / 6) {
    throw InvalidArgument(std::string(what) + ": " + std::to_string(n) + " points is too many for 32-bit kernel indices");
  }
}

}  // namespace

std::vector<double> bilateralPass(const Device& device, Precision precision, const std::vector<double>& pos,
                                  const std::vector<double>& nrm, const std::vector<double>& area,
                                  const std::vector<std::uint32_t>& offsets, const std::vector<std::uint32_t>& nbr,
                                  double a, double b) {
  device.requirePrecision(precision);
  const std::size_t n = area.size();
  checkSize(n, "bilateral filter");
  if (pos.size() != 3 * n || nrm.size() != 3 * n || offsets.size() != n + 1) {
    throw InvalidArgument("bilateralPass: array sizes do not match the point count");
  }
  return dispatch(precision, [&](auto zero) {
    using T = decltype(zero);
    const std::vector<T> p = convert<T>(pos), q = convert<T>(nrm), s = convert<T>(area);
    if (device.isReference()) {
      std::vector<T> d(3 * n);
      bilateralFilterReference<T>(n, p.data(), q.data(), s.data(), offsets.data(), nbr.data(), static_cast<T>(a),
                                  static_cast<T>(b), d.data());
      return std::vector<double>(d.begin(), d.end());
    }
    DeviceImpl& impl = *device.impl();
    const cl::Buffer pb = upload(device, p, "bilateral filter positions");
    const cl::Buffer nb = upload(device, q, "bilateral filter normals");
    const cl::Buffer sb = upload(device, s, "bilateral filter area weights");
    const cl::Buffer ob = upload(device, offsets, "bilateral filter neighbour offsets");
    const cl::Buffer ib = upload(device, nbr, "bilateral filter neighbour lists");
    const cl::Buffer db = createBuffer(device, std::max<std::size_t>(3 * n, 1) * sizeof(T), "bilateral filter output");
    const char* name = "bilateral_filter";
    cl::Kernel& k = impl.kernel("preprocess", precision, name);
    setArgs(k, name, static_cast<cl_uint>(n), pb, nb, sb, ob, ib);
    setRealArg(k, 6, a, precision, name);
    setRealArg(k, 7, b, precision, name);
    setArg(k, 8, db, name);
    impl.launch(k, n, impl.params().workGroup, name);
    return download<T>(device, db, 3 * n);
  });
}

std::vector<double> pcaCovariances(const Device& device, Precision precision, const std::vector<double>& pos,
                                   std::size_t k1, const std::vector<std::uint32_t>& nbr) {
  device.requirePrecision(precision);
  const std::size_t n = pos.size() / 3;
  checkSize(n, "normal estimation");
  if (nbr.size() != n * k1 || k1 == 0) throw InvalidArgument("pcaCovariances: neighbour array size mismatch");
  return dispatch(precision, [&](auto zero) {
    using T = decltype(zero);
    const std::vector<T> p = convert<T>(pos);
    if (device.isReference()) {
      std::vector<T> c(6 * n);
      pcaCovarianceReference<T>(n, k1, p.data(), nbr.data(), c.data());
      return std::vector<double>(c.begin(), c.end());
    }
    DeviceImpl& impl = *device.impl();
    const cl::Buffer pb = upload(device, p, "normal estimation positions");
    const cl::Buffer ib = upload(device, nbr, "normal estimation neighbour lists");
    const cl::Buffer cb = createBuffer(device, std::max<std::size_t>(6 * n, 1) * sizeof(T), "normal estimation covariances");
    const char* name = "pca_covariance";
    cl::Kernel& k = impl.kernel("preprocess", precision, name);
    setArgs(k, name, static_cast<cl_uint>(n), static_cast<cl_uint>(k1), pb, ib, cb);
    impl.launch(k, n, impl.params().workGroup, name);
    return download<T>(device, cb, 6 * n);
  });
}

}  // namespace duplexfit::detail
