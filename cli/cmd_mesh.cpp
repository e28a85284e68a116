// `duplexfit mesh`: re-extract one level set from a saved field (runMeshPipeline).
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
  bool quiet = false;
  double iso = 0.0, minComponent = 0.0;
  std::string input, out = "mesh.ply";
  SurfaceOptions surface;
  app.add_option("FIELD", input, "a field file (.dpxf) written by duplexfit fit");
  addNumber(app, "iso", iso, "the level (default 0)");
  app.add_option("-o,--output", out, "output mesh: .ply, .obj or .stl (default mesh.ply)")->type_name("OUT");
  addDeviceOptions(app, device);
  addQuiet(app, quiet);
  addNumber(app, "cell", surface.cell, "marching grid cell size");
  addInteger(app, "resolution", surface.resolution, "marching grid cells along the longest side");
  addFraction(app, "min-component", minComponent, "drop components below F of the mesh's area (default 0)");
  if (parse(app, argc, argv)) return 0;
  surface.precision = device.precision;
  StderrProgress progress(quiet);
  const Device dev = openDevice(device.spec, progress);
  if (input.empty()) throw UsageError("mesh needs a field file: duplexfit mesh FIELD --iso V -o OUT");
  const ImplicitField field = ImplicitField::load(input);
  const MeshPipelineResult r = runMeshPipeline(dev, field, iso, surface, minComponent, &progress);
  writeMesh(out, r.mesh);
  const MeshTopology& t = r.topology;
  std::cout << out << ": iso " << iso << ", " << t.faces << " triangles, " << t.components << " component(s), "
            << (t.watertight() && t.manifold() ? "watertight 2-manifold" : "NOT watertight/manifold") << "\n";
  return 0;
}

}  // namespace duplexfit::cli
