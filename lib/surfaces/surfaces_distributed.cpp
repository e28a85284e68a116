// Distributed extraction (docs/method.md, "Distributed fit"): each rank polygonizes a slab of the one
// grid, rank 0 welds the slabs by vertex key.
#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <string>
#include <type_traits>
#include <vector>

#include "duplexfit/communicator.hpp"
#include "duplexfit/error.hpp"
#include "duplexfit/surfaces.hpp"
#include "duplexfit/timer.hpp"

namespace duplexfit {

namespace {

template <class T>
void put(std::vector<unsigned char>& out, const T* data, std::size_t n) {
  const auto* b = reinterpret_cast<const unsigned char*>(data);
  out.insert(out.end(), b, b + n * sizeof(T));
}

/// Reads n values of T at `at` from a received buffer, checking its bounds.
template <class T>
void take(const std::vector<unsigned char>& in, std::size_t& at, std::size_t end, T* data, std::size_t n) {
  const std::size_t bytes = n * sizeof(T);
  if (at > end || end - at < bytes) throw Error("distributed extraction: a slab's mesh message is truncated");
  if (bytes > 0) std::memcpy(data, in.data() + at, bytes);
  at += bytes;
}

}  // namespace

std::vector<int> slabCuts(const ImplicitField& field, const GridSpec& grid, int parts) {
  if (parts < 1) throw InvalidArgument("slabCuts: parts must be >= 1");
  const int nz = grid.cells(2);
  std::vector<int> cuts(static_cast<std::size_t>(parts) + 1, nz);
  cuts[0] = 0;
  if (parts == 1) return cuts;
  // Histogram of the finest level's centres (world z) over the cell layers.
  std::vector<std::int64_t> count(static_cast<std::size_t>(nz), 0);
  std::int64_t total = 0;
  if (!field.levels().empty()) {
    const FieldLevel& finest = field.levels().back();
    const Normalization& n = field.normalization();
    const double z0 = grid.box.min()(2), h = grid.cellSize()(2);
    for (Eigen::Index i = 0; i < finest.centres.rows(); ++i) {
      const double z = finest.centres(i, 2) / n.scale + n.centre(2);
      const auto k = static_cast<std::int64_t>(std::floor((z - z0) / h));
      ++count[static_cast<std::size_t>(std::clamp<std::int64_t>(k, 0, nz - 1))];
      ++total;
    }
  }
  if (total == 0) {
    for (int s = 1; s < parts; ++s) cuts[static_cast<std::size_t>(s)] = static_cast<int>(std::int64_t{nz} * s / parts);
    return cuts;
  }
  std::int64_t seen = 0;
  int k = 0;
  for (int s = 1; s < parts; ++s) {
    const std::int64_t share = total * s / parts;
    while (k < nz && seen + count[static_cast<std::size_t>(k)] <= share) seen += count[static_cast<std::size_t>(k++)];
    cuts[static_cast<std::size_t>(s)] = std::max(k, cuts[static_cast<std::size_t>(s - 1)]);
  }
  return cuts;
}

SurfaceResult extractSurfacesDistributed(Communicator& comm, const FieldEvaluator& evaluator, const ImplicitField& field,
                                         const std::vector<double>& isoValues, const SurfaceOptions& options,
                                         Interrupter* interrupter, DistributedExtractionReport* report) {
  if (isoValues.empty()) throw InvalidArgument("surface extraction: no iso values given");
  if (evaluator.levelCount() != static_cast<int>(field.levels().size())) {
    throw InvalidArgument("surface extraction: the evaluator holds " + std::to_string(evaluator.levelCount()) +
                          " levels, the field " + std::to_string(field.levels().size()));
  }
  const int me = comm.rank(), ranks = comm.size();
  SurfaceResult out;
  out.grid = surfaceGrid(field, isoValues, options);
  const FieldSampler sampler = valueSampler(evaluator);
  PolygonizeOptions po = surfacePolygonizeOptions(field, options);
  po.keepVertexKeys = true;
  SlabExtractionReport mine;
  mine.rank = me;
  PolygonizeResult r;
  for (int attempt = 0;; ++attempt) {
    const std::vector<int> cuts = slabCuts(field, out.grid, ranks);
    mine.slabBegin = cuts[static_cast<std::size_t>(me)];
    mine.slabEnd = cuts[static_cast<std::size_t>(me) + 1];
    const auto start = std::chrono::steady_clock::now();
    if (mine.slabEnd > mine.slabBegin) {
      po.slabBegin = mine.slabBegin;
      po.slabEnd = mine.slabEnd;
      r = polygonize(sampler, out.grid, isoValues, po, interrupter);
    } else {
      r = PolygonizeResult();
      r.meshes.resize(isoValues.size());
      r.vertexKeys.resize(isoValues.size());
    }
    mine.seconds += secondsSince(start);
    // Grow the box on every rank where any rank's level set reaches it (as extractSurfaces does).
    std::array<double, 6> touch = boundaryContacts(r.meshes, out.grid);
    comm.allreduce(touch.data(), touch.size(), ReduceOp::Max);
    const bool touches = std::any_of(touch.begin(), touch.end(), [](double t) { return t > 0.0; });
    out.boxGrowths = attempt;
    if (!touches || attempt >= 3) {
      out.touchesBoundary = touches;
      break;
    }
    out.grid = grownGrid(out.grid, touch);
  }
  mine.evaluatedNodes = r.stats.evaluatedNodes;
  mine.refinedCells = r.stats.refinedCells;
  for (const Mesh& m : r.meshes) mine.triangles += m.faces.rows();

  // The slabs' meshes to rank 0: per iso value, vertex and face counts, keys, positions, faces.
  std::vector<std::vector<unsigned char>> send(static_cast<std::size_t>(ranks));
  std::vector<unsigned char>& msg = send[0];
  for (std::size_t q = 0; q < isoValues.size(); ++q) {
    const Mesh& m = r.meshes[q];
    const std::uint64_t counts[2] = {static_cast<std::uint64_t>(m.vertices.rows()), static_cast<std::uint64_t>(m.faces.rows())};
    put(msg, counts, 2);
    put(msg, r.vertexKeys[q].data(), r.vertexKeys[q].size());
    for (Eigen::Index v = 0; v < m.vertices.rows(); ++v) {
      const double x[3] = {m.vertices(v, 0), m.vertices(v, 1), m.vertices(v, 2)};
      put(msg, x, 3);
    }
    for (Eigen::Index f = 0; f < m.faces.rows(); ++f) {
      const std::int32_t t[3] = {static_cast<std::int32_t>(m.faces(f, 0)), static_cast<std::int32_t>(m.faces(f, 1)),
                                 static_cast<std::int32_t>(m.faces(f, 2))};
      put(msg, t, 3);
    }
  }
  mine.bytesSent = me == 0 ? 0 : msg.size();
  r.meshes.clear();
  r.vertexKeys.clear();
  std::vector<std::size_t> received;
  const std::vector<unsigned char> all = comm.alltoallv(send, received);
  send.clear();

  // Statistics: sums over the ranks (times: the slowest rank's).
  PolygonizeStats& s = out.stats;
  s = r.stats;
  const auto reduce = [&comm](auto fields, ReduceOp op) {
    std::vector<std::remove_pointer_t<typename decltype(fields)::value_type>> v;
    for (const auto* f : fields) v.push_back(*f);
    comm.allreduce(v.data(), v.size(), op);
    for (std::size_t i = 0; i < v.size(); ++i) *fields[i] = v[i];
  };
  reduce(std::array<std::int64_t*, 11>{&s.evaluatedNodes, &s.samplerCalls, &s.coarseBlocks, &s.refinedBlocks,
                                       &s.continuedCells, &s.thinCells, &s.deviatingCells, &s.shallowCells,
                                       &s.refinedCells, &s.refinedTetrahedra, &s.refinedEvaluations},
         ReduceOp::Sum);
  reduce(std::array<double*, 5>{&s.samplingSeconds, &s.samplerSeconds, &s.extractionSeconds, &s.refinedSeconds,
                                &s.totalSeconds},
         ReduceOp::Max);
  s.totalNodes = out.grid.nodeCount();
  if (report != nullptr) {
    report->ranks = comm.allgather(std::vector<SlabExtractionReport>{mine});
  }

  out.meshes.resize(isoValues.size());
  if (me != 0) return out;
  // Rank 0: unpack every slab and weld each level set.
  const auto weldStart = std::chrono::steady_clock::now();
  std::vector<std::vector<Mesh>> pieces(static_cast<std::size_t>(ranks), std::vector<Mesh>(isoValues.size()));
  std::vector<std::vector<std::vector<std::uint64_t>>> keys(
      static_cast<std::size_t>(ranks), std::vector<std::vector<std::uint64_t>>(isoValues.size()));
  std::size_t at = 0;
  for (std::size_t src = 0; src < static_cast<std::size_t>(ranks); ++src) {
    const std::size_t end = at + received[src];
    for (std::size_t q = 0; q < isoValues.size(); ++q) {
      std::uint64_t counts[2];
      take(all, at, end, counts, 2);
      if (counts[0] > (end - at) / 8 || counts[1] > (end - at) / 12) {
        throw Error("distributed extraction: rank " + std::to_string(src) + " sent inconsistent mesh counts");
      }
      Mesh& m = pieces[src][q];
      keys[src][q].resize(static_cast<std::size_t>(counts[0]));
      take(all, at, end, keys[src][q].data(), keys[src][q].size());
      m.vertices.resize(static_cast<Eigen::Index>(counts[0]), 3);
      for (Eigen::Index v = 0; v < m.vertices.rows(); ++v) {
        double x[3];
        take(all, at, end, x, 3);
        for (int d = 0; d < 3; ++d) m.vertices(v, d) = x[d];
      }
      m.faces.resize(static_cast<Eigen::Index>(counts[1]), 3);
      for (Eigen::Index f = 0; f < m.faces.rows(); ++f) {
        std::int32_t t[3];
        take(all, at, end, t, 3);
        for (int d = 0; d < 3; ++d) m.faces(f, d) = t[d];
      }
    }
    if (at != end) throw Error("distributed extraction: rank " + std::to_string(src) + " sent extra bytes");
  }
  for (std::size_t q = 0; q < isoValues.size(); ++q) {
    std::vector<const Mesh*> meshes;
    std::vector<const std::vector<std::uint64_t>*> keyLists;
    for (std::size_t src = 0; src < static_cast<std::size_t>(ranks); ++src) {
      meshes.push_back(&pieces[src][q]);
      keyLists.push_back(&keys[src][q]);
    }
    out.meshes[q] = weldByKeys(meshes, keyLists);
  }
  if (report != nullptr) report->weldSeconds = secondsSince(weldStart);
  return out;
}

}  // namespace duplexfit
