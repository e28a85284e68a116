// Regression tests of docs/reliability.md, at the reported input sizes: a check on 20,000 copies of one
// triangle and on one 349k-corner polygon with repeated corners (both used to store every intersecting
// pair and abort with bad_alloc inside an OpenMP region), a measure on coordinates of 1e200 (a NaN cast to
// size_t in sampleMesh), and empty or all-degenerate meshes (reported watertight).
#include <doctest/doctest.h>

#include <sstream>
#include <string>

#include <nlohmann/json.hpp>

#include "cli_runner.hpp"
#include "duplexfit/error.hpp"
#include "duplexfit/io.hpp"
#include "duplexfit/jobs.hpp"
#include "duplexfit/measure.hpp"
#include "measure/measure_shapes.hpp"
#include "temp_dir.hpp"

namespace {

using namespace duplexfit;

bool has(const std::string& text, const std::string& part) { return text.find(part) != std::string::npos; }

#ifdef DUPLEXFIT_SANITIZED
constexpr bool kSanitized = true;
#else
constexpr bool kSanitized = false;
#endif

/// The sanitizer build (about 10x slower) checks the same inputs with a smaller work bound.
CheckOptions boundedOptions() {
  CheckOptions o;
  if (kSanitized) o.candidatePairBudget = 20'000'000;
  return o;
}

/// 3 vertices and `copies` faces "f 1 2 3".
std::string copiesObj(std::size_t copies) {
  std::string s = "v 0 0 0\nv 1 0 0\nv 0 1 0\n";
  s.reserve(s.size() + 8 * copies);
  for (std::size_t i = 0; i < copies; ++i) s += "f 1 2 3\n";
  return s;
}

/// 3 vertices and one face with `corners` corners cycling 1 2 3 (fanned: a third are copies of 1 2 3).
std::string polygonObj(std::size_t corners) {
  std::string s = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf";
  s.reserve(s.size() + 2 * corners + 1);
  for (std::size_t i = 0; i < corners; ++i) {
    s += ' ';
    s += static_cast<char>('1' + i % 3);
  }
  s += '\n';
  return s;
}

}  // namespace

