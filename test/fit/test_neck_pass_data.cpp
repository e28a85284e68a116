// The pipelines' neck pass (SurfaceOptions::neckPassMaxFaces) on the outputs issue's cloud: maxplanck_12k's
// default fit at δ = 0.02, whose offset level set has a neck narrower than a quarter cell. Without the pass the
// offset mesh stays more than 0.1% of the side from its level set there; with it (the default) every mesh is
// within 0.1%, closed, and under 400k triangles. Also the phantom repair on the two clouds whose zero
// meshes kept phantom components. In the fit suite (labels data and device).
#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <string>

#include <Eigen/Core>

#include "data.hpp"
#include "duplexfit/field.hpp"
#include "duplexfit/io.hpp"
#include "duplexfit/measure.hpp"
#include "duplexfit/pipeline.hpp"
#include "test_device.hpp"

using namespace duplexfit;

// In the sanitizer build test_refine runs the deeper refinement's code; these fits would take minutes there.
#ifdef DUPLEXFIT_SANITIZED
#define SKIP_WHEN_SANITIZED DUPLEXFIT_SKIP("in the sanitizer build (test_refine runs the deeper refinement's code there)")
#else
#define SKIP_WHEN_SANITIZED static_cast<void>(0)
#endif

namespace {

/// The default pipeline on a shared cloud with one inward offset: its zero level and offset.
PipelineResult defaultFit(const Device& device, const std::string& cloud, double delta, PipelineOptions& o) {
  o.fit.offsets = {delta};
  PipelineResult result = runPipeline(device, cloud, o);
  REQUIRE(result.surfaces.size() == 2);
  return result;
}

}  // namespace

