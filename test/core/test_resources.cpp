// ResourceLimits: the --max-memory size parser (good and bad values), the default budget and the refusal's
// message.
#include <doctest/doctest.h>

#include <string>

#include "duplexfit/resources.hpp"

using namespace duplexfit;

TEST_SUITE("core") {
  TEST_CASE("parseByteSize: units are powers of 1024, a plain number is bytes") {
    CHECK(parseByteSize("8G") == (std::uint64_t{8} << 30));
    CHECK(parseByteSize("512M") == (std::uint64_t{512} << 20));
    CHECK(parseByteSize("512m") == (std::uint64_t{512} << 20));
    CHECK(parseByteSize("1.5GiB") == (std::uint64_t{3} << 29));
    CHECK(parseByteSize("1.5 GB") == (std::uint64_t{3} << 29));
    CHECK(parseByteSize("2048k") == (std::uint64_t{2} << 20));
    CHECK(parseByteSize("2T") == (std::uint64_t{2} << 40));
    CHECK(parseByteSize("1048576") == (std::uint64_t{1} << 20));
    CHECK(parseByteSize("3000000000") == std::uint64_t{3000000000});
    CHECK(parseByteSize("1048576B") == (std::uint64_t{1} << 20));
  }

  TEST_CASE("parseByteSize: bad values are InvalidArgument naming the option and the forms") {
    for (const char* bad : {"", "G", "-1G", "+1G", "1e9", "0x100000", "8X", "8GG", "8Gi", "1.2.3M", "inf", "nan", "0",
                            "1000", "1023k", "2000P", "99999999999999999999"}) {
      CAPTURE(bad);
      try {
        parseByteSize(bad, "--max-memory");
        FAIL("accepted");
      } catch (const InvalidArgument& e) {
        const std::string what = e.what();
        CHECK(what.find("--max-memory") != std::string::npos);
        CHECK(what.find("8G, 512M, 1.5GiB") != std::string::npos);
      }
    }
  }

  TEST_CASE("the default budget is 75% of the physical memory at most, and requireMemory's message") {
    const std::uint64_t physical = physicalMemoryBytes();
    const std::uint64_t budget = defaultMaxMemoryBytes();
    CHECK(budget > 0);
    if (physical > 0) CHECK(budget <= physical / 4 * 3);
    CHECK(ResourceLimits{}.bytes() == budget);
    CHECK(ResourceLimits{std::uint64_t{5} << 20}.bytes() == (std::uint64_t{5} << 20));
    CHECK(formatBytes(34.2 * 1073741824.0) == "34.2 GiB");
    CHECK(formatBytes(512.0 * 1048576.0) == "512 MiB");
    CHECK(formatBytes(12.0) == "12 bytes");

    const ResourceLimits limits{std::uint64_t{1} << 30};
    CHECK_NOTHROW(requireMemory(limits, "stage", 1073741824.0, "the work", "use less"));
    try {
      requireMemory(limits, "polygonize", 2.0 * 1073741824.0, "the 2048x2048x2048 grid", "use a larger --cell");
      FAIL("not refused");
    } catch (const MemoryLimitExceeded& e) {
      CHECK(e.stage() == "polygonize");
      CHECK(e.budget() == limits.maxMemoryBytes);
      CHECK(std::string(e.what()) ==
            "polygonize: the 2048x2048x2048 grid needs about 2 GiB, more than --max-memory 1 GiB; use a larger "
            "--cell, or raise --max-memory");
    }
  }
}
