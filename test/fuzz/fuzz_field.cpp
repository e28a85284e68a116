// libFuzzer target: ImplicitField::load from bytes (the binary field file, docs/field-format.md). A field
// that loads is evaluated once (reference path) and saved again; saving and reloading must round-trip.
#include <cstddef>
#include <cstdint>
#include <sstream>
#include <string>

#include "duplexfit/field.hpp"
#include "fuzz_util.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  std::istringstream in(std::string(reinterpret_cast<const char*>(data), size));
  duplexfit::fuzz::expectLibraryErrorsOnly([&] {
    const duplexfit::ImplicitField field = duplexfit::ImplicitField::load(in, "fuzz input");
    // Bounded work: the reference evaluation visits every centre once.
    if (field.centreCount() <= 4096) (void)field.value(field.bounds().center());
    std::ostringstream out;
    field.save(out);
    std::istringstream again(out.str());
    const duplexfit::ImplicitField reloaded = duplexfit::ImplicitField::load(again, "saved fuzz input");
    if (reloaded.centreCount() != field.centreCount() || reloaded.levels().size() != field.levels().size()) {
      __builtin_trap();
    }
  });
  return 0;
}
