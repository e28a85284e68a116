// duplexfit-sample-cloud MESH N OUT.ply [SEED]: N oriented samples of a closed triangle mesh (sampleMeshCloud:
// area-proportional, unit outward face normals), written as a binary PLY cloud. bench/scaling.py makes the
// large synthetic clouds of the "Scaling" benchmark with it (they are not committed).
#include <cstdlib>
#include <iostream>
#include <string>

#include "duplexfit/io.hpp"
#include "duplexfit/mesh_sampling.hpp"

int main(int argc, char** argv) {
  if (argc < 4 || argc > 5) {
    std::cerr << "usage: duplexfit-sample-cloud MESH POINTS OUT.ply [SEED]\n";
    return 1;
  }
  try {
    const duplexfit::Mesh mesh = duplexfit::readMesh(argv[1]);
    duplexfit::MeshSampleOptions o;
    o.points = static_cast<std::size_t>(std::stoull(argv[2]));
    if (argc == 5) o.seed = std::stoull(argv[4]);
    o.limits.maxMemoryBytes = std::uint64_t{1} << 40;  // the budget of a benchmark machine is its own business
    const duplexfit::MeshSampleResult r = duplexfit::sampleMeshCloud(mesh, o, argv[1]);
    for (const std::string& w : r.report.warnings) std::cerr << "warning: " << w << "\n";
    duplexfit::writePointCloud(argv[3], r.points);
    std::cerr << argv[3] << ": " << r.points.size() << " points, spacing " << r.report.spacing << "\n";
  } catch (const std::exception& e) {
    std::cerr << "duplexfit-sample-cloud: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
