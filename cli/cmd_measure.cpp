// `duplexfit measure`: Metro distances between two meshes (forward, backward, symmetric Hausdorff), or the
// accuracy of an offset mesh against its surface; `duplexfit check`: topology, orientation, genus and
// self-intersections of one mesh. Results go to stdout as a table or JSON; progress to stderr.
#include <cstdio>
#include <iomanip>
#include <iostream>
#include <sstream>

#include <nlohmann/json.hpp>

#include "commands.hpp"
#include "options.hpp"
#include "timer.hpp"
#include "duplexfit/error.hpp"
#include "duplexfit/io.hpp"
#include "duplexfit/measure.hpp"

namespace duplexfit::cli {

const char* const kMeasureHelp =
    R"(  measure A B        Metro distance between two meshes: samples of A to B (forward), of B to A
                     (backward), max / mean / RMS and the symmetric Hausdorff distance, also relative
                     to the bounding-box diagonal of B
      --samples N      face samples per triangle on average, plus every vertex (default 10)
      --seed S         seed of the deterministic sampling (default 1)
      --json           machine-readable output
  measure O --offset-of S --delta D
                     accuracy of offset mesh O against surface mesh S for the signed offset D (positive
                     = inward, as in fit): dist(sample, S) and |dist − |D||, max / mean / RMS / p99,
                     relative to |D|, and the share of samples on the wrong side of S
  check MESH         closed, 2-manifold, oriented, outward, components, Euler characteristic, genus,
                     boundary loops, degenerate triangles and self-intersecting triangle pairs
      --json           machine-readable output
      --strict         exit with status 4 unless the mesh is closed, manifold, oriented, outward and
                       free of self-intersections
      --no-intersections  skip the self-intersection test
)";

