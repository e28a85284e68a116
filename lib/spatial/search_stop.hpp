// The stop flag of a parallel batched search (private to the library; NeighborIndex and PointBvh): the
// calling thread polls the Interrupter when the search starts (before the parallel region), then, as the
// team's thread 0, before a block once kPollInterval has passed; once it says stop, every thread skips its
// remaining blocks and the search throws Cancelled. The first poll is not left to thread 0's first block:
// on a loaded machine the other threads can take every block of a short search before thread 0 takes one,
// and a stop asked before the search was then missed (a flaky "cancelled at the first poll" test).
#pragma once

#include <atomic>
#include <chrono>

#include "duplexfit/error.hpp"
#include "duplexfit/interrupter.hpp"

namespace duplexfit::detail {

class SearchStop {
 public:
  static constexpr std::chrono::milliseconds kPollInterval{20};

  /// Polls the interrupter once, on the calling thread (an exception from it propagates).
  explicit SearchStop(Interrupter* interrupter) : interrupter_(interrupter) {
    if (interrupter_ != nullptr && interrupter_->wasInterrupted()) stop_.store(true, std::memory_order_relaxed);
  }

  /// Called by thread `thread` of the team before each block: true when the block is to be skipped (the
  /// search was stopped). Only thread 0 polls; an exception from the interrupter propagates.
  bool skip(int thread) {
    if (stop_.load(std::memory_order_relaxed)) return true;
    if (interrupter_ == nullptr || thread != 0) return false;
    const auto now = std::chrono::steady_clock::now();
    if (now - lastPoll_ < kPollInterval) return false;
    lastPoll_ = now;
    if (!interrupter_->wasInterrupted()) return false;
    stop_.store(true, std::memory_order_relaxed);
    return true;
  }
  bool stopped() const noexcept { return stop_.load(std::memory_order_relaxed); }
  /// After the parallel region: @throws Cancelled when the search was stopped.
  void throwIfStopped() const {
    if (stop_.load()) throw Cancelled("cancelled during a neighbour search");
  }

 private:
  Interrupter* interrupter_;
  std::atomic<bool> stop_{false};
  std::chrono::steady_clock::time_point lastPoll_ = std::chrono::steady_clock::now();  // just polled
};

}  // namespace duplexfit::detail
