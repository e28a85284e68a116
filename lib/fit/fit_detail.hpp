// Helpers fit() shares with fitDistributed().
#pragma once

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "duplexfit/field.hpp"
#include "duplexfit/fit.hpp"
#include "duplexfit/interrupter.hpp"
#include "duplexfit/linalg.hpp"
#include "duplexfit/neighbors.hpp"
#include "fit/constraints.hpp"

namespace duplexfit::detail {

/// The fit's progress as a percentage of its work, for the callers' fractions and ETAs. A level's work is
/// taken as proportional to its centres; the levels not reached yet are estimated from the last one known
/// (4x a level, a surface's cells at half the size, capped at the input's size plus its offset points).
/// Within a level: constraints 0–30%, right-hand sides 30–45%, assembly 45–55%, the solve 55–100% (by
/// log(residual) / log(tolerance), the fraction of the residual's decades the CG has gained). A level
/// solved in units (the distributed fit's blocks, one after the other) spreads these stages over each unit
/// in turn: unit j of n covers [j/n, (j + 1)/n) of the level.
class FitWork {
 public:
  FitWork(int levels, Eigen::Index points, std::size_t offsets)
      : cap_(static_cast<double>(points) * static_cast<double>(2 + offsets)), known_(static_cast<std::size_t>(std::max(levels, 0)), -1.0) {}
  /// Level k (1-based) has `centres` unknowns.
  void setLevel(int k, Eigen::Index centres) {
    if (k >= 1 && static_cast<std::size_t>(k) <= known_.size()) known_[static_cast<std::size_t>(k - 1)] = static_cast<double>(centres);
  }
  /// Percent done at `within` ∈ [0, 1] of level k (never less than before); -1 outside the levels.
  int percent(int k, double within) const {
    if (k < 1 || known_.empty()) return -1;
    double last = 8.0, done = 0.0, total = 0.0;
    for (std::size_t i = 0; i < known_.size(); ++i) {
      const double w = known_[i] >= 0.0 ? known_[i] : std::min(cap_, 4.0 * last);
      last = w;
      total += w;
      if (static_cast<int>(i) + 1 < k) done += w;
      if (static_cast<int>(i) + 1 == k) done += std::clamp(within, 0.0, 1.0) * w;
    }
    if (!(total > 0.0)) return -1;
    // Monotone: a level larger than its estimate moves the total, never the percent back.
    shown_ = std::max(shown_, static_cast<int>(std::clamp(100.0 * done / total, 0.0, 100.0)));
    return shown_;
  }

 private:
  mutable int shown_ = 0;
  double cap_;
  std::vector<double> known_;
};

inline double stageStart(FitStage stage) {
  switch (stage) {
    case FitStage::Residual: return 0.30;
    case FitStage::Assembly: return 0.45;
    case FitStage::Solve: return 0.55;
    default: return 0.0;
  }
}

/// Where stage fraction `stage` ∈ [0, 1] of unit `unit` of `units` lies within its level (see FitWork).
inline double unitWithin(int unit, int units, double stage) {
  return units > 1 ? (unit + std::clamp(stage, 0.0, 1.0)) / units : stage;
}

/// Passes everything on to the fit's interrupter, with the level filled into the solver's events and the
/// solve's progress (log residual / log tolerance) as the fit's percent (of unit `unit` of `units`).
class LevelInterrupter final : public Interrupter {
 public:
  LevelInterrupter(Interrupter& to, int level, int levels, const FitWork& work, double tolerance, int unit = 0,
                   int units = 1)
      : to_(to), level_(level), levels_(levels), work_(work), tolerance_(tolerance), unit_(unit), units_(units) {}
  void start(const char* name) override { to_.start(name); }
  void end() override { to_.end(); }
  bool wasInterrupted(int percent) override {
    if (percent < 0) {
      double within = 0.0;
      if (residual_ > 0.0 && residual_ < 1.0 && tolerance_ > 0.0 && tolerance_ < 1.0) {
        within = std::log(residual_) / std::log(tolerance_);
      }
      const double stage = stageStart(FitStage::Solve) + (1.0 - stageStart(FitStage::Solve)) * std::clamp(within, 0.0, 1.0);
      percent = work_.percent(level_, unitWithin(unit_, units_, stage));
    }
    return to_.wasInterrupted(percent);
  }
  void fitEvent(const FitEvent& event) override {
    FitEvent e = event;
    e.level = level_;
    e.levels = levels_;
    if (e.stage == FitStage::Solve && e.iteration > 0) residual_ = e.residual;
    to_.fitEvent(e);
  }
  void message(const std::string& line) override { to_.message(line); }

