// Consumer check: links the installed duplexfit, assembles a small Wendland system and solves it on
// the reference device and on the default device, then runs the whole fit-and-extract pipeline on a
// sphere and writes its outputs into the folder argv[1]. Exit status 0 only if the solves converge and
// agree, the pipeline gives a closed surface and offset surface, and the check job (jobs.hpp) finds the
// written surface a valid closed mesh.
#include <duplexfit/device.hpp>
#include <duplexfit/error.hpp>
#include <duplexfit/interrupter.hpp>
#include <duplexfit/jobs.hpp>
#include <duplexfit/linalg.hpp>
#include <duplexfit/pipeline.hpp>
#include <duplexfit/wendland.hpp>

#include <cmath>
#include <filesystem>
#include <iostream>
#include <sstream>
#include <string>

namespace {

/// Counts the fit's progress events (an Interrupter that never interrupts).
class CountingInterrupter : public duplexfit::Interrupter {
 public:
  void fitEvent(const duplexfit::FitEvent& e) override { solves += e.stage == duplexfit::FitStage::Solve ? 1 : 0; }
  int solves = 0;
};

/// The whole pipeline on `cloud`: a fit with one inward offset, both surfaces extracted and self-checked.
int pipeline(const duplexfit::PointSet& cloud, const std::string& outDir) {
  using namespace duplexfit;
  CountingInterrupter progress;
  // --- the README's five lines ---
  PipelineOptions options;
  options.fit.offsets = {0.05};
  options.surface.resolution = 40;
  const PipelineResult result = runPipeline(Device::openDefault(), cloud, options, &progress);
  writePipelineOutputs(result, outDir);  // zero.ply, offset1.ply, field.dpxf, report.json
  // ---
  for (const PipelineSurface& s : result.surfaces) {
    std::cout << "surface at offset " << s.offset << ": " << s.topology.faces << " triangles, "
              << s.topology.components << " component(s)\n";
    if (!s.topology.watertight() || s.topology.components != 1) return 1;
  }
  std::cout << progress.solves << " solve events, self-check " << (result.report.selfCheck.ok() ? "ok" : "FAILED")
            << "\n";
  const bool written = std::filesystem::exists(std::filesystem::path(outDir) / "report.json");
  // `duplexfit check` as a library call on the written surface.
  const CheckJobResult check = runCheckJob((std::filesystem::path(outDir) / "zero.ply").string());
  std::ostringstream checkJson;
  writeCheckJson(checkJson, check);
  std::cout << "check: " << (check.check.valid() ? "valid" : "NOT valid") << ", genus " << check.check.genus << "\n";
  const bool checked = check.check.valid() && checkJson.str().find("\"valid\": true") != std::string::npos;
  return result.surfaces.size() == 2 && progress.solves > 0 && result.report.selfCheck.ok() && written && checked
             ? 0
             : 1;
}

/// Cancels at the first CG solve: runPipeline must throw Cancelled.
class CancelAtSolve : public duplexfit::Interrupter {
 public:
  void fitEvent(const duplexfit::FitEvent& e) override { cancel = cancel || e.stage == duplexfit::FitStage::Solve; }
  bool wasInterrupted(int) override { return cancel; }
  bool cancel = false;
};

bool cancels(const duplexfit::PointSet& cloud) {
  CancelAtSolve cancel;
  duplexfit::PipelineOptions options;
  options.fit.offsets = {0.05};
  try {
    duplexfit::runPipeline(duplexfit::Device::openDefault(), cloud, options, &cancel);
  } catch (const duplexfit::Cancelled& e) {
    std::cout << "cancelled: " << e.what() << "\n";
    return true;
  }
  return false;
}

}  // namespace

int main(int argc, char** argv) {
  using namespace duplexfit;
  const int n = 400;
  Points centres(n, 3);
  for (int i = 0; i < n; ++i) {  // a Fibonacci sphere of radius 0.5
    const double z = 1.0 - (2.0 * i + 1.0) / n;
    const double r = std::sqrt(1.0 - z * z);
    const double phi = 2.399963229728653 * i;
    centres.row(i) << 0.5 * r * std::cos(phi), 0.5 * r * std::sin(phi), 0.5 * z;
  }
  const CsrMatrix a = assembleWendland(centres, 0.2);
  const Eigen::VectorXd b = Eigen::VectorXd::Ones(n);
  Eigen::VectorXd solutions[2];
  const Device devices[2] = {Device::reference(), Device::openDefault()};
  for (int k = 0; k < 2; ++k) {
    const DeviceCsr m = DeviceCsr::upload(devices[k], a, Precision::Float);
    const DeviceVector db = DeviceVector::upload(devices[k], b, Precision::Float);
    DeviceVector x(devices[k], n, Precision::Float);
    const SolveStats s = solveCg(m, db, x);
    std::cout << devices[k].description() << ": " << s.iterations << " iterations, residual "
              << s.relativeResidual << " (" << stopReasonName(s.reason) << ")\n";
    if (!s.converged) return 1;
    solutions[k] = x.download();
  }
  const double diff = (solutions[0] - solutions[1]).norm() / solutions[0].norm();
  std::cout << "relative difference " << diff << "\n";
  if (!(diff < 1e-3)) return 1;
  // The same sphere, with outward normals, through the pipeline.
  Points normals = centres / 0.5;
  const PointSet cloud(centres, normals);
  if (!cancels(cloud)) return 1;
  return pipeline(cloud, argc > 1 ? argv[1] : "consumer-out");
}
