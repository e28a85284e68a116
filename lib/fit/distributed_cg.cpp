// Distributed PCG on a level's global system (the exact mode of the distributed fit, docs/method.md
// "Distributed fit"): the rank's rows with ghost columns, the ghost exchange, rank-order reductions and
// the rank-local block Jacobi preconditioner. The iteration and its stopping rules are solveCg's.
#include "fit/distributed_cg.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
#include <limits>

#include <Eigen/Cholesky>

#include "duplexfit/error.hpp"
#include "duplexfit/timer.hpp"
#include "duplexfit/wendland.hpp"
#include "fit/partition.hpp"

namespace duplexfit::detail {

namespace {

// Element-wise over the ranks, every rank's partials added (first `sums` entries) or maxed (the rest) in
// rank order: the same doubles on every rank and in every run, whatever the MPI library's algorithm.
std::vector<double> reduceInRankOrder(Communicator& comm, const std::vector<double>& mine, std::size_t sums,
                                      std::uint64_t& bytes) {
  const std::vector<double> all = comm.allgather(mine);
  bytes += static_cast<std::uint64_t>(all.size() * sizeof(double));
  const std::size_t n = mine.size();
  std::vector<double> out(n, 0.0);
  for (std::size_t j = sums; j < n; ++j) out[j] = -std::numeric_limits<double>::infinity();
  for (std::size_t at = 0; at + n <= all.size(); at += n) {
    for (std::size_t j = 0; j < n; ++j) out[j] = j < sums ? out[j] + all[at + j] : std::max(out[j], all[at + j]);
  }
  return out;
}

// y ← A·x over the rank's rows.
void multiply(const CsrMatrix& a, const Eigen::VectorXd& x, Eigen::VectorXd& y) {
#pragma omp parallel for schedule(static)
  for (Index i = 0; i < a.rows; ++i) {
    double s = 0.0;
    for (Index k = a.rowPtr[static_cast<std::size_t>(i)]; k < a.rowPtr[static_cast<std::size_t>(i) + 1]; ++k) {
      s += a.values[static_cast<std::size_t>(k)] * x[a.colIdx[static_cast<std::size_t>(k)]];
    }
    y[i] = s;
  }
}

// The owned entries of v that the other ranks need, to them; their entries into v's ghost tail.
void exchangeGhosts(Communicator& comm, const DistributedSystem& s, Eigen::VectorXd& v, std::uint64_t& bytes) {
  if (comm.size() == 1) return;
  std::vector<std::vector<unsigned char>> send(static_cast<std::size_t>(comm.size()));
  for (std::size_t r = 0; r < send.size(); ++r) {
    const std::vector<std::uint32_t>& rows = s.sendRows[r];
    send[r].resize(rows.size() * sizeof(double));
    for (std::size_t i = 0; i < rows.size(); ++i) {
      const double value = v[static_cast<Eigen::Index>(rows[i])];
      std::memcpy(send[r].data() + i * sizeof(double), &value, sizeof(double));
    }
  }
  std::vector<std::size_t> counts;
  const std::vector<unsigned char> got = comm.alltoallv(send, counts);
  if (got.size() != s.ghosts * sizeof(double)) {
    throw InvalidArgument("distributed CG: received " + std::to_string(got.size() / sizeof(double)) + " ghost values, expected " +
                          std::to_string(s.ghosts));
  }
  if (s.ghosts > 0) std::memcpy(v.data() + s.owned, got.data(), got.size());
  bytes += static_cast<std::uint64_t>(got.size());
}

// Block Jacobi over the owned rows: dense inverses of the diagonal blocks of `blockSize` consecutive rows
// (Cholesky; the diagonal where a block is not numerically SPD), as BlockJacobiPreconditioner.
class LocalBlockJacobi {
 public:
  LocalBlockJacobi(const CsrMatrix& a, std::size_t n, int blockSize) : n_(n), bs_(static_cast<std::size_t>(std::max(1, blockSize))) {
    const std::size_t blocks = (n_ + bs_ - 1) / bs_;
    inverses_.resize(blocks);
#pragma omp parallel for schedule(dynamic, 64)
    for (std::ptrdiff_t bi = 0; bi < static_cast<std::ptrdiff_t>(blocks); ++bi) {
      const std::size_t base = static_cast<std::size_t>(bi) * bs_;
      const auto m = static_cast<Eigen::Index>(std::min(bs_, n_ - base));
      Eigen::MatrixXd block = Eigen::MatrixXd::Zero(m, m);
      for (Eigen::Index i = 0; i < m; ++i) {
        const std::size_t row = base + static_cast<std::size_t>(i);
        for (Index k = a.rowPtr[row]; k < a.rowPtr[row + 1]; ++k) {
          const auto c = static_cast<std::size_t>(a.colIdx[static_cast<std::size_t>(k)]);
          if (c >= base && c < base + static_cast<std::size_t>(m)) block(i, static_cast<Eigen::Index>(c - base)) = a.values[static_cast<std::size_t>(k)];
        }
      }
      Eigen::MatrixXd inv;
      const Eigen::LLT<Eigen::MatrixXd> llt(block);
      if (llt.info() == Eigen::Success) {
        inv = llt.solve(Eigen::MatrixXd::Identity(m, m));
      } else {
        inv = Eigen::MatrixXd::Zero(m, m);
        for (Eigen::Index i = 0; i < m; ++i) inv(i, i) = block(i, i) > 0.0 ? 1.0 / block(i, i) : 1.0;
      }
      inverses_[static_cast<std::size_t>(bi)] = std::move(inv);
    }
  }
  void apply(const Eigen::VectorXd& r, Eigen::VectorXd& z) const {
    for (std::size_t bi = 0; bi < inverses_.size(); ++bi) {
      const auto base = static_cast<Eigen::Index>(bi * bs_);
      const Eigen::Index m = inverses_[bi].rows();
      z.segment(base, m).noalias() = inverses_[bi] * r.segment(base, m);
    }
  }

