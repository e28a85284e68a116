// libFuzzer target: readPointCloud (PLY in every encoding, XYZ). The first byte picks the format (bit 0)
// and whether normals are required (bit 1); the rest is the file.
#include <cstddef>
#include <cstdint>

#include "duplexfit/io.hpp"
#include "fuzz_util.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size == 0) return 0;
  static const duplexfit::fuzz::InputFile ply("points", ".ply"), xyz("points", ".xyz");
  const bool isPly = (data[0] & 1) == 0;
  const std::string& path = (isPly ? ply : xyz).write(data + 1, size - 1);
  duplexfit::PointReadOptions options;
  options.requireNormals = (data[0] & 2) != 0;
  duplexfit::fuzz::expectLibraryErrorsOnly([&] {
    const duplexfit::PointCloudFile file = duplexfit::readPointCloudWithReport(path, options);
    // The report and the data must agree.
    if (file.report.points != file.points.size()) __builtin_trap();
  });
  return 0;
}