namespace {

struct LoadedMesh {
  std::string path;
  Mesh mesh;
  MeshValidation validation;
};

LoadedMesh load(const std::string& path, bool quiet) {
  LoadedMesh m;
  m.path = path;
  m.mesh = readMesh(path);
  m.validation = validateMesh(m.mesh, path);
  if (!quiet && m.validation.degenerateFaces() > 0) {
    std::cerr << path << ": " << m.validation.degenerateFaces() << " degenerate triangles (first: face "
              << m.validation.firstDegenerateFace << ")\n";
  }
  return m;
}

std::string num(double v, int precision = 6) {
  std::ostringstream s;
  s << std::setprecision(precision) << v;
  return s.str();
}

std::string percent(double v, double of) {
  if (!(of > 0.0)) return "-";
  std::ostringstream s;
  s << std::fixed << std::setprecision(4) << 100.0 * v / of << " %";
  return s.str();
}

using Json = nlohmann::ordered_json;

Json vec(const Eigen::Vector3d& p) { return Json::array({p.x(), p.y(), p.z()}); }

Json meshJson(const LoadedMesh& m) {
  return Json{{"file", m.path},
              {"vertices", m.validation.vertices},
              {"faces", m.validation.faces},
              {"degenerate_faces", m.validation.degenerateFaces()}};
}

Json statsJson(const SampleStats& s, double relativeTo = 0.0) {
  Json j{{"samples", s.samples}, {"min", s.min}, {"max", s.max}, {"mean", s.mean}, {"rms", s.rms}, {"p99", s.p99}};
  if (relativeTo > 0.0) {
    j["max_rel"] = s.max / relativeTo;
    j["mean_rel"] = s.mean / relativeTo;
    j["rms_rel"] = s.rms / relativeTo;
  }
  j["max_at"] = vec(s.maxAt);
  j["max_closest"] = vec(s.maxClosest);
  return j;
}

void print(const Json& j) { std::cout << j.dump(2, ' ', false, Json::error_handler_t::replace) << "\n"; }

std::string point(const Eigen::Vector3d& p) { return "(" + num(p.x()) + ", " + num(p.y()) + ", " + num(p.z()) + ")"; }

void statsRow(const char* name, const SampleStats& s, double diagonal) {
  std::cout << std::left << std::setw(20) << name << std::right << std::setw(14) << num(s.max) << std::setw(14)
            << num(s.mean) << std::setw(14) << num(s.rms) << std::setw(14) << num(s.p99) << std::setw(12)
            << s.samples << "\n";
  if (diagonal > 0.0) {
    std::cout << std::left << std::setw(20) << "  / diagonal of B" << std::right << std::setw(14)
              << percent(s.max, diagonal) << std::setw(14) << percent(s.mean, diagonal) << std::setw(14)
              << percent(s.rms, diagonal) << std::setw(14) << percent(s.p99, diagonal) << "\n";
  }
}

void header() {
  std::cout << std::left << std::setw(20) << "" << std::right << std::setw(14) << "max" << std::setw(14) << "mean"
            << std::setw(14) << "RMS" << std::setw(14) << "p99" << std::setw(12) << "samples" << "\n";
}

/// --samples and --seed, checked after parsing (checkMeasureOptions).
void addMeasureOptions(CLI::App& app, MeasureOptions& o, long& seed) {
  addNumber(app, "samples", o.samplesPerFace, "face samples per triangle on average, plus every vertex (default 10)");
  addInteger(app, "seed", seed, "seed of the deterministic sampling (default 1)");
}

void checkMeasureOptions(MeasureOptions& o, long seed) {
  if (!(o.samplesPerFace > 0.0)) {
    throw UsageError("--samples must be a positive number of samples per triangle (got " + num(o.samplesPerFace) +
                     ")");
  }
  if (o.samplesPerFace > 1e6) throw UsageError("--samples must be at most 1e6");
  if (seed < 0) throw UsageError("--seed must be a non-negative integer");
  o.seed = static_cast<std::uint64_t>(seed);
}

int measureOffsetCommand(double delta, const std::string& offsetPath, const std::string& surfacePath,
                         const MeasureOptions& options, bool json, bool quiet) {
  if (delta == 0.0) throw UsageError("measure --offset-of needs --delta D (the signed offset, non-zero)");
  const Timer t0;
  const LoadedMesh o = load(offsetPath, quiet);
  const LoadedMesh s = load(surfacePath, quiet);
  const OffsetReport r = measureOffset(o.mesh, s.mesh, delta, options);
  const double seconds = t0.seconds();
  if (!quiet) std::cerr << "measured " << r.samples << " samples in " << num(seconds, 3) << " s\n";
  if (json) {
    Json components = Json::array();
    for (std::size_t i = 0; i < r.components.size() && i < 50; ++i) {
      const OffsetReport::Component& c = r.components[i];
      components.push_back(Json{{"faces", c.faces},
                                {"mean_distance", c.meanDistance},
                                {"mean_deviation", c.meanDeviation},
                                {"max_deviation", c.maxDeviation},
                                {"off_offset", c.offOffset}});
    }
    print(Json{{"mode", "offset"},
               {"offset", meshJson(o)},
               {"surface", meshJson(s)},
               {"delta", delta},
               {"samples_per_face", options.samplesPerFace},
               {"seed", options.seed},
               {"samples", r.samples},
               {"distance", statsJson(r.distance)},
               {"deviation", statsJson(r.deviation)},
               {"relative_distance", statsJson(r.relativeDistance)},
               {"relative_deviation", statsJson(r.relativeDeviation)},
               {"wrong_side", r.wrongSide},
               {"wrong_side_share", r.wrongSideShare},
               {"components", r.components.size()},
               {"off_offset_components", r.offOffsetComponents},
               {"component_list", std::move(components)},
               {"seconds", seconds}});
    return 0;
  }
  std::cout << "offset   " << o.path << " (" << o.validation.vertices << " vertices, " << o.validation.faces
            << " faces)\n"
            << "surface  " << s.path << " (" << s.validation.vertices << " vertices, " << s.validation.faces
            << " faces)\n"
            << "delta    " << num(delta) << (delta > 0 ? " (inward)" : " (outward)") << ", " << r.samples
            << " samples (" << num(options.samplesPerFace) << " per face + vertices, seed " << options.seed << ")\n\n";
  header();
  statsRow("dist(O, S)", r.distance, 0.0);
  statsRow("|dist - |delta||", r.deviation, 0.0);
  statsRow("dist / |delta|", r.relativeDistance, 0.0);
  statsRow("deviation / |delta|", r.relativeDeviation, 0.0);
  std::cout << "\nwrong side of S  " << r.wrongSide << " samples (" << percent(static_cast<double>(r.wrongSide),
                                                                            static_cast<double>(r.samples))
            << ")\n"
            << "largest deviation at " << point(r.deviation.maxAt) << ", closest on S "
            << point(r.deviation.maxClosest) << "\n";
  std::size_t small = 0;
  for (std::size_t i = 1; i < r.components.size(); ++i) small += r.components[i].faces < 100 ? 1 : 0;
  std::cout << "components       " << r.components.size() << " (" << small << " of them under 100 faces), "
            << r.offOffsetComponents << " not on the offset (mean |dist - |delta|| > |delta|/2)\n";
  return 0;
}

}  // namespace