 private:
  std::size_t n_, bs_;
  std::vector<Eigen::MatrixXd> inverses_;
};

}  // namespace

DistributedSystem distributedSystem(Communicator& comm, const Points& owned, double sigma, double lambda,
                                    const HierarchyBox& box) {
  DistributedSystem s;
  s.owned = static_cast<std::size_t>(owned.rows());
  const int p = comm.size(), me = comm.rank();
  // Global numbering: the ranks' blocks in rank order.
  const std::vector<std::int64_t> counts = comm.allgather(std::vector<std::int64_t>{static_cast<std::int64_t>(owned.rows())});
  s.setupBytes += static_cast<std::uint64_t>(counts.size() * sizeof(std::int64_t));
  std::vector<std::int64_t> first(static_cast<std::size_t>(p) + 1, 0);
  for (int r = 0; r < p; ++r) first[static_cast<std::size_t>(r) + 1] = first[static_cast<std::size_t>(r)] + counts[static_cast<std::size_t>(r)];
  std::vector<std::int64_t> ids(s.owned);
  for (std::size_t i = 0; i < ids.size(); ++i) ids[i] = first[static_cast<std::size_t>(me)] + static_cast<std::int64_t>(i);

  // Candidate ghosts: the other ranks' centres in cells of side σ next to ours, in (rank, row) order,
  // i.e. by global id.
  const Points zeros = Points::Zero(owned.rows(), 3);
  const OwnedRows near = exchangeHalo(comm, owned, zeros, ids, box, sigma);
  s.setupBytes += static_cast<std::uint64_t>(near.ids.size()) * 56;
  const auto candidates = static_cast<Eigen::Index>(near.ids.size());
  Points all(owned.rows() + candidates, 3);
  all.topRows(owned.rows()) = owned;
  if (candidates > 0) all.bottomRows(candidates) = near.positions;
  CsrMatrix full;  // a rank without centres at this level has no rows (it still takes part in the collectives)
  if (all.rows() > 0) full = assembleWendland(all, sigma, lambda);
  full.rowPtr.resize(static_cast<std::size_t>(all.rows()) + 1, 0);

  // The owned rows; ghost columns renumbered over the candidates that some owned row couples to.
  std::vector<Index> ghostColumn(static_cast<std::size_t>(candidates), -1);
  for (std::size_t i = 0; i < s.owned; ++i) {
    for (Index k = full.rowPtr[i]; k < full.rowPtr[i + 1]; ++k) {
      const auto c = static_cast<std::size_t>(full.colIdx[static_cast<std::size_t>(k)]);
      if (c >= s.owned) ghostColumn[c - s.owned] = 0;
    }
  }
  std::vector<std::vector<std::uint32_t>> requests(static_cast<std::size_t>(p));
  Index next = static_cast<Index>(s.owned);
  for (std::size_t g = 0; g < ghostColumn.size(); ++g) {
    if (ghostColumn[g] < 0) continue;
    ghostColumn[g] = next++;
    const std::int64_t id = near.ids[g];
    const auto owner = static_cast<std::size_t>(std::upper_bound(first.begin(), first.end(), id) - first.begin()) - 1;
    requests[owner].push_back(static_cast<std::uint32_t>(id - first[owner]));
  }
  s.ghosts = static_cast<std::size_t>(next) - s.owned;
  CsrMatrix& a = s.rows;
  a.rows = static_cast<Index>(s.owned);
  a.cols = next;
  a.rowPtr.assign(1, 0);
  for (std::size_t i = 0; i < s.owned; ++i) {
    for (Index k = full.rowPtr[i]; k < full.rowPtr[i + 1]; ++k) {
      const auto c = static_cast<std::size_t>(full.colIdx[static_cast<std::size_t>(k)]);
      a.colIdx.push_back(c < s.owned ? static_cast<Index>(c) : ghostColumn[c - s.owned]);
      a.values.push_back(full.values[static_cast<std::size_t>(k)]);
    }
    a.rowPtr.push_back(static_cast<Index>(a.colIdx.size()));
  }
  // Columns stay sorted: owned ones keep their numbers and ghosts are renumbered in increasing order.

  // Tell every owner which of its rows we need (once); what each rank asks of us is what we send it.
  s.sendRows.assign(static_cast<std::size_t>(p), {});
  if (p > 1) {
    std::vector<std::vector<unsigned char>> send(static_cast<std::size_t>(p));
    for (std::size_t r = 0; r < send.size(); ++r) {
      send[r].resize(requests[r].size() * sizeof(std::uint32_t));
      if (!requests[r].empty()) std::memcpy(send[r].data(), requests[r].data(), send[r].size());
    }
    std::vector<std::size_t> got;
    const std::vector<unsigned char> asked = comm.alltoallv(send, got);
    s.setupBytes += static_cast<std::uint64_t>(asked.size());
    std::size_t at = 0;
    for (std::size_t r = 0; r < got.size(); ++r) {
      s.sendRows[r].resize(got[r] / sizeof(std::uint32_t));
      if (got[r] > 0) std::memcpy(s.sendRows[r].data(), asked.data() + at, got[r]);
      for (const std::uint32_t row : s.sendRows[r]) {
        if (row >= s.owned) throw InvalidArgument("distributed CG: rank " + std::to_string(r) + " asked for row " + std::to_string(row));
      }
      at += got[r];
    }
  }
  return s;
}

DistributedSolve solveDistributedCg(Communicator& comm, const DistributedSystem& s, const Eigen::VectorXd& b,
                                    Eigen::VectorXd& xOut, const SolverOptions& options, Precision precision,
                                    int blockSize) {
  const auto start = std::chrono::steady_clock::now();
  DistributedSolve out;
  SolveStats& stats = out.stats;
  const auto n = static_cast<Eigen::Index>(s.owned);
  if (b.size() != n) throw InvalidArgument("distributed CG: b has " + std::to_string(b.size()) + " entries for " + std::to_string(n) + " rows");
  stats.tolerance = options.relativeTolerance > 0.0 ? options.relativeTolerance : precision == Precision::Double ? 1e-6 : 1e-5;
  stats.absoluteTolerance = options.absoluteTolerance;
  auto finish = [&](StopReason reason) {
    stats.reason = reason;
    stats.converged = reason == StopReason::Converged || reason == StopReason::ZeroRhs;
    stats.seconds = secondsSince(start);
    xOut.conservativeResize(n);
    return out;
  };
  std::uint64_t& bytes = out.bytes;
  auto reduce = [&](std::vector<double> mine, std::size_t sums) { return reduceInRankOrder(comm, mine, sums, bytes); };
  const Eigen::Index width = n + static_cast<Eigen::Index>(s.ghosts);
  xOut = Eigen::VectorXd::Zero(width);
  const double bnorm = std::sqrt(reduce({b.squaredNorm()}, 1)[0]);
  if (!std::isfinite(bnorm)) return finish(StopReason::NonFinite);
  if (bnorm == 0.0) return finish(StopReason::ZeroRhs);
  const double target = stats.tolerance * bnorm;

  const auto tp = std::chrono::steady_clock::now();
  const LocalBlockJacobi pre(s.rows, s.owned, blockSize);
  out.preconditionerSeconds = secondsSince(tp);
  Eigen::VectorXd& x = xOut;
  Eigen::VectorXd p = Eigen::VectorXd::Zero(width), r(n), z(n), q(n), t(n);
  struct Sums {
    double rz = 0, rr = 0, rmax = 0;
  };
  auto maxAbs = [](const Eigen::VectorXd& v) { return v.size() > 0 ? v.cwiseAbs().maxCoeff() : 0.0; };
  auto restart = [&]() -> Sums {
    exchangeGhosts(comm, s, x, bytes);
    multiply(s.rows, x, q);
    r = b - q;
    pre.apply(r, z);
    p.head(n) = z;
    const std::vector<double> g = reduce({r.dot(z), r.squaredNorm(), maxAbs(r)}, 2);
    return {g[0], g[1], g[2]};
  };
  auto trueResidual = [&]() -> std::pair<double, double> {
    exchangeGhosts(comm, s, x, bytes);
    multiply(s.rows, x, q);
    t = b - q;
    const std::vector<double> g = reduce({t.squaredNorm(), maxAbs(t)}, 1);
    return {std::sqrt(std::max(g[0], 0.0)), g[1]};
  };
  const double absTol = options.absoluteTolerance;
  auto converged = [&](double norm, double mx) { return norm <= target || (absTol > 0.0 && mx <= absTol); };
  Sums sums = restart();
  bool haveTrue = false;
  double trueNormLast = 0.0, trueMaxLast = 0.0;
  int restarts = 0, it = 0;
  StopReason reason = StopReason::IterationLimit;
  for (;;) {
    const double rnorm = std::sqrt(std::max(sums.rr, 0.0));
    stats.recurrenceResidual = rnorm / bnorm;
    if (!std::isfinite(sums.rz) || !std::isfinite(sums.rr)) {
      reason = StopReason::NonFinite;
      break;
    }
    if (converged(rnorm, sums.rmax)) {
      const auto [trueNorm, trueMax] = trueResidual();
      haveTrue = true;
      trueNormLast = trueNorm;
      trueMaxLast = trueMax;
      if (converged(trueNorm, trueMax)) {
        reason = StopReason::Converged;
        break;
      }
      if (restarts >= 3 || it >= options.maxIterations) {
        reason = StopReason::Stagnated;
        break;
      }
      ++restarts;
      haveTrue = false;
      sums = restart();
      continue;
    }
    if (it >= options.maxIterations) break;
    if (!(sums.rz > 0.0)) {
      reason = StopReason::Breakdown;
      break;
    }
    exchangeGhosts(comm, s, p, bytes);
    multiply(s.rows, p, q);
    const double pq = reduce({p.head(n).dot(q)}, 1)[0];
    if (!std::isfinite(pq)) {
      reason = StopReason::NonFinite;
      break;
    }
    if (!(pq > 0.0)) {
      reason = StopReason::Breakdown;
      break;
    }
    const double alpha = sums.rz / pq, rzOld = sums.rz;
    x.head(n) += alpha * p.head(n);
    r -= alpha * q;
    pre.apply(r, z);
    const std::vector<double> g = reduce({r.dot(z), r.squaredNorm(), maxAbs(r)}, 2);
    sums = {g[0], g[1], g[2]};
    const double beta = sums.rz / rzOld;
    p.head(n) = z + beta * p.head(n);
    ++it;
  }
  stats.iterations = it;
  if (!haveTrue || reason != StopReason::Converged) {
    const auto [finalNorm, finalMax] = trueResidual();
    trueNormLast = finalNorm;
    trueMaxLast = finalMax;
  }
  stats.relativeResidual = trueNormLast / bnorm;
  stats.maxResidual = trueMaxLast;
  if (reason == StopReason::Converged && !std::isfinite(stats.relativeResidual)) reason = StopReason::NonFinite;
  return finish(reason);
}

}  // namespace duplexfit::detail
