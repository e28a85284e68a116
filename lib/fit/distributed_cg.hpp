// The exact mode of the distributed fit (docs/method.md, "Distributed fit"): one level's GLOBAL system
// Φ + λI solved by PCG over the ranks. Each rank holds the rows of the centres it owns (columns: its owned
// centres, then the ghost centres of other ranks within one support); the ghost values of the search
// direction (and of x at a restart) come from their owners every iteration by one alltoallv that carries
// only the entries a neighbour needs; dot products are reduced in rank order (the same doubles on every
// rank, run after run); the preconditioner is each rank's own: block Jacobi over its owned rows (the
// kind and block size of FitOptions), no coupling across ranks.
#pragma once

#include <cstdint>
#include <vector>

#include <Eigen/Core>

#include "duplexfit/communicator.hpp"
#include "duplexfit/fit.hpp"
#include "duplexfit/linalg.hpp"
#include "duplexfit/sparse.hpp"
#include "fit/hierarchy.hpp"

namespace duplexfit::detail {

/// This rank's rows of a level's global system and the exchange plan of its ghost entries.
struct DistributedSystem {
  CsrMatrix rows;                 ///< owned × (owned + ghosts), columns in local numbering
  std::size_t owned = 0;          ///< local columns [0, owned) are the owned centres
  std::size_t ghosts = 0;         ///< local columns [owned, owned + ghosts): other ranks' centres
  /// sendRows[r]: the owned rows whose values rank r needs, in the order it expects them.
  std::vector<std::vector<std::uint32_t>> sendRows;
  std::uint64_t setupBytes = 0;   ///< bytes received while building it (ghost centres, requests)
};

/// Builds this rank's rows of the system over the centres every rank owns (`owned`, this rank's, in its
/// order; the global numbering is the ranks' blocks in rank order): the ghost centres are fetched from
/// their owners (a superset by cells of side σ, then only those within σ of an owned centre kept).
/// Entry (i, j) = φ(‖c_i − c_j‖/σ) + λδ_ij, the values assembleWendland gives the same two centres.
DistributedSystem distributedSystem(Communicator& comm, const Points& owned, double sigma, double lambda,
                                    const HierarchyBox& box);

struct DistributedSolve {
  SolveStats stats;               ///< global figures, the same on every rank
  std::uint64_t bytes = 0;        ///< bytes received by the exchanges and reductions of the solve
  double preconditionerSeconds = 0.0;
};

/// Solves the global system for b (this rank's owned entries) from x = 0 by PCG with solveCg's rules:
/// stop when ‖r‖ ≤ tol·‖b‖ or max|r_i| ≤ absoluteTolerance on the recurrence residual, confirmed on the
/// true residual b − Ax (restarts from it at most 3 times, else Stagnated); tol = the options' relative
/// tolerance, or 1e-6 (double) / 1e-5 (float) by `precision`. Arithmetic in double on the host.
/// `blockSize` 1 is Jacobi. The weights of the owned centres land in x.
DistributedSolve solveDistributedCg(Communicator& comm, const DistributedSystem& system, const Eigen::VectorXd& b,
                                    Eigen::VectorXd& x, const SolverOptions& options, Precision precision,
                                    int blockSize);

}  // namespace duplexfit::detail
