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
      --place plate|none  lowest layer's bottom at z = 0, centred on the plate (default), or model coordinates
      --scale S        output units per model unit (default 1)   --units mm|in|um  output unit ($$UNITS)
      --plate WxD      build plate size in output units (default: the part plus a margin)
      --svg-per-layer  svg/layer_00001.svg, ... instead of one slices.svg
      --png-xy PX      also masks/layer_00001.png, ... of the whole plate: white inside, pixel size PX
      --drain-hole X,Y,Z,R  (shell mode, repeatable) cut the drain holes of fit/mesh --shell (their mesh)
      --sl1 NAME.sl1   also an SLA print package in DIR (PrusaSlicer's SL1 zip: config.ini, prusaslicer.ini,
                       one PNG per layer at the display's resolution, thumbnails; needs libzip). Needs
                       --layer (in model units), millimetres (--units mm, --scale S) and a part that fits
                       the display, which is the plate
      --sl1-display WxD  display size in mm (default 120.96x68.04, the Original Prusa SL1)
      --sl1-pixels NXxNY  display pixels along x and y (default 2560x1440; square pixels)
      --sl1-orientation portrait|landscape  (default portrait)   --sl1-mirror x|y|xy|none  (default x)
      --exposure S     layer exposure (default 10 s)   --initial-exposure S  first layer (default 15 s)
      --fade-layers N  layers fading from the initial exposure to the exposure (3..20, default 10)
      --device SPEC, --precision float|double, --refine-steps N, --quiet, --json (summary on stdout)
      --max-memory SIZE  memory budget (as fit's): the layers' contours, a band of plane samples, one mask
)";
int cmdSlice(int argc, char** argv) {
  CLI::App app("cut a saved field into print layers", "slice");
  bool quiet = false, json = false, svgPerLayer = false, svg = false;
  DeviceOptions deviceOptions;
  SliceJobOptions job;
  SliceOptions& options = job.slice;
  std::vector<std::string> holes;
  std::string input, mode = "zero", rule = "geometric", axis = "z", output = ".", place = "plate", plate;
  const double nan = std::numeric_limits<double>::quiet_NaN();  // numbers: NaN marks "not given"
  double pixel = nan, cusp = nan, minLayer = nan, maxLayer = nan, layer = nan, grid = nan;
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
  app.add_option("--place", place, "plate (default) or none");
  addNumber(app, "scale", job.placement.scale, "output units per model unit (default 1)");
  app.add_option("--units", job.unitsName, "mm (default), in or um");
  app.add_option("--plate", plate, "build plate WxD in output units")->type_name("WxD");
  addNumber(app, "png-xy", pixel, "PNG masks of the plate, pixel size in output units");
  app.add_flag("--svg", svg, "slices.svg (always written; accepted for clarity)");
  app.add_flag("--svg-per-layer", svgPerLayer, "one SVG per layer as well");
  addDrainHoles(app, holes);
  addMaxMemory(app, options.limits);
  std::string sl1Display, sl1Pixels, sl1Orientation, sl1Mirror;
  double exposure = nan, initialExposure = nan;
  int fadeLayers = 0;
  app.add_option("--sl1", job.sl1, "SLA package NAME.sl1 in the output folder")->type_name("NAME");
  app.add_option("--sl1-display", sl1Display, "display size WxD in mm")->type_name("WxD");
  app.add_option("--sl1-pixels", sl1Pixels, "display pixels NXxNY")->type_name("NXxNY");
  app.add_option("--sl1-orientation", sl1Orientation, "portrait (default) or landscape");
  app.add_option("--sl1-mirror", sl1Mirror, "x (default), y, xy or none");
  addNumber(app, "exposure", exposure, "layer exposure time in seconds (SL1)");
  addNumber(app, "initial-exposure", initialExposure, "first layer exposure time in seconds (SL1)");
  addInteger(app, "fade-layers", fadeLayers, "layers fading to the exposure time (SL1)");
  addDeviceOptions(app, deviceOptions);
  addQuiet(app, quiet);
  addJson(app, json);
  if (parse(app, argc, argv)) return 0;
  job.drainHoles = parseDrainHoles(holes);
  options.mode = parseSliceMode(mode);
  options.rule = parseCuspRule(rule);
  options.axis = parseAxis(axis);
  options.precision = deviceOptions.precision;
  const bool pngGiven = !std::isnan(pixel);
  checkOutputFolderName(output, "slice");
  const std::filesystem::path outDir = output;
  if (input.empty()) throw UsageError("slice needs a field file: duplexfit slice FIELD --cusp T -o DIR");
  if (std::isnan(layer) && std::isnan(cusp)) throw UsageError("slice needs --cusp T (adaptive) or --layer H (uniform)");
  auto positive = [](double v, const char* name) {  // NaN: not given
    if (!std::isnan(v) && !(v > 0.0)) throw UsageError(std::string(name) + " must be > 0 (got " + std::to_string(v) + ")");
  };
  positive(cusp, "--cusp"), positive(layer, "--layer"), positive(minLayer, "--min-layer"), positive(pixel, "--png-xy");
  positive(maxLayer, "--max-layer"), positive(grid, "--grid"), positive(job.placement.scale, "--scale");
  if (!std::isnan(minLayer) && !std::isnan(maxLayer) && minLayer > maxLayer) {
    throw UsageError("--min-layer " + std::to_string(minLayer) + " exceeds --max-layer " + std::to_string(maxLayer));
  }
  job.placement.place = parseSlicePlace(place);
  if (!plate.empty()) job.placement.plate = parsePlateSize(plate);
  if (options.refineSteps < 0 || options.refineSteps > 64) throw UsageError("--refine-steps must be in 0..64");
  auto given = [](double v) { return std::isnan(v) ? 0.0 : v; };
  options.cusp = given(cusp), options.layer = given(layer), options.minLayer = given(minLayer);
  options.maxLayer = given(maxLayer), options.grid = given(grid);
  job.units = lengthUnitMillimetres(job.unitsName);
  job.maskPixel = given(pixel);
  job.svgPerLayer = svgPerLayer;
  const bool sl1Settings = !sl1Display.empty() || !sl1Pixels.empty() || !sl1Orientation.empty() ||
                           !sl1Mirror.empty() || !std::isnan(exposure) || !std::isnan(initialExposure) || app.count("--fade-layers") > 0;
  if (sl1Settings && job.sl1.empty()) {
    throw UsageError("--sl1-display, --sl1-pixels, --sl1-orientation, --sl1-mirror, --exposure, --initial-exposure "
                     "and --fade-layers set up the SLA package: give it a name with --sl1 NAME.sl1");
  }
  Sl1Options& sl1 = job.sl1Options;
  if (!sl1Display.empty()) {
    try {
      const Eigen::Vector2d d = parsePlateSize(sl1Display);
      sl1.printer.displayWidth = d.x(), sl1.printer.displayHeight = d.y();
    } catch (const InvalidArgument&) {
      throw UsageError("--sl1-display '" + sl1Display + "' is not WxD in mm with two positive numbers (e.g. 120.96x68.04)");
    }
  }
  if (!sl1Pixels.empty()) {
    const auto sep = sl1Pixels.find_first_of("xX,");
    auto whole = [](const std::string& t, int& out) {
      if (t.empty() || t.size() > 6 || t.find_first_not_of("0123456789") != std::string::npos) return false;
      out = std::stoi(t);
      return out > 0;
    };
    if (sep == std::string::npos || !whole(sl1Pixels.substr(0, sep), sl1.printer.pixelsX) ||
        !whole(sl1Pixels.substr(sep + 1), sl1.printer.pixelsY)) {
      throw UsageError("--sl1-pixels '" + sl1Pixels + "' is not NXxNY with two positive whole numbers (e.g. 2560x1440)");
    }
  }
  if (!sl1Orientation.empty()) sl1.printer.orientation = parseSl1Orientation(sl1Orientation);
  if (!sl1Mirror.empty()) {
    if (sl1Mirror != "x" && sl1Mirror != "y" && sl1Mirror != "xy" && sl1Mirror != "none") {
      throw UsageError("--sl1-mirror '" + sl1Mirror + "' is not x, y, xy or none");
    }
    sl1.printer.mirrorX = sl1Mirror == "x" || sl1Mirror == "xy";
    sl1.printer.mirrorY = sl1Mirror == "y" || sl1Mirror == "xy";
  }
  positive(exposure, "--exposure"), positive(initialExposure, "--initial-exposure");
  if (!std::isnan(exposure)) sl1.exposure = exposure;
  if (!std::isnan(initialExposure)) sl1.initialExposure = initialExposure;
  if (app.count("--fade-layers") > 0) sl1.fadeLayers = fadeLayers;
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
  const SliceResult& r = result.placed;
  const SliceStats s = sliceStats(r);
  std::cout << std::setprecision(5) << "slice " << input << ": " << r.layers.size() << " layers ("
            << sliceModeName(r.mode) << ", " << (r.adaptive ? "adaptive" : "uniform") << "), thickness "
            << s.thicknessMin << " to " << s.thicknessMax << " (mean " << s.thicknessMean << "), " << s.loops
            << " loops, " << r.vertices << " vertices, " << result.secondsSlice << " s; " << job.unitsName
            << ", plate " << result.placement.plate.sizes().x() << " x " << result.placement.plate.sizes().y() << "\n  "
            << (outDir / "slices.cli").string() << ", " << (outDir / (svgPerLayer ? "svg/" : "slices.svg")).string()
            << ", " << (outDir / "slices.json").string() << (pngGiven ? ", " + (outDir / "masks/").string() : "")
            << (written.sl1 ? ", " + (outDir / job.sl1).string() : "") << "\n";
  if (written.sl1) {
    const Sl1Summary& p = *written.sl1;
    std::cout << "  SL1 package: " << p.layers << " layers of " << p.layerHeight << " mm, " << p.imageWidth << " x "
              << p.imageHeight << " px images (" << p.pixel << " mm), " << p.numFast << " fast + " << p.numSlow
              << " slow, about " << std::lround(p.printTime / 60.0) << " min, " << p.usedMaterial << " ml\n";
  }
  return 0;
}

}  // namespace duplexfit::cli
