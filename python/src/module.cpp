// duplexfit._duplexfit: the native half of the Python package `duplexfit` (python/duplexfit/__init__.py
// gives fit() and run_pipeline() their keyword signatures and passes the options here as a dict).
// Every long call releases the GIL; progress and cancellation go through PyProgress (progress.hpp).
#include <algorithm>
#include <cstdint>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include "arrays.hpp"
#include "progress.hpp"
#include "duplexfit/device.hpp"
#include "duplexfit/error.hpp"
#include "duplexfit/field.hpp"
#include "duplexfit/fit.hpp"
#include "duplexfit/io.hpp"
#include "duplexfit/mesh.hpp"
#include "duplexfit/mesh_finish.hpp"
#include "duplexfit/pipeline.hpp"
#include "duplexfit/point_set.hpp"
#include "duplexfit/surfaces.hpp"
#include "duplexfit/version.hpp"

namespace duplexfit::python {
namespace {

// ---------------------------------------------------------------------------------------------
// Exceptions

PyObject* newException(py::module_& m, const char* name, const char* doc, py::tuple bases) {
  const std::string qualified = std::string("duplexfit.") + name;
  PyObject* type = PyErr_NewExceptionWithDoc(qualified.c_str(), doc, bases.ptr(), nullptr);
  if (type == nullptr) throw py::error_already_set();
  m.add_object(name, py::handle(type));  // the module keeps a reference; so do we (never released)
  return type;
}

void setError(PyObject* type, const std::exception& e) { PyErr_SetString(type, e.what()); }

void registerExceptions(py::module_& m) {
  ExceptionTypes& t = exceptionTypes;
  t.error = newException(m, "Error", "Base of every error the duplexfit library raises.",
                         py::make_tuple(py::handle(PyExc_RuntimeError)));
  t.invalidArgument = newException(m, "InvalidArgument",
                                   "Bad input data or options; the message names the argument, element or field.",
                                   py::make_tuple(py::handle(t.error), py::handle(PyExc_ValueError)));
  t.ioError = newException(m, "IoError",
                           "A file could not be read or written, or its content is malformed (the message names "
                           "the file and where).",
                           py::make_tuple(py::handle(t.error), py::handle(PyExc_OSError)));
  t.deviceError = newException(m, "DeviceError",
                               "An OpenCL call failed, no device matched a spec, or the device cannot do what was "
                               "asked. Attributes: status (the OpenCL status, 0 if none), call.",
                               py::make_tuple(py::handle(t.error)));
  t.buildError = newException(m, "BuildError", "An OpenCL program failed to build (the message holds the log).",
                              py::make_tuple(py::handle(t.deviceError)));
  t.cancelled = newException(m, "Cancelled",
                             "A long operation was cancelled: the progress callback returned False or raised (that "
                             "exception is the __cause__).",
                             py::make_tuple(py::handle(t.error)));
  py::register_exception_translator([](std::exception_ptr p) {
    const ExceptionTypes& types = exceptionTypes;
    try {
      if (p) std::rethrow_exception(p);
    } catch (const DeviceError& e) {
      PyObject* type = dynamic_cast<const BuildError*>(&e) != nullptr ? types.buildError : types.deviceError;
      py::object value = py::reinterpret_borrow<py::object>(type)(e.what());
      value.attr("status") = e.status();
      value.attr("call") = e.call();
      PyErr_SetObject(type, value.ptr());
    } catch (const InvalidArgument& e) {
      setError(types.invalidArgument, e);
    } catch (const IoError& e) {
      setError(types.ioError, e);
    } catch (const Cancelled& e) {
      setError(types.cancelled, e);
    } catch (const Error& e) {
      setError(types.error, e);
    }
  });
}

/// A path argument: str or os.PathLike (os.fspath), as UTF-8.
std::string pathArg(const py::object& path) {
  const py::object text = py::module_::import("os").attr("fspath")(path);
  if (!py::isinstance<py::str>(text)) throw py::type_error("a path must be a str or os.PathLike of str");
  return text.cast<std::string>();
}

// ---------------------------------------------------------------------------------------------
// Devices

/// The device of calls given device=None: DUPLEXFIT_DEVICE, else the first GPU, else the first CPU OpenCL
/// device, else the reference device. Opened once (with the GIL held) and never closed, so that no OpenCL
/// object outlives the runtime at exit.
const Device& defaultDevice() {
  static const Device* device = new Device(Device::openDefault());
  return *device;
}

/// The device a spec string opens, opened at its first use (with the GIL held) and then reused, so that
/// device="cpu" in repeated calls shares one context and its compiled programs; never closed either.
const Device& deviceForSpec(const std::string& spec) {
  static auto* opened = new std::map<std::string, Device>();
  auto it = opened->find(spec);
  if (it == opened->end()) it = opened->emplace(spec, Device::open(spec)).first;
  return it->second;
}

/// device=None, a Device, or a spec string.
Device resolveDevice(const py::object& device) {
  if (device.is_none()) return defaultDevice();
  if (py::isinstance<py::str>(device)) return deviceForSpec(device.cast<std::string>());
  if (py::isinstance<Device>(device)) return device.cast<Device>();
  throw py::type_error("device must be None, a duplexfit.Device or a device spec string such as \"cpu\" or \"ref\"");
}

bool sameDevice(const Device& a, const Device& b) { return a.impl() == b.impl(); }

std::string deviceRepr(const Device& d) {
  return "<duplexfit.Device " + d.info().spec + ": " + d.description() + ">";
}

// ---------------------------------------------------------------------------------------------
// Reports as dicts

py::dict topologyDict(const MeshTopology& t) {
  py::dict d;
  d["vertices"] = t.vertices;
  d["faces"] = t.faces;
  d["edges"] = t.edges;
  d["boundary_edges"] = t.boundaryEdges;
  d["non_manifold_edges"] = t.nonManifoldEdges;
  d["non_manifold_vertices"] = t.nonManifoldVertices;
  d["inconsistent_edges"] = t.inconsistentEdges;
  d["degenerate_faces"] = t.degenerateFaces;
  d["components"] = t.components;
  d["euler_characteristic"] = t.eulerCharacteristic;
  d["watertight"] = t.watertight();
  d["manifold"] = t.manifold();
  d["oriented"] = t.oriented();
  return d;
}

py::dict fitReportDict(const FitReport& r) {
  py::list levels;
  bool converged = true;
  for (const LevelReport& l : r.levelReports) {
    py::dict d;
    d["level"] = l.level;
    d["sigma"] = l.sigma;
    d["centres"] = l.centres;
    d["iterations"] = l.solve.iterations;
    d["converged"] = l.solve.converged;
    d["stop"] = stopReasonName(l.solve.reason);
    d["relative_residual"] = l.solve.relativeResidual;
    d["seconds"] = l.secondsConstraints + l.secondsAssembly + l.secondsSolve + l.secondsResidual;
    levels.append(d);
    converged = converged && (l.solve.iterations == 0 || l.solve.converged);
  }
  py::dict d;
  d["device"] = r.device;
  d["device_tuning"] = r.deviceTuning;
  d["precision"] = r.precision;
  d["preconditioner"] = r.preconditioner;
  d["assembly"] = r.assembly;
  d["input_points"] = r.inputPoints;
  d["duplicates_merged"] = r.duplicatesMerged;
  d["zero_normals"] = r.zeroNormals;
  d["offsets"] = r.offsets;
  d["off_surface_side"] = offSurfaceSideName(r.offSurfaceSide);
  d["sigma0"] = r.sigma0;
  d["sigma1"] = r.sigma1;
  d["levels"] = r.levels;
  d["stopped_early"] = r.stoppedEarly;
  d["e0"] = r.e0;
  d["e_delta"] = r.eDelta;
  d["converged"] = converged;
  d["level_reports"] = levels;
  d["seconds"] = r.secondsTotal;
  return d;
}

// ---------------------------------------------------------------------------------------------
// Options from the dicts that __init__.py builds

/// Reads the options out of a dict, and at the end rejects any key it did not read.
class OptionReader {
 public:
  explicit OptionReader(const py::dict& d) : dict_(d) {}
  template <class T>
  void get(const char* key, T& value) {
    used_.push_back(key);
    if (!dict_.contains(key)) return;
    const py::object v = dict_[key];
    if (v.is_none()) return;  // None: the library's default
    try {
      value = v.cast<T>();
    } catch (const py::cast_error&) {
      throw py::type_error(std::string(key) + ": cannot use " + py::repr(v).cast<std::string>());
    }
  }
  void finish() const {
    for (const auto& item : dict_) {
      const std::string key = item.first.cast<std::string>();
      if (std::find(used_.begin(), used_.end(), key) == used_.end()) {
        throw py::type_error("unexpected option '" + key + "'");
      }
    }
  }

