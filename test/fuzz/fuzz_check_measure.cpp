// libFuzzer target: checkMesh, sampleMesh, measureDistance and measureOffset on meshes parsed from the
// input (the first byte picks PLY, OBJ or STL, mod 3). Meshes above 2000 faces are skipped to keep each
// run short; the readers themselves are fuzz_mesh's business.
#include <cmath>
#include <cstddef>
#include <cstdint>

#include "duplexfit/io.hpp"
#include "duplexfit/measure.hpp"
#include "fuzz_util.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size == 0) return 0;
  static const duplexfit::fuzz::InputFile files[3] = {{"check", ".ply"}, {"check", ".obj"}, {"check", ".stl"}};
  const std::string& path = files[data[0] % 3].write(data + 1, size - 1);
  duplexfit::Mesh mesh;
  try {
    mesh = duplexfit::readMesh(path);
  } catch (const duplexfit::Error&) {
    return 0;
  }
  if (mesh.faces.rows() > 2000) return 0;
  duplexfit::fuzz::expectLibraryErrorsOnly([&] {
    duplexfit::CheckOptions options;
    options.listedPairs = 5;
    const duplexfit::MeshCheck c = duplexfit::checkMesh(mesh, options);
    if (c.pairs.size() > 5 || c.pairs.size() > c.selfIntersections) __builtin_trap();
    if (c.valid() && (c.empty() || !c.watertight)) __builtin_trap();
  });
  duplexfit::fuzz::expectLibraryErrorsOnly([&] {
    duplexfit::MeasureOptions options;
    options.samplesPerFace = 2.0;
    const duplexfit::MeshSamples s = duplexfit::sampleMesh(mesh, options);
    if (!s.points.allFinite()) __builtin_trap();
    const duplexfit::DistanceReport d = duplexfit::measureDistance(mesh, mesh, options);
    if (std::isnan(d.hausdorff)) __builtin_trap();
    const duplexfit::OffsetReport o = duplexfit::measureOffset(mesh, mesh, 0.01, options);
    if (o.wrongSide > o.samples) __builtin_trap();
  });
  return 0;
}
