// FieldEvaluator: per-level grids of the field's centres (cells at least σ_k deep in y and z and an
// eighth of that wide along x, so that the 3 × 3 rows of cells around a query hold every centre within
// the support and each row is cut to the support's x-extent), uploaded once; batched evaluation by the
// eval_field kernels or, on the reference device, by the same body (kernels/field_point.cl) in C++.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <mutex>
#include <type_traits>

#include "device/cl_check.hpp"
#include "device/device_impl.hpp"
#include "duplexfit/error.hpp"
#include "duplexfit/field.hpp"
#include "linalg/storage.hpp"
#include "spatial/morton.hpp"

namespace duplexfit {

namespace detail {

namespace kernels {
#include "field_point.cl"  // NOLINT(bugprone-suspicious-include): the body shared with OpenCL
}  // namespace kernels

struct EvaluatorImpl {
  Device device;
  Precision precision = Precision::Float;
  Normalization norm;
  double f0 = -1.0;
  cl_uint levels = 0;
  std::vector<double> params;           // 7 per level: origin xyz, 1/cell (y, z), sigma, 1/sigma, 1/cell (x)
  std::vector<cl_uint> dims;            // 5 per level: nx, ny, nz, cell_start offset, centre offset
  std::vector<cl_uint> cellStart;       // per level nx*ny*nz + 1 prefix offsets
  std::size_t centres = 0;               // centres of the levels added so far
  std::vector<double> packed;           // x, y, z, w per centre, sorted by cell within each level
  std::vector<float> paramsF, packedF;  // float copies (precision float)
  /// With the SIMD kernels (float on a CPU device): the centres level by level as four arrays x, y, z,
  /// w of the level's size each, level k from 4 × its centre offset (kernels/eval_field.cl), written by
  /// addLevel straight from the level; packed and packedF are then not kept (fandisk_550k: the whole
  /// field's 104 MB of doubles grew again for the finest level, 0.27-0.8 s of fresh pages and copies).
  bool soa = false;
  std::vector<float> soaF;
  /// With soa, where the device's tuning says fieldCoarseDouble: the levels of at most
  /// kDoubleLevelMaxCentres centres whose largest |w| exceeds kDoubleLevelWeight also in double, block by
  /// block (σ, 1/σ, then x, y, z, w arrays in the float arrays' order), which the SIMD kernels sum in
  /// double; dlevel[k] is level k's block offset in soaD, or kFloatLevel.
  bool coarseDouble = false;
  std::vector<double> soaD;
  std::vector<cl_uint> dlevel;
  /// A device copy of one host array: `capacity` elements allocated, the first `uploaded` current.
  struct DeviceArray {
    cl::Buffer buffer;
    std::size_t capacity = 0, uploaded = 0;
  };
  DeviceArray paramsBuf, dimsBuf, cellStartBuf, centresBuf, dlevelBuf, dcentresBuf;
  /// The query and result buffers of evaluateRaw, kept between calls (used under the device's launch
  /// mutex): a new pair per chunk cost the driver fresh pages every time (PoCL allocates a buffer's host
  /// memory when it is first used and frees it with the buffer).
  mutable cl::Buffer queryBuf, resultBuf;
  mutable std::size_t queryBytes = 0, resultBytes = 0;

