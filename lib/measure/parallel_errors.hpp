// Exceptions inside OpenMP regions of the measure module (private to the library): an exception must not
// leave a parallel region or task (that calls std::terminate), so each body runs through
// ParallelErrors::run, which keeps the first exception, and the caller rethrows it after the region.
#pragma once

#include <exception>
#include <utility>

namespace duplexfit::measure_detail {

class ParallelErrors {
 public:
  /// Runs body(); an exception it throws is kept (the first one only) instead of propagating.
  template <typename Body>
  void run(Body&& body) noexcept {
    try {
      std::forward<Body>(body)();
    } catch (...) {
      keep(std::current_exception());
    }
  }
  /// Whether an exception has been kept (safe to ask inside the region).
  bool failed() const noexcept {
    bool kept = false;
#pragma omp critical(duplexfit_measure_errors)
    kept = static_cast<bool>(error_);
    return kept;
  }
  /// Rethrows the kept exception, if any (call after the parallel region).
  void rethrow() const {
    if (error_) std::rethrow_exception(error_);
  }

 private:
  void keep(std::exception_ptr e) noexcept {
#pragma omp critical(duplexfit_measure_errors)
    {
      if (!error_) error_ = std::move(e);
    }
  }
  std::exception_ptr error_;
};

}  // namespace duplexfit::measure_detail
