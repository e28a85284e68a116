// BLAS-1 operations and the fused CG vector updates: OpenCL launches and their reference twins.
#include <algorithm>
#include <cmath>

#include "device/cl_check.hpp"
#include "duplexfit/error.hpp"
#include "linalg/ops.hpp"
#include "linalg/storage.hpp"

namespace duplexfit {

using detail::dispatch;

namespace {

cl_uint toUint(std::size_t n) { return static_cast<cl_uint>(n); }

}  // namespace

void axpy(double alpha, const DeviceVector& x, DeviceVector& y) {
  detail::checkCompatible("axpy", x, y);
  const std::size_t n = x.size();
  if (n == 0) return;
  dispatch(x.precision(), [&](auto zero) {
    using T = decltype(zero);
    if (x.device().isReference()) {
      const T a = static_cast<T>(alpha);
      const T* xs = x.storage().host<T>().data();
      T* ys = y.storage().host<T>().data();
#pragma omp parallel for schedule(static)
      for (std::size_t i = 0; i < n; ++i) ys[i] += a * xs[i];
      return;
    }
    auto& impl = *x.device().impl();
    cl::Kernel& k = impl.kernel("blas1", x.precision(), "axpy");
    detail::setArg(k, 0, toUint(n), "axpy");
    detail::setRealArg(k, 1, alpha, x.precision(), "axpy");
    detail::setArg(k, 2, x.storage().buffer, "axpy");
    detail::setArg(k, 3, y.storage().buffer, "axpy");
    impl.launch(k, n, impl.params().workGroup, "axpy");
  });
}

void xpay(const DeviceVector& x, double beta, DeviceVector& y) {
  detail::checkCompatible("xpay", x, y);
  const std::size_t n = x.size();
  if (n == 0) return;
  dispatch(x.precision(), [&](auto zero) {
    using T = decltype(zero);
    if (x.device().isReference()) {
      const T b = static_cast<T>(beta);
      const T* xs = x.storage().host<T>().data();
      T* ys = y.storage().host<T>().data();
#pragma omp parallel for schedule(static)
      for (std::size_t i = 0; i < n; ++i) ys[i] = xs[i] + b * ys[i];
      return;
    }
    auto& impl = *x.device().impl();
    cl::Kernel& k = impl.kernel("blas1", x.precision(), "xpay");
    detail::setArg(k, 0, toUint(n), "xpay");
    detail::setArg(k, 1, x.storage().buffer, "xpay");
    detail::setRealArg(k, 2, beta, x.precision(), "xpay");
    detail::setArg(k, 3, y.storage().buffer, "xpay");
    impl.launch(k, n, impl.params().workGroup, "xpay");
  });
}

double dot(const DeviceVector& x, const DeviceVector& y) {
  detail::checkCompatible("dot", x, y);
  const std::size_t n = x.size();
  if (n == 0) return 0.0;
  return dispatch(x.precision(), [&](auto zero) -> double {
    using T = decltype(zero);
    if (x.device().isReference()) {
      const T* xs = x.storage().host<T>().data();
      const T* ys = y.storage().host<T>().data();
      double s = 0.0;
#pragma omp parallel for schedule(static) reduction(+ : s)
      for (std::size_t i = 0; i < n; ++i) s += static_cast<double>(xs[i] * ys[i]);
      return s;
    }
    auto& impl = *x.device().impl();
    const char* name = impl.params().chunkReductions ? "dot_chunk" : "dot_group";
    cl::Kernel& k = impl.kernel("blas1", x.precision(), name);
    detail::setArgs(k, name, toUint(n), x.storage().buffer, y.storage().buffer);
    return detail::reduceLaunch(x.device(), x.precision(), k, 3, n, 1, name)[0];
  });
}

double norm2(const DeviceVector& x) {
  const double d = dot(x, x);
  return std::isnan(d) ? d : std::sqrt(std::max(0.0, d));  // keep NaN visible to callers
}

namespace detail {

std::vector<double> reduceLaunch(const Device& device, Precision precision, cl::Kernel& k, unsigned partialArg,
                                 std::size_t n, std::size_t perItem, const char* name, std::size_t maxSlot) {
  DeviceImpl& impl = *device.impl();
  const auto& p = impl.params();
  std::size_t parts = 0, global = 0;
  if (p.chunkReductions) {
    parts = (n + p.chunk - 1) / p.chunk;
    global = parts;
  } else {
    parts = std::min(p.groups, (n + p.workGroup - 1) / p.workGroup);
    global = parts * p.workGroup;
  }
  cl::Buffer& scratch = impl.scratch(parts * perItem * sizeOf(precision));
  setArg(k, partialArg, scratch, name);
  impl.launch(k, global, p.workGroup, name);
  const std::vector<double> all = readPartials(impl, scratch, parts * perItem, precision);
  std::vector<double> sums(perItem, 0.0);
  for (std::size_t i = 0; i < all.size(); ++i) {
    const std::size_t slot = i % perItem;
    sums[slot] = slot == maxSlot ? std::max(sums[slot], all[i]) : sums[slot] + all[i];
  }
  return sums;
}

}  // namespace detail

namespace steps {

using namespace detail;  // the launch helpers

void vmul(const DeviceVector& d, const DeviceVector& r, DeviceVector& z) {
  checkCompatible("vmul", d, r);
  checkCompatible("vmul", r, z);
  const std::size_t n = r.size();
  if (n == 0) return;
  dispatch(r.precision(), [&](auto zero) {
    using T = decltype(zero);
    if (r.device().isReference()) {
      const T* ds = d.storage().host<T>().data();
      const T* rs = r.storage().host<T>().data();
      T* zs = z.storage().host<T>().data();
#pragma omp parallel for schedule(static)
      for (std::size_t i = 0; i < n; ++i) zs[i] = ds[i] * rs[i];
      return;
    }
    auto& impl = *r.device().impl();
    cl::Kernel& k = impl.kernel("blas1", r.precision(), "vmul");
    setArgs(k, "vmul", toUint(n), d.storage().buffer, r.storage().buffer, z.storage().buffer);
    impl.launch(k, n, impl.params().workGroup, "vmul");
  });
}

void triad(DeviceVector& a, const DeviceVector& b, const DeviceVector& c, double s) {
  checkCompatible("triad", a, b);
  checkCompatible("triad", b, c);
  const std::size_t n = a.size();
  if (n == 0) return;
  dispatch(a.precision(), [&](auto zero) {
    using T = decltype(zero);
    if (a.device().isReference()) {
      const T sc = static_cast<T>(s);
      T* as = a.storage().host<T>().data();
      const T* bs = b.storage().host<T>().data();
      const T* cs = c.storage().host<T>().data();
#pragma omp parallel for schedule(static)
      for (std::size_t i = 0; i < n; ++i) as[i] = bs[i] + sc * cs[i];
      return;
    }
    auto& impl = *a.device().impl();
    cl::Kernel& k = impl.kernel("blas1", a.precision(), "triad");
    setArgs(k, "triad", toUint(n), a.storage().buffer, b.storage().buffer, c.storage().buffer);
    setRealArg(k, 4, s, a.precision(), "triad");
    impl.launch(k, n, impl.params().workGroup, "triad");
  });
}

namespace {

// x ← x + αp, r ← r − αq with the reductions r·D·r (when dinv is given), r·r and max|r|: the body of both
// fused CG updates (kernels cg_update_* and cg_update_xr_*).
CgSums cgUpdateImpl(const char* op, double alpha, const DeviceVector& p, const DeviceVector& q,
                    const DeviceVector* dinv, DeviceVector& x, DeviceVector& r) {
  checkCompatible(op, p, q);
  if (dinv != nullptr) checkCompatible(op, p, *dinv);
  checkCompatible(op, p, x);
  checkCompatible(op, p, r);
  const std::size_t n = p.size();
  if (n == 0) return {};
  return dispatch(p.precision(), [&](auto zero) -> CgSums {
    using T = decltype(zero);
    if (p.device().isReference()) {
      const T a = static_cast<T>(alpha);
      const T* ps = p.storage().host<T>().data();
      const T* qs = q.storage().host<T>().data();
      const T* ds = dinv != nullptr ? dinv->storage().host<T>().data() : nullptr;
      T* xs = x.storage().host<T>().data();
      T* rs = r.storage().host<T>().data();
      double rz = 0.0, rr = 0.0, rmax = 0.0;
#pragma omp parallel for schedule(static) reduction(+ : rz, rr) reduction(max : rmax)
      for (std::size_t i = 0; i < n; ++i) {
        xs[i] += a * ps[i];
        const T ri = rs[i] - a * qs[i];
        rs[i] = ri;
        if (ds != nullptr) rz += static_cast<double>(ri * ds[i] * ri);
        rr += static_cast<double>(ri * ri);
        rmax = std::max(rmax, static_cast<double>(std::abs(ri)));
      }
      return {rz, rr, rmax};
    }
    auto& impl = *p.device().impl();
    const bool chunk = impl.params().chunkReductions;
    const char* name = dinv != nullptr ? (chunk ? "cg_update_chunk" : "cg_update_group")
                                       : (chunk ? "cg_update_xr_chunk" : "cg_update_xr_group");
    cl::Kernel& k = impl.kernel("cg", p.precision(), name);
    cl_uint arg = 0;
    setArg(k, arg++, toUint(n), name);
    setRealArg(k, arg++, alpha, p.precision(), name);
    setArg(k, arg++, p.storage().buffer, name);
    setArg(k, arg++, q.storage().buffer, name);
    if (dinv != nullptr) setArg(k, arg++, dinv->storage().buffer, name);
    setArg(k, arg++, x.storage().buffer, name);
    setArg(k, arg++, r.storage().buffer, name);
    if (dinv != nullptr) {
      const std::vector<double> v = reduceLaunch(p.device(), p.precision(), k, arg, n, 3, name, 2);
      return {v[0], v[1], v[2]};
    }
    const std::vector<double> v = reduceLaunch(p.device(), p.precision(), k, arg, n, 2, name, 1);
    return {0.0, v[0], v[1]};
  });
}

}  // namespace

CgSums cgUpdate(double alpha, const DeviceVector& p, const DeviceVector& q, const DeviceVector& dinv,
                DeviceVector& x, DeviceVector& r) {
  return cgUpdateImpl("cgUpdate", alpha, p, q, &dinv, x, r);
}

CgSums cgUpdateXR(double alpha, const DeviceVector& p, const DeviceVector& q, DeviceVector& x, DeviceVector& r) {
  return cgUpdateImpl("cgUpdateXR", alpha, p, q, nullptr, x, r);
}

void cgDirection(double beta, const DeviceVector& r, const DeviceVector& dinv, DeviceVector& p) {
  checkCompatible("cgDirection", r, dinv);
  checkCompatible("cgDirection", r, p);
  const std::size_t n = r.size();
  if (n == 0) return;
  dispatch(r.precision(), [&](auto zero) {
    using T = decltype(zero);
    if (r.device().isReference()) {
      const T b = static_cast<T>(beta);
      const T* rs = r.storage().host<T>().data();
      const T* ds = dinv.storage().host<T>().data();
      T* ps = p.storage().host<T>().data();
      if (beta == 0.0) {
#pragma omp parallel for schedule(static)
        for (std::size_t i = 0; i < n; ++i) ps[i] = ds[i] * rs[i];
      } else {
#pragma omp parallel for schedule(static)
        for (std::size_t i = 0; i < n; ++i) ps[i] = ds[i] * rs[i] + b * ps[i];
      }
      return;
    }
    if (beta == 0.0) {
      vmul(dinv, r, p);  // p may hold garbage (NaN): never read it
      return;
    }
    auto& impl = *r.device().impl();
    cl::Kernel& k = impl.kernel("cg", r.precision(), "cg_direction");
    setArg(k, 0, toUint(n), "cg_direction");
    setRealArg(k, 1, beta, r.precision(), "cg_direction");
    setArg(k, 2, r.storage().buffer, "cg_direction");
    setArg(k, 3, dinv.storage().buffer, "cg_direction");
    setArg(k, 4, p.storage().buffer, "cg_direction");
    impl.launch(k, n, impl.params().workGroup, "cg_direction");
  });
}

}  // namespace steps

}  // namespace duplexfit