  explicit EvaluatorImpl(const Device& d) : device(d) {}
};

}  // namespace detail

namespace {

constexpr std::size_t kMaxCellsPerLevel = std::size_t{1} << 24;
/// Cells along x per cell in y and z: a query visits in each of its 3 × 3 rows the cells within the
/// support's x-extent (kernels/field_point.cl, dpx_x_span), on average 2σ + σ/kSplitX of the row, where
/// cubic σ cells gave 3σ. Cutting each row further to the support's extent at the row's distance in
/// (y, z) visited fewer centres still but cost more than it saved in the value kernel (docs/benchmarks.md).
constexpr std::size_t kSplitX = 8;
constexpr std::size_t kChunk = std::size_t{1} << 20;
/// Reals past the last centre in the device buffer: the SIMD kernels (kernels/eval_field.cl, _v8) read, and
/// mask, up to FIELD_WIDTH − 1 ≤ 15 reals past the last weight.
constexpr std::size_t kCentrePad = 4 * 8;
/// A level of at most kDoubleLevelMaxCentres centres whose largest |weight| exceeds kDoubleLevelWeight is
/// summed in double by the SIMD kernels (docs/method.md §6). Measured (float terms against double at 200k
/// zero-mesh vertices of six fits): a level's float error is about 0.4-0.8e-6 |w|max (normalised units),
/// and the coarsest levels carry the largest weights (fandisk_550k: 2.95 and 1.26 at levels 1 and 2, whose
/// float error was 2.4e-6 and 1e-6 of the box). A level with few centres costs little in double; the next
/// one (857 centres at fandisk_550k) cost 1.25x the whole evaluation where levels 1-2 cost 1.05-1.08x.
constexpr double kDoubleLevelWeight = 0.25;
constexpr std::size_t kDoubleLevelMaxCentres = 256;
constexpr cl_uint kFloatLevel = 0xffffffffu;
/// Doubles past the last block: the kernels read, and mask, up to 7 past a row.
constexpr std::size_t kDoublePad = 8;

void addLevel(detail::EvaluatorImpl& e, const FieldLevel& level) {
  const Points& c = level.centres;
  const auto n = static_cast<std::size_t>(c.rows());
  Eigen::Vector3d lo = Eigen::Vector3d::Zero(), hi = Eigen::Vector3d::Zero();
  if (n > 0) {
    lo = c.colwise().minCoeff().transpose();
    hi = c.colwise().maxCoeff().transpose();
  }
  // Where the table would exceed kMaxCellsPerLevel, the x-cells widen first (σ/4, σ/2, σ) and only then
  // the cells grow in y and z: a row of σ/2-wide x-cells visits 2½σ where 1.5625σ-deep rows (the first
  // that fits fandisk_550k's finest level with eighth-wide x-cells) visit 2.4× the cross-section.
  double cell = level.sigma, cellX = cell / static_cast<double>(kSplitX);
  std::size_t nx = 1, ny = 1, nz = 1;
  for (std::size_t split = kSplitX;;) {
    cellX = cell / static_cast<double>(split);
    const Eigen::Vector3d ext = (hi - lo) / cell;
    nx = static_cast<std::size_t>(std::floor((hi.x() - lo.x()) / cellX)) + 1;
    ny = static_cast<std::size_t>(std::floor(ext.y())) + 1;
    nz = static_cast<std::size_t>(std::floor(ext.z())) + 1;
    if (nx * ny * nz <= kMaxCellsPerLevel) break;
    if (split > 1) {
      split /= 2;
      continue;
    }
    cell *= 1.25;  // coarser cells: still ≥ σ in y and z, so the 3 × 3 rows stay complete
    split = kSplitX;
  }
  const std::size_t cells = nx * ny * nz;
  const std::size_t cellBase = e.cellStart.size();
  const std::size_t centreBase = e.centres;
  if (centreBase + n > std::numeric_limits<cl_uint>::max() || cellBase + cells + 1 > std::numeric_limits<cl_uint>::max()) {
    throw InvalidArgument("FieldEvaluator: the field has too many centres for 32-bit indices");
  }
  // A counting sort straight into the level's part of the table (no count or cursor copies: at the finest
  // levels the table has millions of cells, and fresh pages are what a fit pays most for). After the
  // prefix sum, start[c + 1] is where cell c ends; the centres go in from the last one down, each at
  // --start[its cell + 1], so each cell keeps its centres in index order and start[c + 1] ends as the
  // start of cell c, shifted one place down at the end.
  std::vector<cl_uint> cellOf(n);  // cells ≤ kMaxCellsPerLevel
  e.cellStart.resize(cellBase + cells + 1, 0);
  cl_uint* start = e.cellStart.data() + cellBase;
  for (std::size_t j = 0; j < n; ++j) {
    const auto i = static_cast<Eigen::Index>(j);
    const auto ix = std::min(nx - 1, static_cast<std::size_t>((c(i, 0) - lo.x()) / cellX));
    const auto iy = std::min(ny - 1, static_cast<std::size_t>((c(i, 1) - lo.y()) / cell));
    const auto iz = std::min(nz - 1, static_cast<std::size_t>((c(i, 2) - lo.z()) / cell));
    cellOf[j] = static_cast<cl_uint>((iz * ny + iy) * nx + ix);
    ++start[cellOf[j] + 1];
  }
  for (std::size_t k = 0; k < cells; ++k) start[k + 1] += start[k];
  if (e.soa) {
    e.soaF.resize(4 * (centreBase + n));
    float* out = e.soaF.data() + 4 * centreBase;
    const bool inDouble = e.coarseDouble && n > 0 && n <= kDoubleLevelMaxCentres &&
                          level.weights.cwiseAbs().maxCoeff() > kDoubleLevelWeight;
    double* outD = nullptr;
    if (inDouble) {
      const std::size_t block = e.soaD.size();
      if (block + 2 + 4 * n > std::numeric_limits<cl_uint>::max()) {
        throw InvalidArgument("FieldEvaluator: the field's double levels are too large for 32-bit indices");
      }
      e.soaD.resize(block + 2 + 4 * n);
      e.soaD[block] = level.sigma;
      e.soaD[block + 1] = 1.0 / level.sigma;
      outD = e.soaD.data() + block + 2;
      e.dlevel.push_back(static_cast<cl_uint>(block));
    } else {
      e.dlevel.push_back(kFloatLevel);
    }
    for (std::size_t j = n; j-- > 0;) {
      const std::size_t slot = --start[cellOf[j] + 1];
      const auto i = static_cast<Eigen::Index>(j);
      out[slot] = static_cast<float>(c(i, 0));
      out[n + slot] = static_cast<float>(c(i, 1));
      out[2 * n + slot] = static_cast<float>(c(i, 2));
      out[3 * n + slot] = static_cast<float>(level.weights[i]);
      if (outD != nullptr) {
        outD[slot] = c(i, 0);
        outD[n + slot] = c(i, 1);
        outD[2 * n + slot] = c(i, 2);
        outD[3 * n + slot] = level.weights[i];
      }
    }
  } else {
    e.packed.resize(4 * (centreBase + n));
    for (std::size_t j = n; j-- > 0;) {
      const std::size_t slot = 4 * (centreBase + --start[cellOf[j] + 1]);
      const auto i = static_cast<Eigen::Index>(j);
      e.packed[slot] = c(i, 0);
      e.packed[slot + 1] = c(i, 1);
      e.packed[slot + 2] = c(i, 2);
      e.packed[slot + 3] = level.weights[i];
    }
  }
  e.centres += n;
  std::copy(start + 1, start + cells + 1, start);  // start[c] = the start of cell c
  start[cells] = static_cast<cl_uint>(n);
  e.params.insert(e.params.end(), {lo.x(), lo.y(), lo.z(), 1.0 / cell, level.sigma, 1.0 / level.sigma, 1.0 / cellX});
  e.dims.insert(e.dims.end(), {static_cast<cl_uint>(nx), static_cast<cl_uint>(ny), static_cast<cl_uint>(nz),
                               static_cast<cl_uint>(cellBase), static_cast<cl_uint>(centreBase)});
  ++e.levels;
}

// The reference device's twin of the eval_field kernels: the same body (kernels/field_point.cl,
// compiled here as C++), one query per loop iteration.
template <typename T>
void evalReference(const detail::EvaluatorImpl& e, const std::vector<T>& params, const std::vector<T>& packed,
                   const T* q, std::size_t nq, int k, T* out) {
#pragma omp parallel for schedule(dynamic, 1024)
  for (std::ptrdiff_t qi = 0; qi < static_cast<std::ptrdiff_t>(nq); ++qi) {
    T acc[10];
    detail::kernels::dpx_field_point<T>(q[3 * qi], q[3 * qi + 1], q[3 * qi + 2], e.levels, params.data(), e.dims.data(),
                                e.cellStart.data(), packed.data(), static_cast<T>(e.f0), k, acc);
    std::copy(acc, acc + k, out + static_cast<std::ptrdiff_t>(k) * qi);
  }
}

/// Queries in a scattered order (consecutive ones far apart: a cloud in random order, as Poisson-disk and
/// uniform samples are) read each level's centres from all over the field: on fandisk_550k's field (2.2M
/// centres) its 1.8M zero-mesh vertices took 2.1 µs a point shuffled against 0.65 µs in the mesh's order. Such
/// a chunk of queries (kChunk at most) is evaluated in Morton order and the results put back in place, so
/// no copy of a whole batch is made. Judged on the chunk's first kProbe queries: sorted when the median step
/// between consecutive ones exceeds kScattered times the median step of the same queries in Morton order (a
/// mesh's, a grid's or a scan's order is about as coherent as that).
constexpr Eigen::Index kSortMinQueries = Eigen::Index{1} << 15;
constexpr Eigen::Index kProbe = 4096;
constexpr double kScattered = 4.0;
/// Batches the tile kernels take in their own order (smaller ones: as they come).
constexpr Eigen::Index kTileSortMin = 256;

double medianStep(const Points& p, const std::vector<std::uint32_t>& order) {
  std::vector<double> step;
  step.reserve(static_cast<std::size_t>(p.rows()));
  for (Eigen::Index r = 1; r < p.rows(); ++r) {
    const auto a = order.empty() ? r - 1 : static_cast<Eigen::Index>(order[static_cast<std::size_t>(r - 1)]);
    const auto b = order.empty() ? r : static_cast<Eigen::Index>(order[static_cast<std::size_t>(r)]);
    step.push_back((p.row(b) - p.row(a)).squaredNorm());
  }
  if (step.empty()) return 0.0;
  std::nth_element(step.begin(), step.begin() + static_cast<std::ptrdiff_t>(step.size() / 2), step.end());
  return std::sqrt(step[step.size() / 2]);
}

/// The order to evaluate rows [begin, begin + m) of u in: empty for their own, else a Morton order of them
/// (offsets from begin; see kScattered).
std::vector<std::uint32_t> evaluationOrder(const Points& u, std::size_t begin, std::size_t m) {
  if (m < static_cast<std::size_t>(kSortMinQueries)) return {};
  const auto chunk = u.middleRows(static_cast<Eigen::Index>(begin), static_cast<Eigen::Index>(m));  // no copy
  if (!chunk.allFinite()) return {};
  const Points probe = chunk.topRows(kProbe);
  const double own = medianStep(probe, {}), sorted = medianStep(probe, detail::processingOrder(probe, 2));
  if (!(own > kScattered * sorted)) return {};
  return detail::processingOrder(Points(chunk), 2);
}

/// The levels the tile kernels sum a tile at a time: all but the two finest (kernels/eval_field.cl), whose
/// supports are not much wider than the distance between neighbouring queries (fandisk_550k's zero-mesh
/// vertices: 0.34 µs a point with two levels left per query, 0.50 with one, 0.58 with none).
cl_uint tileLevels(const detail::EvaluatorImpl& e) {
  return e.levels <= 2 ? 0 : static_cast<cl_uint>(e.levels - 2);
}

/// Whether a batch of k results a query goes to the tile kernels: the float SIMD kernels on an OpenCL device
/// with fieldTiles, value or gradient, and levels to tile.
template <typename T>
bool tileKernels(const detail::EvaluatorImpl& e, int k) {
  return std::is_same_v<T, float> && !e.device.isReference() && e.device.impl()->params().fieldTiles && k <= 4 &&
         tileLevels(e) > 0;
}

/// The order the tile kernels take a batch in (rows of u; empty: its own): a Morton order of the whole
/// batch, so that each tile of consecutive queries is compact (a mesh's or a grid's own order is coherent
/// at the scale of a few cells but not within 16 consecutive queries: fandisk_550k's zero mesh took 0.72 µs
/// a point in its order against 0.36 sorted). Queries sharing a Morton cell (1/1024 of the batch's box a
/// side) follow in the order of their coordinates, so the order, and with it each tile and each query's
/// value, depends on the batch's points and not on the order they come in.
std::vector<std::uint32_t> tileOrder(const Points& u) {
  const auto n = static_cast<std::size_t>(u.rows());
  if (n < static_cast<std::size_t>(kTileSortMin) || n > std::numeric_limits<std::uint32_t>::max() || !u.allFinite()) {
    return {};
  }
  const std::vector<std::uint64_t> key = detail::mortonSortedKeys(n, [&u](std::size_t i, double* x) {
    for (int a = 0; a < 3; ++a) x[a] = u(static_cast<Eigen::Index>(i), a);
  });
  std::vector<std::uint32_t> order(n);
  for (std::size_t i = 0; i < n; ++i) order[i] = static_cast<std::uint32_t>(key[i] & 0xffffffffU);
  const auto byCoordinates = [&u](std::uint32_t a, std::uint32_t b) {
    for (int c = 0; c < 3; ++c) {
      const double x = u(static_cast<Eigen::Index>(a), c), y = u(static_cast<Eigen::Index>(b), c);
      if (x != y) return x < y;
    }
    return false;  // the same point: either order gives the same tiles
  };
  for (std::size_t run = 0; run < n;) {
    std::size_t end = run + 1;
    while (end < n && (key[end] >> 32) == (key[run] >> 32)) ++end;
    if (end - run > 1) {
      std::sort(order.begin() + static_cast<std::ptrdiff_t>(run), order.begin() + static_cast<std::ptrdiff_t>(end),
                byCoordinates);
    }
    run = end;
  }
  return order;
}

// Evaluates normalised queries (#Q×3) into a #Q×k row-major array of normalised results, a chunk at a time:
// for the tile kernels the whole batch in its tile order (tileOrder), else each chunk in Morton order where
// it comes scattered (evaluationOrder).
std::vector<double> evaluateRaw(const detail::EvaluatorImpl& e, const Points& u, int k) {
  const auto nq = static_cast<std::size_t>(u.rows());
  std::vector<double> result(nq * static_cast<std::size_t>(k));
  if (nq == 0) return result;
  detail::dispatch(e.precision, [&](auto zero) {
    using T = decltype(zero);
    const bool tiled = tileKernels<T>(e, k);
    const std::vector<std::uint32_t> sorted = tiled ? tileOrder(u) : std::vector<std::uint32_t>{};
    for (std::size_t begin = 0; begin < nq; begin += kChunk) {
      const std::size_t m = std::min(kChunk, nq - begin);
      const std::vector<std::uint32_t> order = tiled ? std::vector<std::uint32_t>{} : evaluationOrder(u, begin, m);
      // Query i of the chunk is row row(i) of u.
      const auto row = [&order, &sorted, begin](std::size_t i) {
        return !sorted.empty() ? static_cast<std::size_t>(sorted[begin + i])
                               : begin + (order.empty() ? i : static_cast<std::size_t>(order[i]));
      };
      std::vector<T> q(3 * m), out(static_cast<std::size_t>(k) * m);
      for (std::size_t i = 0; i < m; ++i) {
        const auto r = static_cast<Eigen::Index>(row(i));
        for (int c = 0; c < 3; ++c) q[3 * i + static_cast<std::size_t>(c)] = static_cast<T>(u(r, c));
      }
      if (e.device.isReference()) {
        if constexpr (std::is_same_v<T, double>) {
          evalReference<double>(e, e.params, e.packed, q.data(), m, k, out.data());
        } else {
          evalReference<float>(e, e.paramsF, e.packedF, q.data(), m, k, out.data());
        }
      } else {
        auto& impl = *e.device.impl();
        const std::lock_guard<std::mutex> lock(impl.launchMutex());
        const std::size_t qBytes = q.size() * sizeof(T), oBytes = out.size() * sizeof(T);
        if (e.queryBytes < qBytes) {
          e.queryBuf = cl::Buffer();
          e.queryBuf = detail::createBuffer(e.device, qBytes, "field query points");
          e.queryBytes = qBytes;
        }
        if (e.resultBytes < oBytes) {
          e.resultBuf = cl::Buffer();
          e.resultBuf = detail::createBuffer(e.device, oBytes, "field evaluation results");
          e.resultBytes = oBytes;
        }
        const cl::Buffer& qb = e.queryBuf;
        const cl::Buffer& ob = e.resultBuf;
        DUPLEXFIT_CL_CHECK(impl.queue().enqueueWriteBuffer(qb, CL_TRUE, 0, qBytes, q.data()));
        const bool v8 = impl.params().fieldVector && std::is_same_v<T, float>;  // float only (eval_field.cl)
        const char* name = tiled    ? (k == 1 ? "eval_field_value_tile" : "eval_field_gradient_tile")
                           : k == 1 ? (v8 ? "eval_field_value_v8" : "eval_field_value")
                           : k == 4 ? (v8 ? "eval_field_gradient_v8" : "eval_field_gradient")
                                    : (v8 ? "eval_field_hessian_v8" : "eval_field_hessian");
        cl::Kernel& kern = impl.kernel("field", e.precision, name);
        detail::setArgs(kern, name, static_cast<cl_uint>(m), qb, e.levels, e.paramsBuf.buffer, e.dimsBuf.buffer,
                        e.cellStartBuf.buffer, e.centresBuf.buffer);
        detail::setRealArg(kern, 7, e.f0, e.precision, name);
        std::size_t items = m, local = impl.params().workGroup;
        if (v8) {
          detail::setArg(kern, 8, e.dlevelBuf.buffer, name);
          detail::setArg(kern, 9, e.dcentresBuf.buffer, name);
          if (tiled) {
            // One work-item a tile of fieldWidth queries; smaller work-groups for a small batch, so that a
            // few thousand queries still make enough groups to spread over the cores (16 at least: each
            // group costs PoCL a few microseconds, so large batches keep the usual size).
            const auto width = static_cast<std::size_t>(impl.params().fieldWidth);
            detail::setArg(kern, 10, tileLevels(e), name);
            detail::setArg(kern, 11, ob, name);
            items = (m + width - 1) / width;
            while (local > 1 && items < 16 * local) local /= 2;
          } else {
            detail::setArg(kern, 10, ob, name);
          }
        } else {
          detail::setArg(kern, 8, ob, name);
        }
        impl.launch(kern, items, local, name);
        DUPLEXFIT_CL_CHECK(impl.queue().enqueueReadBuffer(ob, CL_TRUE, 0, out.size() * sizeof(T), out.data()));
      }
      const auto width = static_cast<std::size_t>(k);
      for (std::size_t i = 0; i < m; ++i) {
        for (std::size_t c = 0; c < width; ++c) result[width * row(i) + c] = static_cast<double>(out[width * i + c]);
      }
    }
  });
  return result;
}

/// Brings the device copy of `host` up to date: only the elements appended since the last call are
/// written, into the same buffer while it has room; otherwise a new buffer of `reserve` × the size
/// (clipped to the device's largest allocation) receives everything. `pad` more elements are always
/// allocated past the host's (never written: the SIMD field kernels read, and mask, up to 15 reals
/// past the last one).
template <typename T>
void syncArray(const Device& device, detail::EvaluatorImpl::DeviceArray& a, const std::vector<T>& host, double reserve,
               const std::string& what, std::size_t pad = 0) {
  auto& queue = device.impl()->queue();
  if (host.size() + pad > a.capacity || a.capacity == 0) {
    const std::size_t need = std::max<std::size_t>(host.size() + pad, 1);
    const std::size_t limit = std::max<std::size_t>(need, static_cast<std::size_t>(device.maxAllocBytes() / sizeof(T)));
    const std::size_t capacity = std::min(limit, std::max(need, static_cast<std::size_t>(reserve * static_cast<double>(need))));
    a.buffer = detail::createBuffer(device, capacity * sizeof(T), what);
    a.capacity = capacity;
    a.uploaded = 0;
  }
  if (host.size() > a.uploaded) {
    DUPLEXFIT_CL_CHECK(queue.enqueueWriteBuffer(a.buffer, CL_TRUE, a.uploaded * sizeof(T),
                                                (host.size() - a.uploaded) * sizeof(T), host.data() + a.uploaded));
  }
  a.uploaded = host.size();
}

/// Makes the float copies and the device buffers current after levels were added.
void sync(detail::EvaluatorImpl& e, double reserve) {
  const bool soa = e.soa;
  if (e.precision == Precision::Float) {
    e.paramsF.insert(e.paramsF.end(), e.params.begin() + static_cast<std::ptrdiff_t>(e.paramsF.size()), e.params.end());
    if (!soa) {
      e.packedF.insert(e.packedF.end(), e.packed.begin() + static_cast<std::ptrdiff_t>(e.packedF.size()), e.packed.end());
    }
  }
  if (e.device.isReference()) return;
  if (e.precision == Precision::Float) {
    syncArray(e.device, e.paramsBuf, e.paramsF, reserve, "field level parameters");
    syncArray(e.device, e.centresBuf, soa ? e.soaF : e.packedF, reserve, "field centres", kCentrePad);
  } else {
    syncArray(e.device, e.paramsBuf, e.params, reserve, "field level parameters");
    syncArray(e.device, e.centresBuf, e.packed, reserve, "field centres", kCentrePad);
  }
  if (soa) {
    syncArray(e.device, e.dlevelBuf, e.dlevel, reserve, "field level precisions");
    syncArray(e.device, e.dcentresBuf, e.soaD, reserve, "field centres in double", kDoublePad);
  }
  syncArray(e.device, e.dimsBuf, e.dims, reserve, "field grid sizes");
  syncArray(e.device, e.cellStartBuf, e.cellStart, reserve, "field grid cells");
}

}  // namespace

FieldEvaluator::FieldEvaluator(const Device& device, const ImplicitField& field, Precision precision, int levelCount)
    : FieldEvaluator(device, field.normalization(), field.f0(), precision) {
  auto& e = *impl_;
  const int total = static_cast<int>(field.levels().size());
  const int use = levelCount < 0 ? total : std::min(levelCount, total);
  for (int k = 0; k < use; ++k) addLevel(e, field.levels()[static_cast<std::size_t>(k)]);
  sync(e, 1.0);
}

FieldEvaluator::FieldEvaluator(const Device& device, const Normalization& normalization, double f0,
                               Precision precision)
    : impl_(std::make_unique<detail::EvaluatorImpl>(device)) {
  device.requirePrecision(precision);
  auto& e = *impl_;
  e.precision = precision;
  e.norm = normalization;
  e.f0 = f0;
  e.soa = precision == Precision::Float && !device.isReference() && device.impl()->params().fieldVector;
  e.coarseDouble = e.soa && device.tuning().fieldCoarseDouble;  // the device's rule, DeviceOptions included
}

void FieldEvaluator::appendLevel(const FieldLevel& level) {
  addLevel(*impl_, level);
  // Room for about as much again: the levels of a fit grow geometrically, so each buffer is
  // reallocated O(log) times and otherwise only the new level is written.
  sync(*impl_, 2.0);
}

void FieldEvaluator::dropLastLevel() {
  auto& e = *impl_;
  if (e.levels == 0) throw InvalidArgument("FieldEvaluator::dropLastLevel: there is no level to drop");
  const std::size_t last = e.levels - 1;
  const std::size_t cellBase = e.dims[5 * last + 3], centreBase = e.dims[5 * last + 4];
  e.params.resize(7 * last);
  e.dims.resize(5 * last);
  e.cellStart.resize(cellBase);
  e.centres = centreBase;
  if (e.soa) {
    e.soaF.resize(4 * centreBase);
    if (e.dlevel.back() != kFloatLevel) e.soaD.resize(e.dlevel.back());
    e.dlevel.pop_back();
  } else {
    e.packed.resize(4 * centreBase);
  }
  e.paramsF.resize(std::min(e.paramsF.size(), e.params.size()));
  e.packedF.resize(std::min(e.packedF.size(), e.packed.size()));
  --e.levels;
  // The device copies keep their buffers; what lies past the host arrays now is written again when a
  // level is appended (syncArray writes from `uploaded` on).
  const auto clip = [](detail::EvaluatorImpl::DeviceArray& a, std::size_t size) { a.uploaded = std::min(a.uploaded, size); };
  const bool f = e.precision == Precision::Float;
  clip(e.paramsBuf, f ? e.paramsF.size() : e.params.size());
  clip(e.centresBuf, e.soa ? e.soaF.size() : f ? e.packedF.size() : e.packed.size());
  clip(e.dlevelBuf, e.dlevel.size());
  clip(e.dcentresBuf, e.soaD.size());
  clip(e.dimsBuf, e.dims.size());
  clip(e.cellStartBuf, e.cellStart.size());
}

int FieldEvaluator::levelCount() const noexcept { return static_cast<int>(impl_->levels); }

FieldEvaluator::FieldEvaluator(FieldEvaluator&&) noexcept = default;
FieldEvaluator& FieldEvaluator::operator=(FieldEvaluator&&) noexcept = default;
FieldEvaluator::~FieldEvaluator() = default;

const Device& FieldEvaluator::device() const { return impl_->device; }

Eigen::VectorXd FieldEvaluator::evaluateNormalized(const Points& u) const {
  const std::vector<double> raw = evaluateRaw(*impl_, u, 1);
  return Eigen::Map<const Eigen::VectorXd>(raw.data(), static_cast<Eigen::Index>(raw.size()));
}

FieldSamples FieldEvaluator::evaluate(const Points& queries, FieldDerivatives derivatives) const {
  const auto& e = *impl_;
  for (Eigen::Index i = 0; i < queries.rows(); ++i) {
    if (!queries.row(i).allFinite()) {
      throw InvalidArgument("field evaluation: query point " + std::to_string(i) + " is not finite");
    }
  }
  const Points u = (e.norm.scale * (queries.rowwise() - e.norm.centre.transpose())).eval();
  const int k = derivatives == FieldDerivatives::None ? 1 : derivatives == FieldDerivatives::Gradient ? 4 : 10;
  const std::vector<double> raw = evaluateRaw(e, u, k);
  FieldSamples s;
  const Eigen::Index n = queries.rows();
  s.values.resize(n);
  if (k >= 4) s.gradients.resize(n, 3);
  if (k >= 10) s.hessians.resize(n, 6);
  for (Eigen::Index i = 0; i < n; ++i) {
    const double* r = &raw[static_cast<std::size_t>(k * i)];
    s.values[i] = r[0] / e.norm.scale;  // f_world = f_normalised / scale; ∇ unchanged; H · scale
    if (k >= 4) s.gradients.row(i) << r[1], r[2], r[3];
    if (k >= 10) {
      for (int c = 0; c < 6; ++c) s.hessians(i, c) = r[4 + c] * e.norm.scale;
    }
  }
  return s;
}

}  // namespace duplexfit