 private:
  const py::dict& dict_;
  std::vector<std::string> used_;
};

void readFitOptions(OptionReader& r, FitOptions& o) {
  r.get("offsets", o.offsets);
  r.get("offsets_relative", o.offsetsRelative);
  r.get("normals_inward", o.normalsInward);
  r.get("validity_tolerance", o.validityTolerance);
  r.get("levels", o.levels);
  r.get("alpha", o.alpha);
  r.get("smoothing", o.smoothing);
  r.get("fit_tolerance", o.fitTolerance);
  r.get("merge_distance", o.mergeDistance);
  r.get("side_test", o.sideTest);
  r.get("crease_test", o.creaseTest);
  r.get("sign_anchors", o.signAnchors);
  r.get("medial_constraints", o.medialConstraints);
  r.get("overshoot_check", o.overshootCheck);
  r.get("offset_correction", o.offsetCorrection);
  r.get("drop_zero_normal_points", o.dropZeroNormalPoints);
  r.get("level_tolerance", o.levelTolerance);
  r.get("coarse_tolerance", o.coarseTolerance);
  r.get("max_iterations", o.solver.maxIterations);
  r.get("relative_tolerance", o.solver.relativeTolerance);
  std::string precision = precisionName(o.precision);
  r.get("precision", precision);
  o.precision = parsePrecision(precision.c_str());
  std::string preconditioner = preconditionerKindName(o.preconditioner);
  r.get("preconditioner", preconditioner);
  o.preconditioner = parsePreconditionerKind(preconditioner);
  std::string assembly = assemblyPlaceName(o.assembly);
  r.get("assembly", assembly);
  o.assembly = parseAssemblyPlace(assembly);
  r.get("fsai_threshold", o.fsaiThreshold);
}

py::dict fitDefaults() {
  const FitOptions o;
  py::dict d;
  d["offsets_relative"] = o.offsetsRelative;
  d["normals_inward"] = o.normalsInward;
  d["validity_tolerance"] = o.validityTolerance;
  d["alpha"] = o.alpha;
  d["smoothing"] = o.smoothing;
  d["fit_tolerance"] = o.fitTolerance;
  d["merge_distance"] = o.mergeDistance;
  d["side_test"] = o.sideTest;
  d["crease_test"] = o.creaseTest;
  d["sign_anchors"] = o.signAnchors;
  d["medial_constraints"] = o.medialConstraints;
  d["overshoot_check"] = o.overshootCheck;
  d["offset_correction"] = o.offsetCorrection;
  d["drop_zero_normal_points"] = o.dropZeroNormalPoints;
  d["level_tolerance"] = o.levelTolerance;
  d["coarse_tolerance"] = o.coarseTolerance;
  d["max_iterations"] = o.solver.maxIterations;
  d["relative_tolerance"] = o.solver.relativeTolerance;
  d["precision"] = precisionName(o.precision);
  d["preconditioner"] = preconditionerKindName(o.preconditioner);
  d["assembly"] = assemblyPlaceName(o.assembly);
  d["fsai_threshold"] = o.fsaiThreshold;
  return d;
}

// ---------------------------------------------------------------------------------------------
// Field

/// A fitted or loaded field, with the evaluator of its last device (built at the first evaluation unless
/// the fit handed one on). Evaluations of one Field are serialised (one OpenCL queue and scratch buffers).
struct PyField {
  ImplicitField field;
  Precision precision = Precision::Float;
  std::optional<Device> device;  ///< the device of `evaluator` (or of the fit)
  std::shared_ptr<const FieldEvaluator> evaluator;
  std::optional<FitReport> report;
  std::mutex mutex;

