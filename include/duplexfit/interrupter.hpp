// Interrupter: the one progress-and-cancellation type of every long-running operation (fit, fitSeparate,
// solveCg, polygonize, extractSurfaces, slice, estimateNormals, bilateralFilter, runPipeline, the jobs).
// After the idea of OpenVDB's util::NullInterrupter: the base class does nothing and never interrupts;
// derive from it and override what you need. Every operation takes it as its last argument
// (`Interrupter* = nullptr`); one that finds wasInterrupted() true throws duplexfit::Cancelled (solveCg
// instead returns with StopReason::Cancelled, as it reports every other stop in its SolveStats).
#pragma once

#include <string>

namespace duplexfit {

/// The stages of a fit, in the order they occur (per level: Constraints, Assembly, Solve, Residual).
enum class FitStage {
  Start,        ///< a fit of the separate baseline begins (FitEvent::message: "surface" or "offset j")
  Hierarchy,    ///< the octree and the winding-number tree are built
  Constraints,  ///< a level's surface, offset and off-surface points are chosen
  Assembly,     ///< a level's system is assembled
  Solve,        ///< a level's CG solve; iteration > 0 for each CG iteration
  Residual,     ///< the residual at the next level's centres is updated
  Correction,   ///< the offset-correction level (FitOptions::offsetCorrection)
  Errors,       ///< the final errors E_0, E_δ are measured
  Other         ///< a stage this version does not know
};

/// "start", "hierarchy", "constraints", "assembly", "solve", "residual", "correction", "errors", "other".
const char* fitStageName(FitStage stage) noexcept;

/// One progress event of a fit (solveCg sends Solve events with level 0; fit() fills in the level).
struct FitEvent {
  FitStage stage = FitStage::Other;
  int level = 0;         ///< k ≥ 1 inside a level, 0 outside
  int levels = 0;        ///< M (0 while not yet known)
  int iteration = 0;     ///< CG iteration (Solve; 0 at the start of the solve)
  double residual = 0.0; ///< CG relative residual (Solve, iteration > 0)
  std::string message;   ///< details ("1234 centres", "surface", ...), may be empty
};

class Interrupter {
 public:
  Interrupter() = default;
  virtual ~Interrupter() = default;
  Interrupter(const Interrupter&) = default;
  Interrupter& operator=(const Interrupter&) = default;

  /// An operation begins ("read", "normals", "denoise", "fit", "polygonize", "self-check", ...).
  virtual void start(const char* name = nullptr) { (void)name; }
  /// The operation begun by the last start() ends (not called when it throws).
  virtual void end() {}
  /// Polled during the operations; `percent` in [0, 100] when known, −1 otherwise. Return true to cancel:
  /// the operation then throws Cancelled.
  virtual bool wasInterrupted(int percent = -1) {
    (void)percent;
    return false;
  }
  /// A progress event of the fit (called before wasInterrupted for the same moment).
  virtual void fitEvent(const FitEvent& event) { (void)event; }
  /// One human-readable progress or warning line (what the CLI prints on stderr without --quiet).
  virtual void message(const std::string& line) { (void)line; }
};

/// The interrupter that does nothing (nullptr is accepted wherever an Interrupter* is taken, too).
using NullInterrupter = Interrupter;

}  // namespace duplexfit