TEST_SUITE("measure") {

TEST_CASE("reliability: 20,000 copies of one triangle are counted, not stored") {
  const testing::TempDir dir;
  const std::string path = dir.file("copies.obj");
  REQUIRE(testing::writeFile(path, copiesObj(20000)));
  const Mesh m = readMesh(path);
  REQUIRE(m.faces.rows() == 20000);
  const MeshCheck c = checkMesh(m, boundedOptions());
  CHECK(c.selfIntersectionsChecked);
  CHECK_FALSE(c.valid());
  CHECK_FALSE(c.manifold);
  REQUIRE(c.pairs.size() == 20);
  for (std::size_t k = 1; k < c.pairs.size(); ++k) CHECK(c.pairs[k - 1] < c.pairs[k]);
  const std::size_t all = std::size_t{20000} * 19999 / 2;  // every pair is a duplicate face
  if (kSanitized) {
    // 1024 candidates a face: a lower bound, said to be one.
    CHECK_FALSE(c.selfIntersectionsComplete);
    CHECK(c.selfIntersections >= 20000);
    CHECK(c.selfIntersections < all);
  } else {
    CHECK(c.selfIntersectionsComplete);
    CHECK(c.selfIntersections == all);
    CHECK(c.pairs.front() == std::pair<std::int64_t, std::int64_t>(0, 1));
    CHECK(c.pairs.back() == std::pair<std::int64_t, std::int64_t>(0, 20));
  }

  // A work bound below the candidates: a lower bound, deterministic, and the same first pairs.
  CheckOptions small;
  small.candidatePairBudget = 0;  // 1024 candidates a face
  const MeshCheck a = checkMesh(m, small), b = checkMesh(m, small);
  CHECK_FALSE(a.selfIntersectionsComplete);
  CHECK_FALSE(a.valid());
  CHECK(a.selfIntersections == b.selfIntersections);
  CHECK(a.selfIntersections > 0);
  CHECK(a.selfIntersections <= std::size_t{20000} * 1024);
  CHECK(a.pairs == b.pairs);
  CHECK(a.pairs.size() == 20);
  {
    // The job's text and JSON say that the count is a lower bound.
    const CheckJobResult job = runCheckJob(path, small);
    CHECK(job.check.selfIntersections == a.selfIntersections);
    std::ostringstream text, json;
    writeCheckText(text, job);
    writeCheckJson(json, job);
    CHECK(has(text.str(), "at least " + std::to_string(a.selfIntersections) + " triangle pairs"));
    const nlohmann::json j = nlohmann::json::parse(json.str());
    CHECK(j.at("self_intersections_complete") == false);
    CHECK(j.at("self_intersections") == a.selfIntersections);
  }

  if (kSanitized) {
    testing::skipPart("the CLI run on 20,000 copies (too slow under the sanitizers)");
    return;
  }
  if (testing::cliPath().empty()) {
    testing::skipPart("the duplexfit CLI is not built");
    return;
  }
  const testing::CliRun r = testing::runCli("check " + path + " --quiet");
  INFO(r.out << r.err);
  CHECK(r.status == 0);
  CHECK(has(r.out, std::to_string(all) + " triangle pairs"));
  CHECK(has(r.out, "first pairs: (0, 1) (0, 2)"));
  CHECK(has(r.out, "verdict                not valid"));
}

TEST_CASE("reliability: a 349k-corner polygon with repeated corners reads and checks in bounded work") {
  const testing::TempDir dir;
  const std::string path = dir.file("polygon.obj");
  const std::size_t corners = 349002;
  const std::string text = polygonObj(corners);
  CHECK(text.size() > 690000);  // the reported file: 0.7 MB
  REQUIRE(testing::writeFile(path, text));
  const Mesh m = readMesh(path);
  REQUIRE(m.faces.rows() == static_cast<Eigen::Index>(corners - 2));  // a fan: linear in the corners
  const MeshValidation v = validateMesh(m, path);
  CHECK(v.repeatedIndexFaces == 2 * (corners - 2) / 3);
  const MeshCheck c = checkMesh(m, boundedOptions());
  const std::size_t copies = (corners - 2) / 3 + ((corners - 2) % 3 != 0 ? 1 : 0);  // fan triangles k ≡ 1 mod 3
  CHECK(c.selfIntersectionsChecked);
  CHECK_FALSE(c.selfIntersectionsComplete);  // 116k copies: 6.8e9 pairs are beyond the work bound
  CHECK(c.selfIntersections >= copies);
  CHECK(c.selfIntersections < copies * (copies - 1) / 2);
  CHECK(c.pairs.size() == 20);
  CHECK_FALSE(c.valid());
}

TEST_CASE("reliability: coordinates of 1e200 are a clear InvalidArgument, not undefined behaviour") {
  Mesh big;
  big.vertices.resize(3, 3);
  big.vertices << 0, 0, 0, 1e200, 0, 0, 0, 1e200, 0;
  big.faces.resize(1, 3);
  big.faces << 0, 1, 2;
  auto message = [](auto&& call) -> std::string {
    try {
      call();
    } catch (const InvalidArgument& e) {
      return e.what();
    }
    return "(no InvalidArgument)";
  };
  std::string e = message([&] { validateMesh(big, "big.obj"); });
  CHECK(has(e, "big.obj: vertex 1: coordinate x = 1e+200 is too large"));
  e = message([&] { sampleMesh(big); });
  CHECK(has(e, "too large"));
  const Mesh unit = testing::icosphere(1, 1.0);
  e = message([&] { measureDistance(big, unit); });
  CHECK(has(e, "first mesh: vertex 1"));
  e = message([&] { measureDistance(unit, big); });
  CHECK(has(e, "second mesh: vertex 1"));
  e = message([&] { checkMesh(big); });
  CHECK(has(e, "too large"));

  // 1e60 is still accepted, sampled with finite points and measured.
  big.vertices *= 1e-140;
  MeasureOptions o;
  o.samplesPerFace = 100;
  const MeshSamples s = sampleMesh(big, o);
  CHECK(s.faceSamples > 0);
  CHECK(s.points.allFinite());

  if (testing::cliPath().empty()) {
    testing::skipPart("the duplexfit CLI is not built");
    return;
  }
  const testing::TempDir dir;
  const std::string path = dir.file("big.obj"), good = dir.file("good.obj");
  REQUIRE(testing::writeFile(path, "v 0 0 0\nv 1e200 0 0\nv 0 1e200 0\nf 1 2 3\n"));
  writeMesh(good, unit);
  const testing::CliRun r = testing::runCli("measure " + path + " " + good);
  INFO(r.out << r.err);
  CHECK(r.status == 1);
  CHECK(has(r.err, path + ": vertex 1: coordinate x = 1e+200 is too large"));
  CHECK(r.out.empty());
}

TEST_CASE("reliability: empty and all-degenerate meshes are not watertight or valid") {
  const MeshTopology empty = analyzeTopology(Mesh{});
  CHECK_FALSE(empty.watertight());

  Mesh flat;  // faces, but every one repeats an index: no edges, no surface
  flat.vertices.resize(3, 3);
  flat.vertices << 0, 0, 0, 1, 0, 0, 0, 1, 0;
  flat.faces.resize(2, 3);
  flat.faces << 0, 0, 1, 1, 2, 2;
  const MeshCheck c = checkMesh(flat);
  CHECK(c.empty());
  CHECK_FALSE(c.watertight);
  CHECK_FALSE(c.valid());
  CHECK_FALSE(c.genusKnown);
  CHECK(c.selfIntersections == 0);
  CHECK(c.selfIntersectionsComplete);

  // A closed mesh is unchanged: not empty, watertight and valid.
  const MeshCheck sphere = checkMesh(testing::icosphere(2, 1.0));
  CHECK_FALSE(sphere.empty());
  CHECK(sphere.watertight);
  CHECK(sphere.selfIntersectionsComplete);
  CHECK(sphere.valid());
}

}  // TEST_SUITE