  /// Evaluates with the GIL released.
  FieldSamples evaluate(const py::object& deviceArg, const Points& queries, FieldDerivatives derivatives) {
    std::optional<Device> requested;
    if (!deviceArg.is_none()) requested = resolveDevice(deviceArg);
    else if (!currentDevice()) requested = defaultDevice();  // a loaded field's first evaluation
    py::gil_scoped_release release;
    std::lock_guard<std::mutex> lock(mutex);
    if (requested && (!device || !sameDevice(*device, *requested))) {
      evaluator.reset();
      device = *requested;
    }
    if (queries.rows() == 0) {
      FieldSamples empty;
      empty.values.resize(0);
      empty.gradients.resize(0, 3);
      return empty;
    }
    if (!evaluator) evaluator = std::make_shared<FieldEvaluator>(*device, field, precision);
    return evaluator->evaluate(queries, derivatives);
  }
  /// The device of the evaluator, if any (waits for a running evaluation).
  std::optional<Device> currentDevice() {
    py::gil_scoped_release release;
    std::lock_guard<std::mutex> lock(mutex);
    return device;
  }
};

std::string fieldRepr(const PyField& f) {
  std::ostringstream s;
  s << "<duplexfit.Field: " << f.field.levels().size() << " levels, " << f.field.centreCount() << " centres, offsets [";
  for (std::size_t j = 0; j < f.field.offsets().size(); ++j) s << (j ? ", " : "") << f.field.offsets()[j];
  s << "], " << precisionName(f.precision) << ">";
  return s.str();
}

std::shared_ptr<PyField> makeField(ImplicitField field, Precision precision) {
  auto f = std::make_shared<PyField>();
  f->field = std::move(field);
  f->precision = precision;
  return f;
}

py::tuple fieldMesh(PyField& self, double iso, std::optional<double> cell, std::optional<int> resolution,
                    std::optional<double> minComponent, bool clean, std::size_t maxTriangles, double maxError,
                    const py::object& deviceArg, const py::object& progress) {
  const std::optional<Device> current = deviceArg.is_none() ? self.currentDevice() : std::nullopt;
  const Device device = current ? *current : resolveDevice(deviceArg);
  SurfaceOptions surface;
  if (cell) surface.cell = *cell;
  if (resolution) surface.resolution = *resolution;
  surface.precision = self.precision;
  surface.finish.clean = clean;
  surface.finish.simplify.maxTriangles = maxTriangles;
  surface.finish.simplify.maxError = maxError;
  // As the fit pipeline cleans its meshes: the zero level keeps everything, an offset level drops slivers.
  const double fraction = minComponent ? *minComponent : defaultMinComponent(iso);
  MeshPipelineResult r = withProgress(progress, "mesh", [&](Interrupter* i) {
    return runMeshPipeline(device, self.field, iso, surface, fraction, i);
  });
  return fromMesh(r.mesh);
}

// ---------------------------------------------------------------------------------------------
// Fit and pipeline

PointSet toPointSet(const py::object& points, const py::object& normals) {
  Points p = toPoints(points, "points");
  Points n = toPoints(normals, "normals");
  if (p.rows() != n.rows()) {
    throw py::value_error("points and normals must have the same number of rows; got " + std::to_string(p.rows()) +
                          " points and " + std::to_string(n.rows()) + " normals");
  }
  return PointSet(std::move(p), std::move(n));
}

std::shared_ptr<PyField> fitArrays(const py::object& points, const py::object& normals, const py::dict& options,
                                   const py::object& deviceArg, const py::object& progress) {
  FitOptions o;
  bool mergeDuplicates = true;
  OptionReader reader(options);
  readFitOptions(reader, o);
  reader.get("merge_duplicates", mergeDuplicates);
  reader.finish();
  PointSet set = toPointSet(points, normals);
  const Device device = resolveDevice(deviceArg);
  FitResult r = withProgress(progress, "fit", [&](Interrupter* i) {
    const std::size_t merged = mergeDuplicates ? set.mergeDuplicates() : 0;
    checkFittable(set, "points");
    FitResult result = fit(device, set, o, i);
    result.report.duplicatesMerged = merged;  // as in runPipeline's report (inputPoints: those fitted)
    return result;
  });
  auto f = makeField(std::move(r.field), o.precision);
  f->device = device;
  f->evaluator = std::move(r.evaluator);
  f->report = std::move(r.report);
  return f;
}

/// A runPipeline result: the fields, the cleaned meshes, report.json as a dict, and write().
struct PyPipelineResult {
  std::shared_ptr<const PipelineResult> result;
  std::vector<std::shared_ptr<PyField>> fields;
};

PyPipelineResult runPipelineFrom(const py::object& source, const py::object& normals, const py::dict& options,
                                 const py::object& deviceArg, const py::object& progress) {
  PipelineOptions o;
  OptionReader reader(options);
  readFitOptions(reader, o.fit);
  reader.get("separate", o.separate);
  reader.get("estimate_normals", o.estimateNormals);
  reader.get("denoise", o.denoise);
  reader.get("denoise_when_noisy", o.denoiseWhenNoisy);
  reader.get("denoise_smoothing", o.denoiseSmoothing);
  reader.get("remove_outliers", o.removeOutliers);
  reader.get("cell", o.surface.cell);
  reader.get("resolution", o.surface.resolution);
  reader.get("clean", o.surface.finish.clean);
  reader.get("max_triangles", o.surface.finish.simplify.maxTriangles);
  reader.get("max_error", o.surface.finish.simplify.maxError);
  reader.finish();
  const Device device = resolveDevice(deviceArg);
  std::optional<std::string> path;
  std::optional<PointSet> set;
  if (py::isinstance<py::str>(source) || py::hasattr(source, "__fspath__")) {
    if (!normals.is_none()) throw py::value_error("normals are given with the points, not with a file");
    path = pathArg(source);
  } else if (normals.is_none()) {
    if (!o.estimateNormals) throw py::value_error("normals are needed unless estimate_normals=True");
    Points p = toPoints(source, "points");
    const Eigen::Index n = p.rows();
    set = PointSet(std::move(p), Points::Zero(n, 3));
  } else {
    set = toPointSet(source, normals);
  }
  auto result = std::make_shared<PipelineResult>(withProgress(progress, "pipeline", [&](Interrupter* i) {
    return path ? runPipeline(device, *path, o, i) : runPipeline(device, *set, o, i);
  }));
  PyPipelineResult out;
  for (const ImplicitField& f : result->fields) {
    out.fields.push_back(makeField(f, o.fit.precision));
    out.fields.back()->device = device;
  }
  if (!out.fields.empty()) out.fields.front()->report = result->report.fit;
  out.result = std::move(result);
  return out;
}

}  // namespace
}  // namespace duplexfit::python

