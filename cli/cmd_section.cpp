// `duplexfit section`: pictures of f on axis-aligned planes (blue outside, white at 0, red inside, with
// the 0-level and offset contours). Every image is written under a temporary name first and renamed
// into place only when all of them are done, so a failed run leaves no partial output.
// The job (prepareSectionJob, runSectionJob) and its summary are the library's (jobs.hpp).
#include <filesystem>
#include <iostream>
#include <string>
#include <vector>

#include "commands.hpp"
#include "options.hpp"
#include "progress.hpp"
#include "duplexfit/jobs.hpp"

namespace duplexfit::cli {

const char* const kSectionHelp =
    R"(  section FIELD      picture of f on an axis-aligned plane: blue outside (f < 0), white at 0, red inside,
                     with the 0-level (black) and offset level (green, purple, ...) contour lines
      -o OUT.png       output; without --plane three planes through the box centre: OUT_x.png,
                       OUT_y.png, OUT_z.png (-o FOLDER: section_x.png, ... inside it)
      --plane x=C|y=C|z=C  one plane, in input units
      --size N         pixels along the longer side (16..8192, default 1024)
      --range R        colour scale ±R (default: the 99th percentile of |f| in the picture)
      --gamma G        colour intensity ∝ (|f|/R)^G (default 0.5; 1: linear)
      --rect U0,V0,U1,V1   the part of the plane shown, in (right, up) coordinates: (y, z) for x=C,
                       (x, z) for y=C, (x, y) for z=C (default: the field's box plus 5%)
      --points CLOUD   draw the cloud's points near the plane as yellow dots
      --band W         only points within W of the plane (default 1% of the box's longest side)
      --device SPEC, --precision float|double, --json (summary on stdout), --quiet
      --max-memory SIZE  memory budget (as fit's; the picture needs about 16 bytes a pixel)
)";
int cmdSection(int argc, char** argv) {
  CLI::App app("picture of f on an axis-aligned plane", "section");
  bool quiet = false, json = false;
  DeviceOptions deviceOptions;
  SectionJobOptions job;
  SectionOptions& options = job.section;
  std::string fieldPath, planeText, pointsPath, rectText, output;
  app.add_option("FIELD", fieldPath, "a field file (.dpxf)");
  app.add_option("-o,--output", output, "OUT.png, or a folder for the three axis planes")->type_name("OUT");
  app.add_option("--plane", planeText, "x=C, y=C or z=C (default: the three planes through the centre)");
  addInteger(app, "size", options.size, "pixels of the longer side (default 1024)");
  addNumber(app, "range", options.range, "|f| of full colour (default: from the field)");
  addNumber(app, "gamma", options.gamma, "colour gamma, in (0, 10]");
  app.add_option("--points", pointsPath, "overlay the cloud's points near the plane")->type_name("CLOUD");
  addNumber(app, "band", options.band, "distance from the plane of the points drawn (needs --points)");
  app.add_option("--rect", rectText, "U0,V0,U1,V1: the rectangle of the plane drawn");
  addDeviceOptions(app, deviceOptions);
  addQuiet(app, quiet);
  addJson(app, json);
  addMaxMemory(app, options.limits);
  if (parse(app, argc, argv)) return 0;
  if (options.range < 0.0) throw UsageError("option --range must be positive");
  if (!(options.gamma > 0.0 && options.gamma <= 10.0)) throw UsageError("option --gamma must be in (0, 10]");
  if (options.band < 0.0) throw UsageError("option --band must be positive");
  if (options.band > 0.0 && pointsPath.empty()) throw UsageError("option --band needs --points CLOUD");
  options.precision = deviceOptions.precision;
  if (!rectText.empty()) {
    const std::vector<double> r = parseNumberList(rectText, "rect");
    if (r.size() != 4 || !(r[2] > r[0]) || !(r[3] > r[1])) {
      throw UsageError("option --rect needs U0,V0,U1,V1 with U1 > U0 and V1 > V0");
    }
    options.rectangle = Eigen::AlignedBox2d(Eigen::Vector2d(r[0], r[1]), Eigen::Vector2d(r[2], r[3]));
  }
  if (fieldPath.empty()) throw UsageError("section needs a field file: duplexfit section FIELD -o OUT.png");
  if (output.empty()) throw UsageError("section needs an output: -o OUT.png (or -o FOLDER)");
  if (options.size < 16 || options.size > 8192) throw UsageError("option --size must be between 16 and 8192 (64M pixels)");

  if (!planeText.empty()) job.plane = SectionPlane::parse(planeText);
  job.pointsPath = pointsPath;
  job.output = output;
  const SectionJob prepared = prepareSectionJob(fieldPath, job);  // loads and checks before the device work
  StderrProgress progress(quiet);
  const Device device = openDevice(deviceOptions.spec, progress);
  const bool folderOutput = std::filesystem::is_directory(output) || output.back() == '/';
  OutputFolders folders = folderOutput ? OutputFolders(output) : OutputFolders::forFile(output);
  const SectionJobResult result = runSectionJob(device, prepared, &progress);
  folders.keep();
  if (json) {
    writeSectionJson(std::cout, result, fieldPath);
    return 0;
  }
  for (std::size_t i = 0; i < result.sections.size(); ++i) {
    const SectionResult& r = result.sections[i];
    std::cout << result.files[i] << ": " << r.plane.toString() << ", pixel " << r.pixelSize << ", f in ["
              << r.minValue << ", " << r.maxValue << "], colour scale ±" << r.range;
    if (!pointsPath.empty()) std::cout << ", " << r.pointsDrawn << " points within " << r.band;
    std::cout << "\n";
  }
  return 0;
}

}  // namespace duplexfit::cli
