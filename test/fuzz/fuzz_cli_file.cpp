// libFuzzer target: readCli (the ASCII Common Layer Interface files `slice` writes). A file that reads
// must have positive finite units, finite heights and points, and layers whose bottom is the previous
// layer's top.
#include <cmath>
#include <cstddef>
#include <cstdint>

#include "duplexfit/slice.hpp"
#include "fuzz_util.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static const duplexfit::fuzz::InputFile file("cli", ".cli");
  const std::string& path = file.write(data, size);
  duplexfit::fuzz::expectLibraryErrorsOnly([&] {
    const duplexfit::CliFile cli = duplexfit::readCli(path);
    if (!(cli.units > 0.0) || !std::isfinite(cli.units)) __builtin_trap();
    double top = 0.0;
    for (const duplexfit::CliLayer& layer : cli.layers) {
      if (!std::isfinite(layer.height) || layer.bottom != top) __builtin_trap();
      top = layer.height;
      for (const duplexfit::CliPolyline& p : layer.polylines) {
        if (!p.points.allFinite()) __builtin_trap();
      }
    }
  });
  return 0;
}
