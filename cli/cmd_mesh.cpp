// `duplexfit mesh`: re-extract one level set from a saved field (runMeshPipeline), or with --shell the
// printable shell between the levels 0 and --iso D, with drain holes (runShellPipeline).
#include <iostream>

#include "commands.hpp"
#include "options.hpp"
#include "progress.hpp"
#include "duplexfit/io.hpp"
#include "duplexfit/pipeline.hpp"

namespace duplexfit::cli {

int cmdMesh(int argc, char** argv) {
  CLI::App app("extract one level set of a saved field", "mesh");
  DeviceOptions device;
  bool quiet = false, shell = false, json = false;
  double iso = 0.0, minComponent = -1.0;  // -1: not given
  std::string input, out = "mesh.ply";
  std::vector<std::string> holes;
  SurfaceOptions surface;
  app.add_option("FIELD", input, "a field file (.dpxf) written by duplexfit fit");
  addNumber(app, "iso", iso, "the level (default 0)");
  app.add_option("-o,--output", out, "output mesh: .ply, .obj or .stl (default mesh.ply)")->type_name("OUT");
  addDeviceOptions(app, device);
  addQuiet(app, quiet);
  addJson(app, json, "the mesh's report (topology, cleaning, deviation; with --shell volumes and validity) on stdout");
  addNumber(app, "cell", surface.cell, "marching grid cell size");
  addInteger(app, "resolution", surface.resolution, "marching grid cells along the longest side");
  addMeshFinishOptions(app, surface.finish);
  addRefineOptions(app, surface);
  addMaxMemory(app, surface.polygonize.limits);
  addFraction(app, "min-component", minComponent,
              "drop components below F of the mesh's area (default: 0 at iso 0; 0.001 at any other level, as fit "
              "drops the slivers of an offset where a part is about 2|iso| thick)");
  app.add_flag("--shell", shell, "the shell between the levels 0 and --iso D > 0 as one closed solid");
  addDrainHoles(app, holes);
  if (parse(app, argc, argv)) return 0;
  surface.precision = device.precision;
  // Not given: what fit does with its own meshes (defaultMinComponent); --shell applies the offset fraction
  // to its inner surface itself.
  const bool minComponentGiven = minComponent >= 0.0;
  if (!minComponentGiven) minComponent = 0.0;
  const double meshMinComponent = minComponentGiven ? minComponent : defaultMinComponent(iso);
  ShellOptions shellOptions;
  for (const std::string& h : holes) parseDrainHoleSpec(h, shellOptions);
  shell = shell || shellOptions.drained();  // holes imply --shell
  StderrProgress progress(quiet);
  const Device dev = openDevice(device.spec, progress);
  if (input.empty()) throw UsageError("mesh needs a field file: duplexfit mesh FIELD --iso V -o OUT");
  const ImplicitField field = ImplicitField::load(input);
  if (shell) {
    shellOptions.offset = iso;
    const ShellPipelineResult r = runShellPipeline(dev, field, shellOptions, surface, minComponent, &progress);
    OutputFolders folders = OutputFolders::forFile(out);
    writeMesh(out, r.shell.mesh);
    folders.keep();
    if (json) {
      writeShellPipelineJson(std::cout, r, out);
      return 0;
    }
    const ShellReport& s = r.shell.report;
    std::cout << out << ": shell iso 0 and " << iso << ", " << s.topology.faces << " triangles, "
              << (s.valid() ? "valid solid" : "NOT a valid solid") << ", volume " << s.volume << " (zero - offset "
              << s.zeroMinusOffsetVolume() << "), " << s.drainHoles.size() << " drain hole(s)\n";
    return 0;
  }
  const MeshPipelineResult r = runMeshPipeline(dev, field, iso, surface, meshMinComponent, &progress);
  OutputFolders folders = OutputFolders::forFile(out);
  writeMesh(out, r.mesh);
  folders.keep();
  if (json) {
    writeMeshPipelineJson(std::cout, r, out, iso);
    return 0;
  }
  const MeshTopology& t = r.topology;
  std::cout << out << ": iso " << iso << ", " << t.faces << " triangles, " << t.components << " component(s), "
            << (t.watertight() && t.manifold() ? "watertight 2-manifold" : "NOT watertight/manifold")
            << crossingNote(r.finish.project);
  if (r.finish.deviationMeasured) {
    std::cout << ", deviation from the level set " << r.finish.deviation.max << " ("
              << 100.0 * r.finish.deviation.relativeMax << "% of the largest side)";
  }
  std::cout << "\n";
  return 0;
}

}  // namespace duplexfit::cli