PYBIND11_MODULE(_duplexfit, m) {
  using namespace duplexfit;
  using namespace duplexfit::python;
  namespace py = pybind11;

  m.doc() = "Native part of the duplexfit package (import duplexfit instead).";
  m.attr("__version__") = DUPLEXFIT_VERSION_STRING;
  registerExceptions(m);

  // --- devices
  py::class_<DeviceInfo>(m, "DeviceInfo", "What a compute device is (duplexfit.devices()).")
      .def_readonly("spec", &DeviceInfo::spec, "opens this device again: Device(spec)")
      .def_readonly("platform", &DeviceInfo::platform)
      .def_readonly("name", &DeviceInfo::name)
      .def_readonly("vendor", &DeviceInfo::vendor)
      .def_property_readonly("type", [](const DeviceInfo& d) { return deviceTypeName(d.type); },
                             "'cpu', 'gpu', 'accelerator' or 'other'")
      .def_readonly("compute_units", &DeviceInfo::computeUnits)
      .def_readonly("global_mem_bytes", &DeviceInfo::globalMemBytes)
      .def_readonly("max_alloc_bytes", &DeviceInfo::maxAllocBytes)
      .def_readonly("fp64", &DeviceInfo::fp64)
      .def_readonly("driver_version", &DeviceInfo::driverVersion)
      .def_readonly("device_version", &DeviceInfo::deviceVersion)
      .def_readonly("opencl_c_version", &DeviceInfo::openclCVersion)
      .def("__repr__", [](const DeviceInfo& d) {
        return "<duplexfit.DeviceInfo " + d.spec + ": " + d.name + " (" + d.platform + ", " + deviceTypeName(d.type) +
               ")>";
      });

  m.def(
      "devices",
      [] {
        std::vector<DeviceInfo> all = Device::enumerate();
        all.push_back(Device::reference().info());
        return all;
      },
      "Every OpenCL device of every platform, then the reference device (spec 'ref').");

  py::class_<Device>(m, "Device",
                     "A compute device. Device() opens DUPLEXFIT_DEVICE or the default (first GPU, else first CPU "
                     "OpenCL device, else the reference device); Device(spec) opens 'ref', 'cpu', 'gpu', "
                     "'accelerator', 'P:D' (as listed by devices()) or the first device whose name, platform or "
                     "vendor contains spec.")
      .def(py::init([](const std::optional<std::string>& spec, bool allowFp64, std::uint64_t maxAllocBytes) {
             DeviceOptions options;
             options.allowFp64 = allowFp64;
             options.maxAllocBytes = maxAllocBytes;
             return spec ? Device::open(*spec, options) : Device::openDefault(options);
           }),
           py::arg("spec") = py::none(), py::kw_only(), py::arg("allow_fp64") = true,
           py::arg("max_alloc_bytes") = 0)
      .def_static("reference", &Device::reference, "The plain C++ reference device (always available).")
      .def_static("default", &defaultDevice, "The device that calls with device=None use (opened once).")
      .def_property_readonly("spec", [](const Device& d) { return d.info().spec; })
      .def_property_readonly("name", [](const Device& d) { return d.info().name; })
      .def_property_readonly("platform", [](const Device& d) { return d.info().platform; })
      .def_property_readonly("type", [](const Device& d) { return deviceTypeName(d.info().type); })
      .def_property_readonly("info", [](const Device& d) { return d.info(); })
      .def_property_readonly("is_reference", &Device::isReference)
      .def_property_readonly("supports_double", &Device::supportsDouble)
      .def_property_readonly("description", &Device::description)
      .def(
          "compile_kernels",
          [](const Device& d, const std::string& precision) {
            const Precision p = parsePrecision(precision.c_str());
            py::gil_scoped_release release;
            d.compileKernels(p);
          },
          py::arg("precision") = "float", "Builds every OpenCL program for the precision now.")
      .def(
          "__eq__", [](const Device& a, const Device& b) { return sameDevice(a, b); }, py::is_operator())
      .def("__hash__", [](const Device& d) { return std::hash<const void*>()(d.impl()); })
      .def("__repr__", &deviceRepr);

  // --- field
  py::class_<PyField, std::shared_ptr<PyField>>(
      m, "Field",
      "A fitted implicit field f: positive inside the solid, about the signed distance near the surface; the "
      "surface is {f = 0} and each offset surface {f = delta} (delta > 0 inward). Evaluation runs on the fit's "
      "device (or the one given) in the fit's precision.")
      .def(
          "value",
          [](PyField& f, const py::object& points, const py::object& device) {
            const Points q = toPoints(points, "points");
            return fromVector(f.evaluate(device, q, FieldDerivatives::None).values);
          },
          py::arg("points"), py::kw_only(), py::arg("device") = py::none(), "f at (M, 3) points: an (M,) array.")
      .def(
          "__call__",
          [](PyField& f, const py::object& points) {
            return fromVector(f.evaluate(py::none(), toPoints(points, "points"), FieldDerivatives::None).values);
          },
          py::arg("points"), "The same as value(points).")
      .def(
          "gradient",
          [](PyField& f, const py::object& points, const py::object& device) {
            const Points q = toPoints(points, "points");
            return fromPoints(f.evaluate(device, q, FieldDerivatives::Gradient).gradients);
          },
          py::arg("points"), py::kw_only(), py::arg("device") = py::none(),
          "The gradient of f at (M, 3) points: an (M, 3) array (it points into the solid).")
      .def(
          "value_and_gradient",
          [](PyField& f, const py::object& points, const py::object& device) {
            const Points q = toPoints(points, "points");
            const FieldSamples s = f.evaluate(device, q, FieldDerivatives::Gradient);
            return py::make_tuple(fromVector(s.values), fromPoints(s.gradients));
          },
          py::arg("points"), py::kw_only(), py::arg("device") = py::none(),
          "(values (M,), gradients (M, 3)) in one evaluation.")
      .def("mesh", &fieldMesh, py::arg("iso") = 0.0, py::kw_only(), py::arg("cell") = py::none(),
           py::arg("resolution") = py::none(), py::arg("min_component") = py::none(), py::arg("clean") = true,
           py::arg("max_triangles") = 0, py::arg("max_error") = 0.0, py::arg("device") = py::none(),
           py::arg("progress") = py::none(),
           "The level set {f = iso} as (vertices (V, 3) float64, faces (F, 3) int32), outward oriented, as "
           "`duplexfit mesh` makes it: marching tetrahedra on a grid of `cell` (default sigma_M/2, 128 to 512 "
           "cells along the longest side) or `resolution` cells, components below min_component of the area "
           "dropped (default: none for iso 0, 0.001 for an offset, as the fit pipeline), then cleaned and, with "
           "max_triangles or max_error, simplified (needs meshoptimizer in the build).")
      .def(
          "save",
          [](const PyField& f, const py::object& pathObject) {
            const std::string path = pathArg(pathObject);
            py::gil_scoped_release release;
            f.field.save(path);
          },
          py::arg("path"), "Writes the field file (.dpxf, docs/field-format.md) atomically.")
      .def_property_readonly(
          "bounds",
          [](const PyField& f) {
            return py::make_tuple(fromVector3(f.field.bounds().min()), fromVector3(f.field.bounds().max()));
          },
          "(min, max) corners of the input points' bounding box.")
      .def_property_readonly(
          "offsets", [](const PyField& f) { return f.field.offsets(); }, "The fitted offsets delta (input units).")
      .def_property_readonly(
          "levels", [](const PyField& f) { return f.field.levels().size(); }, "Number of levels M.")
      .def_property_readonly(
          "sigmas",
          [](const PyField& f) {
            std::vector<double> s;
            for (const FieldLevel& l : f.field.levels()) s.push_back(l.sigma / f.field.normalization().scale);
            return s;
          },
          "Support radius of each level, coarsest first (input units).")
      .def_property_readonly(
          "centres", [](const PyField& f) { return f.field.centreCount(); }, "Number of RBF centres.")
      .def_property_readonly(
          "precision", [](const PyField& f) { return precisionName(f.precision); },
          "Arithmetic of the evaluations: 'float' or 'double'.")
      .def_property_readonly(
          "device", [](PyField& f) { return f.currentDevice(); },
          "The device evaluations use (None until the first one for a loaded field).")
      .def_property_readonly(
          "report",
          [](const PyField& f) { return f.report ? py::object(fitReportDict(*f.report)) : py::object(py::none()); },
          "The fit's report as a dict (levels, sigmas, CG iterations, e0, e_delta, seconds), None when loaded.")
      .def("__repr__", &fieldRepr);

  m.def(
      "load_field",
      [](const py::object& pathObject, const std::string& precision) {
        const std::string path = pathArg(pathObject);
        const Precision p = parsePrecision(precision.c_str());
        std::optional<ImplicitField> field;
        {
          py::gil_scoped_release release;
          field = ImplicitField::load(path);
        }
        return makeField(std::move(*field), p);
      },
      py::arg("path"), py::arg("precision") = "float", "Reads a field file written by Field.save or duplexfit fit.");

  m.def("_fit_defaults", &fitDefaults, "FitOptions' defaults, for the signature of duplexfit.fit.");
  m.def("_fit", &fitArrays, py::arg("points"), py::arg("normals"), py::arg("options"), py::arg("device"),
        py::arg("progress"));

  // --- pipeline
  py::class_<PyPipelineResult>(m, "PipelineResult",
                               "The whole fit job: fields, cleaned meshes (zero level first, then one per offset) and "
                               "the report; write(out_dir) writes what `duplexfit fit -o` writes.")
      .def_property_readonly("field", [](const PyPipelineResult& r) { return r.fields.front(); },
                             "The (first) fitted field.")
      .def_property_readonly("fields", [](const PyPipelineResult& r) { return r.fields; })
      .def_property_readonly(
          "meshes",
          [](const PyPipelineResult& r) {
            py::list meshes;
            for (const PipelineSurface& s : r.result->surfaces) meshes.append(fromMesh(s.mesh));
            return meshes;
          },
          "[(vertices, faces)] of the zero level, then of each offset.")
      .def_property_readonly(
          "surfaces",
          [](const PyPipelineResult& r) {
            py::list surfaces;
            for (const PipelineSurface& s : r.result->surfaces) {
              py::dict d;
              d["offset"] = s.offset;
              d["iso"] = s.iso;
              d["field"] = s.field;
              d["vertices"] = fromPoints(s.mesh.vertices);
              d["faces"] = fromFaces(s.mesh.faces);
              d["topology"] = topologyDict(s.topology);
              d["float32_degenerate"] = s.quality.float32DegenerateFaces;
              d["slivers"] = s.quality.slivers;
              d["sound"] = s.sound();
              surfaces.append(d);
            }
            return surfaces;
          },
          "One dict per surface: offset, iso, field (index), vertices, faces, topology, float32_degenerate, "
          "slivers, sound (what `fit --strict` asks: closed, oriented, manifold, no crossing left, what `check` "
          "asks of the triangles).")
      .def_property_readonly(
          "report",
          [](const PyPipelineResult& r) {
            std::ostringstream json;
            writePipelineReport(json, *r.result);
            return py::module_::import("json").attr("loads")(json.str());
          },
          "report.json's content as a dict.")
      .def_property_readonly("converged", [](const PyPipelineResult& r) { return r.result->report.converged(); })
      .def(
          "write",
          [](const PyPipelineResult& r, const py::object& outDirObject, const std::string& meshFormat) {
            const std::string outDir = pathArg(outDirObject);
            py::gil_scoped_release release;
            writePipelineOutputs(*r.result, outDir, meshFormat);
          },
          py::arg("out_dir"), py::arg("mesh_format") = "ply",
          "Writes zero.EXT, offsetJ.EXT, field.dpxf and report.json into out_dir (atomically).");
  m.def("_run_pipeline", &runPipelineFrom, py::arg("source"), py::arg("normals"), py::arg("options"),
        py::arg("device"), py::arg("progress"));

  // --- files and meshes
  m.def(
      "read_point_cloud",
      [](const py::object& pathObject, bool requireNormals) {
        const std::string path = pathArg(pathObject);
        PointReadOptions options;
        options.requireNormals = requireNormals;
        std::optional<PointSet> set;
        {
          py::gil_scoped_release release;
          set = readPointCloud(path, options);
        }
        return py::make_tuple(fromPoints(set->positions()), fromPoints(set->normals()));
      },
      py::arg("path"), py::kw_only(), py::arg("require_normals") = true,
      "(points (N, 3), normals (N, 3)) of a PLY or XYZ cloud; normals unit length (zero where missing).");
  m.def(
      "write_point_cloud",
      [](const py::object& pathObject, const py::object& points, const py::object& normals) {
        const std::string path = pathArg(pathObject);
        const PointSet set = toPointSet(points, normals);
        py::gil_scoped_release release;
        writePointCloud(path, set);
      },
      py::arg("path"), py::arg("points"), py::arg("normals"), "Writes binary PLY with float x y z nx ny nz.");
  m.def(
      "write_mesh",
      [](const py::object& pathObject, const py::object& vertices, const py::object& faces) {
        const std::string path = pathArg(pathObject);
        const Mesh mesh = toMesh(vertices, faces);
        py::gil_scoped_release release;
        writeMesh(path, mesh);
      },
      py::arg("path"), py::arg("vertices"), py::arg("faces"),
      "Writes a mesh atomically: .ply (binary), .obj or .stl by the extension.");
  m.def(
      "read_mesh",
      [](const py::object& pathObject) {
        const std::string path = pathArg(pathObject);
        std::optional<Mesh> mesh;
        {
          py::gil_scoped_release release;
          mesh = readMesh(path);
        }
        return fromMesh(*mesh);
      },
      py::arg("path"), "(vertices, faces) of a PLY, OBJ or STL mesh.");
  m.def(
      "mesh_topology", [](const py::object& vertices, const py::object& faces) {
        return topologyDict(analyzeTopology(toMesh(vertices, faces)));
      },
      py::arg("vertices"), py::arg("faces"),
      "Topology of a mesh as a dict: counts, components, euler_characteristic, watertight, manifold, oriented.");
  m.def("simplification_available", &simplificationAvailable,
        "Whether this build has meshoptimizer (Field.mesh's max_triangles and max_error).");
}