 private:
  Interrupter& to_;
  int level_, levels_;
  const FitWork& work_;
  double tolerance_;
  int unit_, units_;
  double residual_ = 1.0;
};


/// The overshoot check's candidates (docs/method.md, "Overshoot between sparse samples"): q = p + s·D·ν for
/// each listed point p with a non-zero normal ν (inward) and each off-surface side s (−1 outside, +1 inside)
/// that `offSide` has (−1, 1 or 2 both), in the listed order within each side.
struct OvershootCandidates {
  Points q;
  std::vector<Eigen::Index> source;  ///< the row of q's point
  std::vector<double> toward;        ///< s
  std::vector<char> added;           ///< q joined the level in an earlier round
};
OvershootCandidates overshootCandidates(const Points& points, const Points& normals, const std::vector<Eigen::Index>& rows,
                                        double d, int offSide);
/// One round of the check with the finest level solved (in `evaluator`): the candidates not added yet where
/// s·f < D/2 and no point of `index` other than their own lies within D (the space there is known empty),
/// now marked added. `index` is over the points the candidates' rows refer to.
std::vector<std::size_t> overshootSites(const FieldEvaluator& evaluator, OvershootCandidates& c, const NeighborIndex& index,
                                        double d);

/// @throws InvalidArgument naming the first bad field of `o`.
void checkFitOptions(const FitOptions& o);
/// The typical sample spacing: the square root of the median point area.
double medianSpacing(const Eigen::VectorXd& areas);

/// The levels, counted from the finest, whose constraints get the crease-plane test (FitOptions::creaseTest).
/// Coarser levels' points are centroids of cells much larger than the gaps the test is for, and their
/// averaged normals make most of them look like crease points: there the test only took away constraints
/// the coarse fit used (pinion_53k, δ = 0.05: offset max 23% → 44% of δ with the test at every level, 23%
/// with it at the finest three). cube_24k needs the finest two (δ = 0.02: max 99% at the finest alone,
/// 55% with two, 50% with three).
constexpr int kCreaseTestLevels = 3;

/// The constraint options of level `level` of `levels` with support `sigma` (normalised units): the
/// offsets `deltas`, the off-surface side (−1 outside, 1 inside, 0 none, 2 both) and the fit's tolerances
/// and switches; the neighbour searches poll `interrupter` (may be null).
ConstraintOptions levelConstraintOptions(const FitOptions& options, const std::vector<double>& deltas, double sigma,
                                         int level, int levels, int offSurfaceSide, Interrupter* interrupter);
/// A level's solver options: options.solver with the absolute tolerance levelTolerance (when it has none)
/// and, below the finest level, the relative tolerance coarseTolerance.
SolverOptions levelSolverOptions(const FitOptions& options, bool finest);
/// The name of the level solves' preconditioner under `options` (FsaiPreconditioner::describe, BlockJacobiPreconditioner::describe or "jacobi").
std::string preconditionerName(const FitOptions& options);

/// Solves a level's system A w = b on the device as every level of a fit is solved: A and b uploaded in
/// options.precision, the preconditioner of options, PCG with levelSolverOptions. An empty b is a
/// converged solve with no weights. `monitor` (if not null) gets the solver's events. With `buffers`, A goes
/// into the device buffers held there where they are large enough (DeviceCsr::upload), and the uploaded A
/// is left there for the next level. With `assembled` (A on the device already, its host copy `a`: the device
/// assembly), that matrix is solved instead of an upload of `a`, and left in `buffers` likewise.
SolveStats solveLevelSystem(const Device& device, const CsrMatrix& a, const Eigen::VectorXd& b, const FitOptions& options,
                            bool finest, Eigen::VectorXd& weights, Interrupter* monitor = nullptr,
                            DeviceCsr* buffers = nullptr, DeviceCsr* assembled = nullptr);

/// Whether a fit under `options` assembles its level matrices on `device` (FitOptions::assembly).
bool assemblesOnDevice(const Device& device, const FitOptions& options);

}  // namespace duplexfit::detail