TEST_SUITE("fit") {
  TEST_CASE("neck pass: maxplanck_12k at delta 0.02, every mesh within 0.1% of the side of its level set") {
    SKIP_WHEN_SANITIZED;
    DUPLEXFIT_SHARED_DATA_DIR(dir);
    DUPLEXFIT_OPENCL_DEVICE(device);
    PipelineOptions o;
    const PipelineResult result = defaultFit(device, dir + "/clouds/maxplanck_12k.ply", 0.02, o);
    for (const PipelineSurface& s : result.surfaces) {
      CAPTURE(s.offset);
      const MeshFinishReport& f = s.finish;
      MESSAGE("iso " << s.offset << ": " << s.mesh.faces.rows() << " triangles, deviation " << 100.0 * f.deviation.relativeMax
                     << "% of the side; neck pass applied " << f.neckPass.applied << ", kept " << f.neckPass.kept << ", "
                     << f.neckPass.cells << " cells, " << 100.0 * f.neckPass.maxBefore << "% -> "
                     << 100.0 * f.neckPass.maxAfter << "%, " << f.neckPass.seconds << " s");
      CHECK(f.deviationMeasured);
      CHECK(f.deviation.relativeMax <= 1e-3);
      CHECK(s.topology.watertight());
      CHECK(s.topology.manifold());
      CHECK(s.topology.components == 1);
      CHECK(s.mesh.faces.rows() <= 400000);
    }
    const NeckPassReport& neck = result.surfaces[1].finish.neckPass;
    CHECK(neck.applied);
    CHECK(neck.kept);
    CHECK(neck.cells > 0);
    CHECK(neck.maxBefore > 1e-3);
    CHECK(neck.maxAfter <= 1e-3);
    // Its first round replaced only the faces around the neck (the local replacement; the second round,
    // whose zone's boundary loops do not pair up, extracted the whole level set again).
    CHECK(neck.removedFaces > 0);
    CHECK(neck.patchFaces > 0);
    // The same level set without the pass: beyond 0.1% (what the pass is for).
    SurfaceOptions without = o.surface;
    without.neckPassMaxFaces = 0;
    const MeshPipelineResult plain =
        runMeshPipeline(device, result.fields[0], 0.02, without, defaultMinComponent(0.02));
    CHECK_FALSE(plain.finish.neckPass.applied);
    CHECK(plain.finish.deviation.relativeMax > 1e-3);
    CHECK(plain.finish.deviation.relativeMax == doctest::Approx(neck.maxBefore));
  }

  // joint_40k's zero level at δ = −0.02 (found by fitting every shared cloud at 0.01, 0.05 and −0.02 and
  // checking both meshes): the neck pass's first local round spliced in a band with four triangles degenerate
  // in float32 (their corners on the hole's loops, which the patch's cleaning may not move), so `check`
  // refused the zero mesh that `fit --strict` had accepted. The round is refused now and the level set
  // extracted whole; and a mesh with such a triangle is not sound.
  TEST_CASE("neck pass: joint_40k at delta -0.02, no triangle degenerate in float32 spliced in") {
    SKIP_WHEN_SANITIZED;
    DUPLEXFIT_SHARED_DATA_DIR(dir);
    DUPLEXFIT_OPENCL_DEVICE(device);
    PipelineOptions o;
    const PipelineResult result = defaultFit(device, dir + "/clouds/joint_40k.ply", -0.02, o);
    for (const PipelineSurface& s : result.surfaces) {
      CAPTURE(s.offset);
      const NeckPassReport& neck = s.finish.neckPass;
      MESSAGE("iso " << s.offset << ": neck pass applied " << neck.applied << ", kept " << neck.kept << ", local "
                     << neck.local << ", refused: " << neck.localRefused << "; float32-degenerate "
                     << s.quality.float32DegenerateFaces);
      CHECK(s.quality.float32DegenerateFaces == 0);
      CHECK(s.sound());
      const MeshCheck c = checkMesh(s.mesh);
      CHECK(c.quality.float32DegenerateFaces == 0);
      CHECK(c.valid());
    }
    CHECK(result.surfaces[0].finish.neckPass.applied);
  }

  // The noisy bunny's offset at δ = 0.025 ends in a thin, sharp tail whose points beyond the limit span about
  // 1,600 cells in 6 clusters (within neckPassMaxCells since 2026-12-06). Its first local round brings the
  // offset from 1% of the side to about the limit; the second round's local replacement crosses the kept faces,
  // and the first round's patch stays instead of the whole level set being extracted again (kWholeAgainFactor):
  // the result is within twice the limit. That is the field of the fit without the crease-plane test (the
  // field this case was found on): with the test (the default since 2026-12-07) the tail differs, the first
  // local round is refused (5 crossing pairs in its patch) and the whole offset is extracted again, 0.53% →
  // 0.093% of the side; the default's outcome is checked first.
  TEST_CASE("neck pass: bunny_35k_noise0.5pct at delta 0.025, a local round near the limit is not redone whole") {
    SKIP_WHEN_SANITIZED;
    DUPLEXFIT_SHARED_DATA_DIR(dir);
    DUPLEXFIT_OPENCL_DEVICE(device);
    {
      PipelineOptions defaults;
      const PipelineResult result = defaultFit(device, dir + "/clouds/bunny_35k_noise0.5pct.ply", 0.025, defaults);
      const PipelineSurface& offset = result.surfaces[1];
      const NeckPassReport& neck = offset.finish.neckPass;
      MESSAGE("defaults, offset: neck pass applied " << neck.applied << ", kept " << neck.kept << ", local "
                                                     << neck.local << ", " << 100.0 * neck.maxBefore << "% -> "
                                                     << 100.0 * neck.maxAfter << "%");
      CHECK(neck.applied);
      CHECK(neck.kept);
      CHECK(neck.maxAfter <= 2e-3);
      CHECK(offset.topology.watertight());
      CHECK(offset.topology.manifold());
      CHECK(offset.topology.components == 1);
    }
    PipelineOptions o;
    o.fit.creaseTest = false;
    const PipelineResult result = defaultFit(device, dir + "/clouds/bunny_35k_noise0.5pct.ply", 0.025, o);
    const PipelineSurface& offset = result.surfaces[1];
    const NeckPassReport& neck = offset.finish.neckPass;
    MESSAGE("offset: neck pass applied " << neck.applied << ", kept " << neck.kept << ", local " << neck.local << ", "
                                         << neck.cells << " cells, " << 100.0 * neck.maxBefore << "% -> "
                                         << 100.0 * neck.maxAfter << "%, " << neck.seconds << " s, refused: "
                                         << neck.localRefused);
    CHECK(neck.applied);
    CHECK(neck.kept);
    // No round extracted the whole level set again: the first local round is kept (as maxplanck_12k's above)
    // and leaves the offset within twice the limit, so the refused second round does not fall back to it.
    CHECK(neck.local);
    CHECK(neck.maxBefore > 5e-3);
    CHECK(neck.maxAfter <= 2e-3);
    CHECK(neck.maxAfter < 0.2 * neck.maxBefore);
    CHECK(offset.topology.watertight());
    CHECK(offset.topology.manifold());
    CHECK(offset.topology.components == 1);
  }
}

