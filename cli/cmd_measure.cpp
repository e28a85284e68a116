// `duplexfit measure`: Metro distances between two meshes (forward, backward, symmetric Hausdorff), or the
// accuracy of an offset mesh against its surface; `duplexfit check`: topology, orientation, genus and
// self-intersections of one mesh. Results go to stdout as a table or JSON; progress to stderr.
// The jobs, their reports and tables are the library's (jobs.hpp).
#include <iostream>
#include <sstream>
#include <string>

#include "commands.hpp"
#include "options.hpp"
#include "progress.hpp"
#include "duplexfit/jobs.hpp"

namespace duplexfit::cli {

const char* const kMeasureHelp =
    R"(  measure A B        Metro distance between two meshes: samples of A to B (forward), of B to A
                     (backward), max / mean / RMS and the symmetric Hausdorff distance, also relative
                     to the bounding-box diagonal of B
      --samples N      face samples per triangle on average, plus every vertex (default 10)
      --seed S         seed of the deterministic sampling (default 1)
      --json           machine-readable output
      --max-memory SIZE  memory budget (as fit's): the samples and the other mesh's tree
  measure O --offset-of S --delta D
                     accuracy of offset mesh O against surface mesh S for the signed offset D (positive
                     = inward, as in fit): dist(sample, S) and |dist − |D||, max / mean / RMS / p99,
                     relative to |D|, and the share of samples on the wrong side of S
  check MESH         closed, 2-manifold, oriented, outward, components, Euler characteristic, genus,
                     boundary loops, degenerate and float32-degenerate triangles, slivers (minimum angle
                     histogram) and self-intersecting triangle pairs
      --json           machine-readable output
      --strict         exit with status 4 unless the mesh is closed, manifold, oriented, outward, free
                       of self-intersections and of float32-degenerate triangles, with at most 0.1% slivers
      --sliver-angle DEG  a sliver's minimum angle is below DEG (default 1)
      --no-intersections  skip the self-intersection test
      --max-memory SIZE  memory budget (as fit's)
)";

namespace {

/// --samples and --seed, checked after parsing (checkMeasureOptions).
void addMeasureOptions(CLI::App& app, MeasureOptions& o, long& seed) {
  addNumber(app, "samples", o.samplesPerFace, "face samples per triangle on average, plus every vertex (default 10)");
  addInteger(app, "seed", seed, "seed of the deterministic sampling (default 1)");
}

void checkMeasureOptions(MeasureOptions& o, long seed) {
  if (!(o.samplesPerFace > 0.0)) {
    std::ostringstream got;
    got << o.samplesPerFace;
    throw UsageError("--samples must be a positive number of samples per triangle (got " + got.str() + ")");
  }
  if (o.samplesPerFace > 1e6) throw UsageError("--samples must be at most 1e6");
  if (seed < 0) throw UsageError("--seed must be a non-negative integer");
  o.seed = static_cast<std::uint64_t>(seed);
}

}  // namespace

int cmdMeasure(int argc, char** argv) {
  CLI::App app("Metro distance between two meshes, or the accuracy of an offset mesh", "measure");
  bool json = false, quiet = false;
  MeasureOptions options;
  long seed = 1;
  double delta = 0.0;
  std::string surface;
  std::vector<std::string> pos;
  app.add_option("MESHES", pos, "A B, or the offset mesh O with --offset-of");
  addMeasureOptions(app, options, seed);
  app.add_option("--offset-of", surface, "measure O as the offset of this surface mesh")->type_name("S");
  addNumber(app, "delta", delta, "the signed offset of --offset-of (positive = inward, as in fit)");
  addJson(app, json);
  addQuiet(app, quiet);
  addMaxMemory(app, options.limits);
  if (parse(app, argc, argv)) return 0;
  checkMeasureOptions(options, seed);
  StderrProgress progress(quiet);
  if (!surface.empty()) {
    if (pos.size() != 1) throw UsageError("usage: duplexfit measure OFFSET --offset-of SURFACE --delta D");
    if (delta == 0.0) throw UsageError("measure --offset-of needs --delta D (the signed offset, non-zero)");
    const OffsetJobResult r = runOffsetJob(pos[0], surface, delta, options, &progress);
    json ? writeOffsetJson(std::cout, r) : writeOffsetText(std::cout, r);
    return 0;
  }
  if (pos.size() != 2) throw UsageError("usage: duplexfit measure A B [--samples N] [--seed S] [--json]");
  const DistanceJobResult r = runDistanceJob(pos[0], pos[1], options, &progress);
  json ? writeDistanceJson(std::cout, r) : writeDistanceText(std::cout, r);
  return 0;
}

int cmdCheck(int argc, char** argv) {
  CLI::App app("closed, 2-manifold, oriented, outward, genus and self-intersections of a mesh", "check");
  bool json = false, strict = false, quiet = false;
  CheckOptions options;
  std::vector<std::string> pos;
  app.add_option("MESH", pos, "the mesh (PLY, OBJ or STL)");
  addJson(app, json);
  addQuiet(app, quiet);
  app.add_flag("--strict", strict, "exit with status 4 unless the mesh is closed, manifold, oriented, outward, "
                                   "free of self-intersections and float32-degenerate triangles, <= 0.1% slivers");
  app.add_flag_callback("--no-intersections", [&] { options.selfIntersections = false; },
                        "skip the self-intersection test");
  addNumber(app, "sliver-angle", options.sliverAngle, "a sliver's minimum angle is below DEG degrees (default 1)");
  addMaxMemory(app, options.limits);
  if (parse(app, argc, argv)) return 0;
  if (!(options.sliverAngle >= 0.0 && options.sliverAngle <= 60.0)) throw UsageError("--sliver-angle must be in [0, 60]");
  if (pos.size() != 1) throw UsageError("usage: duplexfit check MESH [--json] [--strict]");
  StderrProgress progress(quiet);
  const CheckJobResult r = runCheckJob(pos[0], options, &progress);
  json ? writeCheckJson(std::cout, r) : writeCheckText(std::cout, r);
  return strict && !r.check.valid() ? kNumerical : 0;
}

}  // namespace duplexfit::cli
