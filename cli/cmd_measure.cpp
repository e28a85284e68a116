// `duplexfit measure`: Metro distances between two meshes (forward, backward, symmetric Hausdorff), or the
// accuracy of an offset mesh against its surface; `duplexfit check`: topology, orientation, genus and
// self-intersections of one mesh. Results go to stdout as a table or JSON; progress to stderr.
#include <cstdio>
#include <iomanip>
#include <iostream>
#include <sstream>

#include "commands.hpp"
#include "options.hpp"
#include "timer.hpp"
#include "duplexfit/error.hpp"
#include "duplexfit/io.hpp"
#include "duplexfit/measure.hpp"
#include "json.hpp"

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

void vec(JsonWriter& w, const char* key, const Eigen::Vector3d& p) {
  w.key(key).beginArray().value(p.x()).value(p.y()).value(p.z()).endArray();
}

void meshJson(JsonWriter& w, const char* key, const LoadedMesh& m) {
  w.key(key)
      .beginObject()
      .field("file", m.path)
      .field("vertices", m.validation.vertices)
      .field("faces", m.validation.faces)
      .field("degenerate_faces", m.validation.degenerateFaces())
      .endObject();
}

void statsJson(JsonWriter& w, const char* key, const SampleStats& s, double relativeTo = 0.0) {
  w.key(key)
      .beginObject()
      .field("samples", s.samples)
      .field("min", s.min)
      .field("max", s.max)
      .field("mean", s.mean)
      .field("rms", s.rms)
      .field("p99", s.p99);
  if (relativeTo > 0.0) {
    w.field("max_rel", s.max / relativeTo).field("mean_rel", s.mean / relativeTo).field("rms_rel", s.rms / relativeTo);
  }
  vec(w, "max_at", s.maxAt);
  vec(w, "max_closest", s.maxClosest);
  w.endObject();
}

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
    JsonWriter w(std::cout);
    w.beginObject().field("mode", "offset");
    meshJson(w, "offset", o);
    meshJson(w, "surface", s);
    w.field("delta", delta)
        .field("samples_per_face", options.samplesPerFace)
        .field("seed", options.seed)
        .field("samples", r.samples);
    statsJson(w, "distance", r.distance);
    statsJson(w, "deviation", r.deviation);
    statsJson(w, "relative_distance", r.relativeDistance);
    statsJson(w, "relative_deviation", r.relativeDeviation);
    w.field("wrong_side", r.wrongSide).field("wrong_side_share", r.wrongSideShare);
    w.field("components", r.components.size()).field("off_offset_components", r.offOffsetComponents);
    w.key("component_list").beginArray();
    for (std::size_t i = 0; i < r.components.size() && i < 50; ++i) {
      const OffsetReport::Component& c = r.components[i];
      w.beginObject().field("faces", c.faces).field("mean_distance", c.meanDistance);
      w.field("mean_deviation", c.meanDeviation).field("max_deviation", c.maxDeviation);
      w.field("off_offset", c.offOffset).endObject();
    }
    w.endArray().field("seconds", seconds);
    w.endObject();
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
    JsonWriter w(std::cout);
    w.beginObject().field("mode", "distance");
    meshJson(w, "a", a);
    meshJson(w, "b", b);
    w.field("samples_per_face", options.samplesPerFace).field("seed", options.seed).field("diagonal_b", diag);
    statsJson(w, "forward", r.forward, diag);
    statsJson(w, "backward", r.backward, diag);
    w.field("hausdorff", r.hausdorff).field("hausdorff_rel", diag > 0.0 ? r.hausdorff / diag : 0.0);
    w.field("seconds", seconds).endObject();
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
    JsonWriter w(std::cout);
    w.beginObject()
        .field("file", m.path)
        .field("vertices", t.vertices)
        .field("faces", t.faces)
        .field("edges", t.edges)
        .field("valid", c.valid())
        .field("watertight", c.watertight)
        .field("manifold", c.manifold)
        .field("oriented", c.oriented)
        .field("outward", c.outward)
        .field("signed_volume", c.signedVolume)
        .field("area", c.area)
        .field("components", t.components)
        .field("euler_characteristic", t.eulerCharacteristic)
        .key("genus");
    if (c.genusKnown) {
      w.value(c.genus);
    } else {
      w.value(std::numeric_limits<double>::quiet_NaN());  // null
    }
    w.field("boundary_edges", t.boundaryEdges)
        .field("boundary_loops", c.boundaryLoops)
        .field("non_manifold_edges", t.nonManifoldEdges)
        .field("non_manifold_vertices", t.nonManifoldVertices)
        .field("inconsistent_edges", t.inconsistentEdges)
        .field("degenerate_faces", c.validation.degenerateFaces())
        .field("repeated_index_faces", c.validation.repeatedIndexFaces)
        .field("zero_area_faces", c.validation.zeroAreaFaces)
        .field("self_intersections_checked", c.selfIntersectionsChecked);
    w.key("self_intersections");
    if (c.selfIntersectionsChecked) {
      w.value(c.selfIntersections);
    } else {
      w.value(std::numeric_limits<double>::quiet_NaN());
    }
    w.key("intersecting_pairs").beginArray();
    for (const auto& p : c.pairs) w.beginArray().value(p.first).value(p.second).endArray();
    w.endArray().field("seconds", seconds).endObject();
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