TEST_SUITE("fit") {
  TEST_CASE("phantom repair: wheel_29k and armadillo_43k at delta 0.025 keep no zero-level component off the truth") {
#ifdef DUPLEXFIT_SANITIZED
    DUPLEXFIT_SKIP("in the sanitizer build (test_phantom_repair's planted blobs run the repair's code there)");
#endif
    DUPLEXFIT_SHARED_DATA_DIR(dir);
    DUPLEXFIT_OPENCL_DEVICE(device);
    // The phantoms the last sessions left: wheel_29k's in a pocket between spokes (458 faces, 0.0114 from
    // the nearest sample), armadillo_43k's beside a claw and between the toes (the latter within the
    // self-check's two edges of a sample, so it passed the check).
    // wheel_29k's phantom no longer forms with the finest level's overshoot check (docs/method.md,
    // "Overshoot between sparse samples"), so the repair is tested there without it, and the default fit
    // must have no phantom either. Without the crease-plane test too (the field the phantom was found on):
    // with the test and without the overshoot check, the repair of that phantom is refused (a face of the
    // offset beside the correction would turn) and it stays, flagged by the self-check; the default fit,
    // which has both, has none (checked below).
    struct Case {
      std::string name;
      Eigen::Vector3d inPhantom;  // a point where the unrepaired field was > 0 (a section through the phantom)
      bool overshootCheck;
    };
    for (const Case& c : {Case{"wheel_29k", {-0.161, -0.1545, -0.0355}, false},
                          Case{"armadillo_43k", {-0.123, 0.466, 0.188}, true}}) {
      const std::string& name = c.name;
      CAPTURE(name);
      PipelineOptions o;
      o.fit.overshootCheck = c.overshootCheck;
      o.fit.creaseTest = c.overshootCheck;
      if (!c.overshootCheck) {
        PipelineOptions defaults;
        const PipelineResult plain = defaultFit(device, dir + "/clouds/" + name + ".ply", 0.025, defaults);
        CHECK(plain.report.fit.levelReports.back().overshootSites > 0);
        CHECK(plain.report.selfCheck.ok());
        CHECK(plain.surfaces[0].topology.components == 1);
        CHECK(plain.fields[0].value(c.inPhantom) < 0.0);
      }
      const PipelineResult result = defaultFit(device, dir + "/clouds/" + name + ".ply", 0.025, o);
      const PhantomRepairReport& pr = result.report.phantomRepair;
      MESSAGE(name << ": " << pr.candidates << " candidate(s), " << pr.repaired << " repaired (" << pr.repairedFaces
                   << " faces), refused '" << pr.refused << "', " << pr.seconds << " s");
      CHECK(pr.repaired >= 1);
      CHECK(pr.refused.empty());
      CHECK(result.report.selfCheck.ok());
      // The truth mesh has one component: so has the zero mesh, and the repaired field is negative where
      // the unrepaired one had a phantom (empty space, outside the truth).
      CHECK(result.surfaces[0].topology.components == 1);
      CHECK(result.surfaces[0].topology.watertight());
      CHECK(result.fields[0].value(c.inPhantom) < 0.0);
    }
  }
  TEST_CASE("phantom repair: wheel_29k at delta 0.01, a void under the offset: the offset extracted again, on the truth's offset") {
#ifdef DUPLEXFIT_SANITIZED
    DUPLEXFIT_SKIP("in the sanitizer build (test_phantom_repair's planted void runs the repair's code there)");
#endif
    DUPLEXFIT_SHARED_DATA_DIR(dir);
    DUPLEXFIT_OPENCL_DEVICE(device);
    // The default fit leaves a phantom void 0.017 under a sparsely sampled face of the rim (150 faces); the
    // δ level wraps it in a lobe joined to the offset sheet, which no vertex move can take back: the repair
    // was refused and `fit --strict` failed. Now the offset is extracted again around the correction.
    const double delta = 0.01;
    const Eigen::Vector3d hole(-0.153, 0.4005, -0.0244);  // inside the void (a section through it)
    PipelineOptions o;
    const PipelineResult result = defaultFit(device, dir + "/clouds/wheel_29k.ply", delta, o);
    const PhantomRepairReport& pr = result.report.phantomRepair;
    MESSAGE("wheel_29k: " << pr.candidates << " candidate(s), " << pr.repaired << " repaired, " << pr.reextracted
                          << " mesh(es) extracted again, " << pr.restored << " keep points restored, refused '"
                          << pr.refused << "', " << pr.seconds << " + " << pr.reextractSeconds << " s");
    CHECK(pr.repaired >= 1);
    CHECK(pr.reextracted >= 1);
    CHECK(pr.refused.empty());
    CHECK(result.report.selfCheck.ok());
    CHECK(result.surfaces[0].topology.components == 1);  // the truth mesh's
    for (const PipelineSurface& s : result.surfaces) {
      CAPTURE(s.offset);
      CHECK(s.topology.watertight());
      CHECK(s.topology.manifold());
      CHECK(s.sound());
    }
    // Against the truth: the void lies in the solid deeper than δ, and the offset mesh near it lies on the
    // truth's offset (|distance to meshes/wheel.ply − δ| within 0.03 of the void: mean 0.0039 and max
    // 0.0185 with the lobe, 0.0006–0.0009 and 0.0036–0.005 repaired; wheel_29k's offsets at δ = 0.01 are
    // 0.0048 off their truth next to it without any phantom, the p99 over the mesh 34%).
    CHECK(result.fields[0].value(hole) > delta);
    const TriangleBvh truth(readMesh(dir + "/meshes/wheel.ply"));
    const Mesh& offset = result.surfaces[1].mesh;
    double worst = 0.0, sum = 0.0;
    std::size_t near = 0;
    for (Eigen::Index v = 0; v < offset.vertices.rows(); ++v) {
      const Eigen::Vector3d x = offset.vertices.row(v).transpose();
      if ((x - hole).norm() > 0.03) continue;
      ++near;
      const double e = std::abs(truth.closest(x).distance - delta);
      worst = std::max(worst, e);
      sum += e;
    }
    MESSAGE("offset vertices within 0.03 of the void: " << near << ", |d - delta| mean " << sum / static_cast<double>(std::max<std::size_t>(near, 1)) << ", max " << worst);
    REQUIRE(near > 0);
    CHECK(sum / static_cast<double>(near) <= 0.15 * delta);
    CHECK(worst <= 0.6 * delta);
  }
}