int cmdMeasure(int argc, char** argv) {
  CLI::App app("Metro distance between two meshes, or the accuracy of an offset mesh", "measure");
  bool json = false, quiet = false;
  MeasureOptions options;
  long seed = 1;
  double delta = 0.0;
  std::string surface;
  std::vector<std::string> pos;
  app.add_option("MESHES", pos, "A B, or the offset mesh O with --offset-of");
  addMeasureOptions(app, options, seed);
  app.add_option("--offset-of", surface, "measure O as the offset of this surface mesh")->type_name("S");
  addNumber(app, "delta", delta, "the signed offset of --offset-of (positive = inward, as in fit)");
  addJson(app, json);
  addQuiet(app, quiet);
  if (parse(app, argc, argv)) return 0;
  checkMeasureOptions(options, seed);
  if (!surface.empty()) {
    if (pos.size() != 1) throw UsageError("usage: duplexfit measure OFFSET --offset-of SURFACE --delta D");
    return measureOffsetCommand(delta, pos[0], surface, options, json, quiet);
  }
  if (pos.size() != 2) throw UsageError("usage: duplexfit measure A B [--samples N] [--seed S] [--json]");
  const Timer t0;
  const LoadedMesh a = load(pos[0], quiet);
  const LoadedMesh b = load(pos[1], quiet);
  const DistanceReport r = measureDistance(a.mesh, b.mesh, options);
  const double seconds = t0.seconds();
  if (!quiet) {
    std::cerr << "measured " << r.forward.samples + r.backward.samples << " samples in " << num(seconds, 3)
              << " s\n";
  }
  const double diag = r.diagonalB;
  if (json) {
    print(Json{{"mode", "distance"},
               {"a", meshJson(a)},
               {"b", meshJson(b)},
               {"samples_per_face", options.samplesPerFace},
               {"seed", options.seed},
               {"diagonal_b", diag},
               {"forward", statsJson(r.forward, diag)},
               {"backward", statsJson(r.backward, diag)},
               {"hausdorff", r.hausdorff},
               {"hausdorff_rel", diag > 0.0 ? r.hausdorff / diag : 0.0},
               {"seconds", seconds}});
    return 0;
  }
  std::cout << "A  " << a.path << " (" << a.validation.vertices << " vertices, " << a.validation.faces
            << " faces)\n"
            << "B  " << b.path << " (" << b.validation.vertices << " vertices, " << b.validation.faces
            << " faces, bounding-box diagonal " << num(diag) << ")\n"
            << "sampling: " << num(options.samplesPerFace) << " per face + vertices, seed " << options.seed << "\n\n";
  header();
  statsRow("forward  A -> B", r.forward, diag);
  statsRow("backward B -> A", r.backward, diag);
  std::cout << "\nHausdorff (symmetric)  " << num(r.hausdorff) << " (" << percent(r.hausdorff, diag)
            << " of the diagonal of B)\n";
  const SampleStats& worst = r.forward.max >= r.backward.max ? r.forward : r.backward;
  std::cout << "attained " << (r.forward.max >= r.backward.max ? "forward" : "backward") << " at "
            << point(worst.maxAt) << ", closest point " << point(worst.maxClosest) << "\n";
  return 0;
}

