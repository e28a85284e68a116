// The Python module's Interrupter: forwards the library's progress to a Python callable
// progress(stage, fraction, message) and turns its answer (False, or an exception) and Ctrl-C into a
// cancellation. Long calls run with the GIL released; the callable is called with it re-acquired.
#pragma once

#include <iomanip>
#include <optional>
#include <sstream>
#include <string>
#include <utility>

#include <pybind11/pybind11.h>

#include "duplexfit/error.hpp"
#include "duplexfit/interrupter.hpp"

namespace duplexfit::python {

namespace py = pybind11;

/// The Python exception types of the module (set once at import).
struct ExceptionTypes {
  PyObject* error = nullptr;
  PyObject* invalidArgument = nullptr;
  PyObject* ioError = nullptr;
  PyObject* deviceError = nullptr;
  PyObject* buildError = nullptr;
  PyObject* cancelled = nullptr;
};
inline ExceptionTypes exceptionTypes;

/// Progress of one library call. Constructed and destroyed with the GIL held; the library calls the
/// overrides from the thread that released the GIL, so the C++ state needs no lock.
class PyProgress final : public Interrupter {
 public:
  /// `callback`: None or a callable; `stage`: the stage reported until the library names one.
  PyProgress(py::object callback, std::string stage) : callback_(std::move(callback)), stage_(std::move(stage)) {
    if (!callback_.is_none() && !PyCallable_Check(callback_.ptr())) {
      throw py::type_error("progress must be a callable progress(stage, fraction, message) or None");
    }
  }

  void start(const char* name) override {
    if (name != nullptr) stage_ = name;
  }
  void fitEvent(const FitEvent& event) override {
    if (event.stage != FitStage::Start) stage_ = fitStageName(event.stage);
    pending_ = describe(event);
  }
  void message(const std::string& line) override {
    if (cancel_ || callback_.is_none()) return;
    py::gil_scoped_acquire gil;
    call(py::none(), line);
  }
  bool wasInterrupted(int percent) override {
    if (cancel_) return true;
    py::gil_scoped_acquire gil;
    if (!callback_.is_none()) {
      call(percent >= 0 ? py::object(py::float_(percent / 100.0)) : py::object(py::none()), std::exchange(pending_, {}));
    }
    if (!cancel_ && PyErr_CheckSignals() != 0) {  // Ctrl-C while the GIL was released (main thread only)
      error_ = py::error_already_set();
      cancel_ = true;
    }
    return cancel_;
  }

  /// Raises (as a Python error) what the library's Cancelled `e` stands for: KeyboardInterrupt as it was,
  /// else duplexfit.Cancelled with the library's message and why, from the callback's exception if any.
  /// Call with the GIL held.
  [[noreturn]] void raiseCancelled(const Cancelled& e) {
    const std::string what = e.what();
    if (error_) {
      if (error_->matches(PyExc_KeyboardInterrupt)) {
        error_->restore();
        throw py::error_already_set();
      }
      py::raise_from(*error_, exceptionTypes.cancelled, (what + ": the progress callback raised an exception").c_str());
      throw py::error_already_set();
    }
    PyErr_SetString(exceptionTypes.cancelled,
                    (what + (cancel_ ? ": the progress callback returned False" : "")).c_str());
    throw py::error_already_set();
  }

 private:
  void call(py::object fraction, const std::string& text) {
    try {
      const py::object answer = callback_(stage_, std::move(fraction), text);
      if (answer.ptr() == Py_False) cancel_ = true;
    } catch (py::error_already_set& e) {
      error_ = std::move(e);
      cancel_ = true;
    }
  }

  /// Called without the GIL: no Python here.
  static std::string describe(const FitEvent& e) {
    std::string s;
    if (e.level > 0) s = "level " + std::to_string(e.level) + "/" + std::to_string(e.levels);
    if (e.stage == FitStage::Solve && e.iteration > 0) {
      std::ostringstream residual;
      residual << std::setprecision(3) << e.residual;
      return s + (s.empty() ? "" : ": ") + "CG iteration " + std::to_string(e.iteration) + ", residual " +
             residual.str();
    }
    if (!e.message.empty()) s += (s.empty() ? "" : ": ") + e.message;
    return s;
  }

  py::object callback_;
  std::string stage_;
  std::string pending_;  ///< the last fit event, reported with the next poll
  bool cancel_ = false;
  std::optional<py::error_already_set> error_;
};

/// Runs work(Interrupter*) with the GIL released and `callback` as its progress; a cancellation becomes
/// the Python exception of PyProgress::raiseCancelled. Call with the GIL held; work must not touch Python.
template <class Work>
auto withProgress(const py::object& callback, const char* stage, Work&& work) -> decltype(work(nullptr)) {
  PyProgress progress(callback, stage);
  try {
    py::gil_scoped_release release;
    return work(&progress);
  } catch (const Cancelled& e) {
    progress.raiseCancelled(e);
  }
}

}  // namespace duplexfit::python
