// `duplexfit mesh`: re-extract one level set from a saved field (runMeshPipeline).
#include <iostream>

#include "commands.hpp"
#include "progress.hpp"
#include "duplexfit/io.hpp"
#include "duplexfit/pipeline.hpp"

namespace duplexfit::cli {

const std::vector<std::string> kMeshValued = {"iso", "output", "device", "precision", "cell", "resolution",
                                              "min-component", "min-offset-component"};

int cmdMesh(Args& args) {
  StderrProgress progress(args.flag("quiet"));
  const double iso = args.num("iso", 0.0);
  SurfaceOptions surface;
  surface.cell = args.num("cell", 0.0);
  surface.resolution = static_cast<int>(args.integer("resolution", 0));
  surface.precision = parsePrecision(args.str("precision", "float").c_str());
  const double minComponent = fractionOption(args, "min-component", 0.0);
  const std::string out = args.str("output", "mesh.ply");
  const Device device = openDevice(args.str("device", ""), progress);
  args.finish(1);
  if (args.positional().empty()) throw UsageError("mesh needs a field file: duplexfit mesh FIELD --iso V -o OUT");
  const ImplicitField field = ImplicitField::load(args.positional()[0]);
  const MeshPipelineResult r = runMeshPipeline(device, field, iso, surface, minComponent, &progress);
  writeMesh(out, r.mesh);
  const MeshTopology& t = r.topology;
  std::cout << out << ": iso " << iso << ", " << t.faces << " triangles, " << t.components << " component(s), "
            << (t.watertight() && t.manifold() ? "watertight 2-manifold" : "NOT watertight/manifold") << "\n";
  return 0;
}

}  // namespace duplexfit::cli