int cmdCheck(int argc, char** argv) {
  CLI::App app("closed, 2-manifold, oriented, outward, genus and self-intersections of a mesh", "check");
  bool json = false, strict = false, quiet = false;
  CheckOptions options;
  std::vector<std::string> pos;
  app.add_option("MESH", pos, "the mesh (PLY, OBJ or STL)");
  addJson(app, json);
  addQuiet(app, quiet);
  app.add_flag("--strict", strict, "exit with status 4 unless the mesh is closed, manifold, oriented, outward and "
                                   "free of self-intersections");
  app.add_flag_callback("--no-intersections", [&] { options.selfIntersections = false; },
                        "skip the self-intersection test");
  if (parse(app, argc, argv)) return 0;
  if (pos.size() != 1) throw UsageError("usage: duplexfit check MESH [--json] [--strict]");
  const Timer t0;
  const LoadedMesh m = load(pos[0], true);
  const MeshCheck c = checkMesh(m.mesh, options);
  const double seconds = t0.seconds();
  if (!quiet) std::cerr << "checked in " << num(seconds, 3) << " s\n";
  const MeshTopology& t = c.topology;
  if (json) {
    Json pairs = Json::array();
    for (const auto& p : c.pairs) pairs.push_back(Json::array({p.first, p.second}));
    print(Json{{"file", m.path},
               {"vertices", t.vertices},
               {"faces", t.faces},
               {"edges", t.edges},
               {"valid", c.valid()},
               {"watertight", c.watertight},
               {"manifold", c.manifold},
               {"oriented", c.oriented},
               {"outward", c.outward},
               {"signed_volume", c.signedVolume},
               {"area", c.area},
               {"components", t.components},
               {"euler_characteristic", t.eulerCharacteristic},
               {"genus", c.genusKnown ? Json(c.genus) : Json()},
               {"boundary_edges", t.boundaryEdges},
               {"boundary_loops", c.boundaryLoops},
               {"non_manifold_edges", t.nonManifoldEdges},
               {"non_manifold_vertices", t.nonManifoldVertices},
               {"inconsistent_edges", t.inconsistentEdges},
               {"degenerate_faces", c.validation.degenerateFaces()},
               {"repeated_index_faces", c.validation.repeatedIndexFaces},
               {"zero_area_faces", c.validation.zeroAreaFaces},
               {"self_intersections_checked", c.selfIntersectionsChecked},
               {"self_intersections", c.selfIntersectionsChecked ? Json(c.selfIntersections) : Json()},
               {"intersecting_pairs", std::move(pairs)},
               {"seconds", seconds}});
  } else {
    auto yes = [](bool b) { return b ? "yes" : "no"; };
    std::cout << "mesh                   " << m.path << "\n"
              << "vertices/edges/faces   " << t.vertices << " / " << t.edges << " / " << t.faces << "\n"
              << "watertight             " << yes(c.watertight) << " (" << t.boundaryEdges << " boundary edges in "
              << c.boundaryLoops << " loops)\n"
              << "2-manifold             " << yes(c.manifold) << " (" << t.nonManifoldEdges << " non-manifold edges, "
              << t.nonManifoldVertices << " non-manifold vertices)\n"
              << "consistently oriented  " << yes(c.oriented) << " (" << t.inconsistentEdges
              << " inconsistent edges)\n"
              << "outward                " << yes(c.outward) << " (signed volume " << num(c.signedVolume) << ", area "
              << num(c.area) << ")\n"
              << "components             " << t.components << "\n"
              << "Euler characteristic   " << t.eulerCharacteristic << "\n"
              << "genus                  " << (c.genusKnown ? std::to_string(c.genus) : std::string("-")) << "\n"
              << "degenerate triangles   " << c.validation.degenerateFaces() << " ("
              << c.validation.repeatedIndexFaces << " repeated index, " << c.validation.zeroAreaFaces
              << " zero area)\n"
              << "self-intersections     "
              << (c.selfIntersectionsChecked ? std::to_string(c.selfIntersections) + " triangle pairs"
                                             : std::string("not checked"))
              << "\n";
    if (!c.pairs.empty()) {
      std::cout << "  first pairs:";
      for (const auto& p : c.pairs) std::cout << " (" << p.first << ", " << p.second << ")";
      std::cout << "\n";
    }
    std::cout << "verdict                " << (c.valid() ? "valid closed oriented manifold" : "not valid") << "\n";
  }
  return strict && !c.valid() ? kNumerical : 0;
}

}  // namespace duplexfit::cli
