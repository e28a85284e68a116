// `duplexfit slice`: a saved field in, the layers of a 3D print out: slices.cli (Common Layer Interface,
// ASCII), slices.svg, slices.json and optional PNG masks. Outputs are staged in a temporary folder inside
// the output folder and moved into place only when everything succeeded.
// The job (SliceJob, writeSliceOutputs) and slices.json are the library's (jobs.hpp).
#include <cmath>
#include <filesystem>
#include <iomanip>
#include <iostream>
#include <limits>
#include <string>

#include "commands.hpp"
#include "options.hpp"
#include "progress.hpp"
#include "duplexfit/jobs.hpp"

namespace duplexfit::cli {

const char* const kSliceHelp = R"(  slice FIELD        cut a saved field into print layers: contours of {f >= 0} (or of the shell between
                     the surface and its offset) as closed, oriented, nested loops; adaptive layer
                     thickness from the cusp height (docs/method.md §10) or uniform layers
      --cusp T         cusp height tau (adaptive slicing; required unless --layer)
      --min-layer A    thinnest layer (default tau/4)     --max-layer B   thickest layer (default 5 tau)
      --layer H        uniform layers of thickness H instead of adaptive ones
      --grid G         plane sampling step (default: largest side of the box / 200)
      --mode zero|shell  the solid (default) or the shell between f = 0 and f = delta
      --offset-index K which of the field's offsets bounds the shell (default 0, the first)
      --cusp-rule geometric|paper  convex/concave by the centre of curvature (default; keeps every
                       cusp within tau) or by the sign of the curvature alone (the paper's counts)
      --axis x|y|z     build direction (default z); plane axes (y,z), (z,x), (x,y)
      -o DIR           output folder: slices.cli, slices.svg, slices.json (default: current folder)
      --units U        millimetres per CLI unit (default 1: field units are mm)
      --svg-per-layer  svg/layer_00001.svg, ... instead of one slices.svg
      --png-xy PX      also masks/layer_00001.png, ...: white inside, pixel size PX
      --device SPEC, --precision float|double, --refine-steps N, --quiet, --json (summary on stdout)
)";
int cmdSlice(int argc, char** argv) {
  CLI::App app("cut a saved field into print layers", "slice");
  bool quiet = false, json = false, svgPerLayer = false, svg = false;
  DeviceOptions deviceOptions;
  SliceJobOptions job;
  SliceOptions& options = job.slice;
  std::string input, mode = "zero", rule = "geometric", axis = "z", output = ".";
  // Numbers: NaN marks "not given".
  const double nan = std::numeric_limits<double>::quiet_NaN();
  double units = 1.0, pixel = 0.0, cusp = nan, minLayer = nan, maxLayer = nan, layer = nan, grid = nan;
  app.add_option("FIELD", input, "a field file (.dpxf)");
  app.add_option("-o,--output", output, "output folder (default: current folder)")->type_name("DIR");
  addNumber(app, "cusp", cusp, "cusp height of the adaptive layers");
  addNumber(app, "min-layer", minLayer, "thinnest adaptive layer");
  addNumber(app, "max-layer", maxLayer, "thickest adaptive layer");
  addNumber(app, "layer", layer, "uniform layer thickness instead of --cusp");
  addNumber(app, "grid", grid, "contouring grid spacing");
  app.add_option("--mode", mode, "zero (the solid, default) or shell");
  app.add_option("--cusp-rule", rule, "the cusp-height rule (default geometric)");
  app.add_option("--axis", axis, "build direction x, y or z (default z)");
  addInteger(app, "offset-index", options.offsetIndex, "the offset of --mode shell (default 0)");
  addInteger(app, "refine-steps", options.refineSteps, "contour refinement steps (0..64)");
  addNumber(app, "units", units, "output units per input unit (default 1)");
  addNumber(app, "png-xy", pixel, "PNG masks with this pixel size");
  app.add_flag("--svg", svg, "slices.svg (always written; accepted for clarity)");
  app.add_flag("--svg-per-layer", svgPerLayer, "one SVG per layer as well");
  addDeviceOptions(app, deviceOptions);
  addQuiet(app, quiet);
  addJson(app, json);
  if (parse(app, argc, argv)) return 0;
  options.mode = parseSliceMode(mode);
  options.rule = parseCuspRule(rule);
  options.axis = parseAxis(axis);
  options.precision = deviceOptions.precision;
  const bool pngGiven = pixel != 0.0;
  const std::filesystem::path outDir = output;
  if (input.empty()) throw UsageError("slice needs a field file: duplexfit slice FIELD --cusp T -o DIR");
  if (std::isnan(layer) && std::isnan(cusp)) throw UsageError("slice needs --cusp T (adaptive) or --layer H (uniform)");
  if (!std::isnan(cusp) && !(cusp > 0.0)) throw UsageError("--cusp must be > 0 (got " + std::to_string(cusp) + ")");
  if (!std::isnan(layer) && !(layer > 0.0)) throw UsageError("--layer must be > 0 (got " + std::to_string(layer) + ")");
  if (!std::isnan(minLayer) && !(minLayer > 0.0)) throw UsageError("--min-layer must be > 0");
  if (!std::isnan(maxLayer) && !(maxLayer > 0.0)) throw UsageError("--max-layer must be > 0");
  if (!std::isnan(minLayer) && !std::isnan(maxLayer) && minLayer > maxLayer) {
    throw UsageError("--min-layer " + std::to_string(minLayer) + " exceeds --max-layer " + std::to_string(maxLayer));
  }
  if (!std::isnan(grid) && !(grid > 0.0)) throw UsageError("--grid must be > 0 (got " + std::to_string(grid) + ")");
  if (!(units > 0.0)) throw UsageError("--units must be > 0");
  if (pngGiven && !(pixel > 0.0)) throw UsageError("--png-xy must be > 0");
  if (options.refineSteps < 0 || options.refineSteps > 64) throw UsageError("--refine-steps must be in 0..64");
  options.cusp = std::isnan(cusp) ? 0.0 : cusp;
  options.layer = std::isnan(layer) ? 0.0 : layer;
  options.minLayer = std::isnan(minLayer) ? 0.0 : minLayer;
  options.maxLayer = std::isnan(maxLayer) ? 0.0 : maxLayer;
  options.grid = std::isnan(grid) ? 0.0 : grid;
  job.units = units;
  job.maskPixel = pixel;
  job.svgPerLayer = svgPerLayer;

  const ImplicitField field = ImplicitField::load(input);
  StderrProgress progress(quiet);
  const Device device = openDevice(deviceOptions.spec, progress);
  const SliceJob slicing(device, field, job, input);  // validates the options against the field
  StagedFolder staging(outDir);  // fails early, before slicing, if the folder is unusable
  const SliceJobResult result = slicing.run(&progress);
  const SliceOutputs written = writeSliceOutputs(result, staging);
  if (json) {
    std::cout << written.report;
    return 0;
  }
  const SliceResult& r = result.slices;
  const SliceStats s = sliceStats(r);
  std::cout << std::setprecision(5) << "slice " << input << ": " << r.layers.size() << " layers ("
            << sliceModeName(r.mode) << ", " << (r.adaptive ? "adaptive" : "uniform") << "), thickness "
            << s.thicknessMin << " to " << s.thicknessMax << " (mean " << s.thicknessMean << "), " << s.loops
            << " loops, " << r.vertices << " vertices, " << result.secondsSlice << " s\n  "
            << (outDir / "slices.cli").string() << ", " << (outDir / (svgPerLayer ? "svg/" : "slices.svg")).string()
            << ", " << (outDir / "slices.json").string() << (pngGiven ? ", " + (outDir / "masks/").string() : "")
            << "\n";
  return 0;
}

}  // namespace duplexfit::cli
