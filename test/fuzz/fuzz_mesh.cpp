// libFuzzer target: readMesh for PLY (every encoding), OBJ and STL (binary and ascii). The first byte picks
// the format (mod 3); the rest is the file. A mesh that reads must have every index in range.
#include <cstddef>
#include <cstdint>

#include "duplexfit/io.hpp"
#include "fuzz_util.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size == 0) return 0;
  static const duplexfit::fuzz::InputFile files[3] = {{"mesh", ".ply"}, {"mesh", ".obj"}, {"mesh", ".stl"}};
  const std::string& path = files[data[0] % 3].write(data + 1, size - 1);
  duplexfit::fuzz::expectLibraryErrorsOnly([&] {
    const duplexfit::Mesh mesh = duplexfit::readMesh(path);
    const auto nv = mesh.vertices.rows();
    for (Eigen::Index f = 0; f < mesh.faces.rows(); ++f) {
      for (int k = 0; k < 3; ++k) {
        if (mesh.faces(f, k) < 0 || mesh.faces(f, k) >= nv) __builtin_trap();
      }
    }
    if (!mesh.vertices.allFinite()) __builtin_trap();
  });
  return 0;
}
