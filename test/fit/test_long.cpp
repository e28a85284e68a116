// Long data tests (ctest label "long", suite "long"; skipped unless DUPLEXFIT_LONG_TESTS=1): the robust field
// on eight_110k at δ = 0.05 inward, the case whose tubes are about 2δ thick, against the ground-truth mesh.
#include <doctest/doctest.h>

#include <cstdlib>
#include <string>

#include "data.hpp"
#include "duplexfit/fit.hpp"
#include "duplexfit/io.hpp"
#include "duplexfit/measure.hpp"
#include "duplexfit/surfaces.hpp"
#include "test_device.hpp"

using namespace duplexfit;

namespace {
bool longTestsEnabled() {
  const char* env = std::getenv("DUPLEXFIT_LONG_TESTS");
  return env != nullptr && std::string(env) == "1";
}
}  // namespace

TEST_SUITE("long") {
  TEST_CASE("long: eight_110k at delta 0.05: one significant offset component on the exact offset, none spurious") {
    if (!longTestsEnabled()) DUPLEXFIT_SKIP("set DUPLEXFIT_LONG_TESTS=1 to run it (about a minute on 2 cores)");
    DUPLEXFIT_OPENCL_DEVICE(d);
    DUPLEXFIT_SHARED_DATA_DIR(dir);
    PointSet cloud = readPointCloud(dir + "/clouds/eight_110k.ply");
    cloud.mergeDuplicates();
    FitOptions options;
    options.offsets = {0.05};
    const FitResult r = fit(d, cloud, options);
    const SurfaceResult s = extractSurfaces(d, r.field, {0.0, 0.05});
    const Mesh truth = readMesh(dir + "/meshes/eight.ply");
    CHECK(analyzeTopology(s.meshes[0]).components == 1);
    const OffsetReport o = measureOffset(s.meshes[1], truth, 0.05);
    // The exact offset has one component; ours may keep slivers where the tubes are about 2δ thick, but
    // none of them off the offset and all of them tiny.
    std::size_t mainFaces = 0, total = 0;
    for (const auto& c : o.components) {
      total += c.faces;
      mainFaces = std::max(mainFaces, c.faces);
    }
    MESSAGE("offset: " << o.components.size() << " components, the largest with "
                       << 100.0 * static_cast<double>(mainFaces) / static_cast<double>(total)
                       << "% of the faces; mean deviation " << o.relativeDeviation.mean * 100 << "% of delta");
    CHECK(o.offOffsetComponents == 0);
    CHECK(static_cast<double>(mainFaces) >= 0.999 * static_cast<double>(total));
    CHECK(o.relativeDeviation.mean <= 0.01);  // measured 0.61% (2.0% before the medial constraints)
  }
}
