// Option parsing with CLI11 for the duplexfit subcommands: the shared option groups (device + precision,
// quiet, json, strict), finite numbers and integers with the CLI's messages, and parse(), which turns
// every parse problem into a UsageError (exit status 1) and --help into the command's help text.
#pragma once

#include <CLI/CLI.hpp>
#include <algorithm>
#include <cctype>
#include <filesystem>

#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include "args.hpp"
#include "duplexfit/error.hpp"
#include "duplexfit/mesh_finish.hpp"
#include "duplexfit/polygonize.hpp"
#include "duplexfit/resources.hpp"
#include "duplexfit/surfaces.hpp"
#include "duplexfit/types.hpp"

namespace duplexfit::cli {

/// --device SPEC and --precision float|double.
struct DeviceOptions {
  std::string spec;
  Precision precision = Precision::Float;
};

inline void addDeviceOptions(CLI::App& app, DeviceOptions& o) {
  app.add_option("--device", o.spec,
                 "ref | P:D | cpu | gpu | name substring (default: $DUPLEXFIT_DEVICE, else first GPU, else first "
                 "CPU OpenCL device, else ref)")
      ->type_name("SPEC")
      ->group("Device");
  app.add_option_function<std::string>(
         "--precision", [&o](const std::string& v) { o.precision = parsePrecision(v.c_str()); },
         "float (default) or double")
      ->type_name("P")
      ->group("Device");
}

inline void addQuiet(CLI::App& app, bool& quiet) {
  app.add_flag("--quiet", quiet, "no progress on stderr")->group("Output");
}
inline void addJson(CLI::App& app, bool& json, const std::string& what = "machine-readable output on stdout") {
  app.add_flag("--json", json, what)->group("Output");
}

/// --max-memory SIZE (8G, 512M, 1.5GiB, bytes) into `limits`: the memory budget the command's estimates are
/// checked against before it allocates. Without the option: $DUPLEXFIT_MAX_MEMORY, else 75% of the
/// machine's memory (defaultMaxMemoryBytes). A bad value of either is a usage error naming it.
inline void addMaxMemory(CLI::App& app, ResourceLimits& limits) {
  const auto parseSize = [](const std::string& text, const std::string& what) {
    try {
      return parseByteSize(text, what);
    } catch (const InvalidArgument& e) {
      throw UsageError(e.what());
    }
  };
  CLI::Option* option = app.add_option_function<std::string>(
                               "--max-memory",
                               [&limits, parseSize](const std::string& v) {
                                 limits.maxMemoryBytes = parseSize(v, "option --max-memory");
                               },
                               "memory budget of the estimates checked before allocating: 8G, 512M, 1.5GiB or bytes "
                               "(default: $DUPLEXFIT_MAX_MEMORY, else 75% of the machine's memory, " +
                                   formatBytes(static_cast<double>(defaultMaxMemoryBytes())) + " here)")
                               ->type_name("SIZE")
                               ->group("Limits");
  app.parse_complete_callback([&limits, option, parseSize] {
    const char* env = std::getenv("DUPLEXFIT_MAX_MEMORY");
    if (option->count() == 0 && env != nullptr && *env != '\0') {
      limits.maxMemoryBytes = parseSize(env, "DUPLEXFIT_MAX_MEMORY");
    }
  });
}

/// A finite number (strtod over the whole text), as Args::num: "option --name: 'x' is not a number".
inline double parseFinite(const std::string& text, const std::string& name) {
  char* end = nullptr;
  const double d = std::strtod(text.c_str(), &end);
  if (text.empty() || end == text.c_str() || *end != '\0' || !std::isfinite(d)) {
    throw UsageError("option --" + name + ": '" + text + "' is not a number");
  }
  return d;
}

/// --name NUMBER into `target` (left unchanged when the option is absent).
inline CLI::Option* addNumber(CLI::App& app, const std::string& name, double& target, const std::string& help) {
  return app.add_option_function<std::string>(
                "--" + name, [&target, name](const std::string& v) { target = parseFinite(v, name); }, help)
      ->type_name("X");
}

/// --name N: a number that must be integral ("option --name must be an integer").
template <typename Int>
CLI::Option* addInteger(CLI::App& app, const std::string& name, Int& target, const std::string& help) {
  return app.add_option_function<std::string>(
                "--" + name,
                [&target, name](const std::string& v) {
                  const double d = parseFinite(v, name);
                  if (d != std::floor(d) || std::abs(d) > 1e15) throw UsageError("option --" + name + " must be an integer");
                  // No narrowing: a value the option's type cannot hold is an error, not a wrapped number.
                  if (d < static_cast<double>(std::numeric_limits<Int>::min()) ||
                      d > static_cast<double>(std::numeric_limits<Int>::max())) {
                    throw UsageError("option --" + name + " is out of range (" +
                                     std::to_string(std::numeric_limits<Int>::min()) + " to " +
                                     std::to_string(std::numeric_limits<Int>::max()) + ")");
                  }
                  target = static_cast<Int>(d);
                },
                help)
      ->type_name("N");
}

/// --name F: an area fraction in [0, 1) (--min-component, --min-offset-component).
inline CLI::Option* addFraction(CLI::App& app, const std::string& name, double& target, const std::string& help) {
  return app.add_option_function<std::string>(
                "--" + name,
                [&target, name](const std::string& v) {
                  const double f = parseFinite(v, name);
                  if (!(f >= 0.0 && f < 1.0)) throw UsageError("--" + name + " must be an area fraction in [0, 1)");
                  target = f;
                },
                help)
      ->type_name("F");
}

/// --drain-hole SPEC, repeatable (every occurrence is kept): x,y,z,r or auto[,r] (parseDrainHoleSpec).
inline void addDrainHoles(CLI::App& app, std::vector<std::string>& specs) {
  app.add_option("--drain-hole", specs, "drain hole: vertical cylinder of radius r from (x,y,z) down (repeatable)")
      ->type_name("X,Y,Z,R")
      ->expected(1)
      ->multi_option_policy(CLI::MultiOptionPolicy::TakeAll);
}

/// INPUT -o OUT and the shared groups of the cloud-in, cloud-out commands (denoise, normals).
struct CloudJobArgs {
  bool quiet = false;
  bool json = false;
  std::string input, output;
  DeviceOptions device;
};

inline void addCloudJobArgs(CLI::App& app, CloudJobArgs& c) {
  app.add_option("INPUT", c.input, "input cloud (PLY or XYZ)");
  app.add_option("-o,--output", c.output, "output cloud (binary PLY with normals; required)")->type_name("OUT");
  addDeviceOptions(app, c.device);
  addQuiet(app, c.quiet);
  addJson(app, c.json, "summary with parameters and timings on stdout");
}

/// Both INPUT and -o OUT were given.
inline void requireCloudJobArgs(const CloudJobArgs& c, const char* command) {
  if (c.input.empty()) {
    throw UsageError(std::string(command) + " needs an input cloud: duplexfit " + command + " INPUT -o OUT");
  }
  if (c.output.empty()) throw UsageError(std::string(command) + " needs an output file: -o OUT");
}

/// --name N, an integer in [1, max].
inline void addPositiveInt(CLI::App& app, const std::string& name, int& target, int max, const std::string& help) {
  addInteger(app, name, target, help)->check([name, max](const std::string& v) {
    const double d = parseFinite(v, name);
    if (d < 1 || d > max) throw UsageError("option --" + name + " must be between 1 and " + std::to_string(max));
    return std::string();
  });
}

/// --name L, a length ≥ 0 (0: the rule's default).
inline void addLength(CLI::App& app, const std::string& name, double& target, const std::string& help) {
  addNumber(app, name, target, help)->check([name](const std::string& v) {
    if (parseFinite(v, name) < 0.0) throw UsageError("option --" + name + " must be positive");
    return std::string();
  });
}

/// --max-triangles N, --max-error E and --no-clean of fit and mesh (SurfaceOptions::finish).
inline void addMeshFinishOptions(CLI::App& app, MeshFinishOptions& o) {
  app.add_option_function<std::string>(
         "--max-triangles",
         [&o](const std::string& v) {
           const double d = parseFinite(v, "max-triangles");
           if (d != std::floor(d) || d < 4 || d > 2e9) throw UsageError("option --max-triangles must be an integer >= 4");
           o.simplify.maxTriangles = static_cast<std::size_t>(d);
         },
         "simplify every mesh to at most N triangles (meshoptimizer)")
      ->type_name("N");
  addLength(app, "max-error", o.simplify.maxError, "simplify every mesh within E input units (meshoptimizer)");
  app.add_flag_callback("--no-clean", [&o] { o.clean = false; }, "keep slivers and float32-degenerate triangles");
  app.add_flag_callback("--no-project", [&o] { o.project = false; },
                        "leave the vertices where the grid put them (no projection onto the level set, no splits)");
  app.add_flag_callback("--evaluate-centres", [&o] { o.predictCentres = false; },
                        "evaluate every face centre in the projection's first round instead of predicting most of "
                        "them from the vertices' tangent planes (slower; sees detail smaller than a triangle)");
  app.add_flag_callback("--fast-projection", [&o] { o.predictCentres = true; },
                        "predict most face centres from the vertices' tangent planes (the default; kept for scripts)");
  app.add_option_function<std::string>(
         "--deviation-samples",
         [&o](const std::string& v) {
           const double d = parseFinite(v, "deviation-samples");
           if (d != std::floor(d) || d < 0 || d > 1e10) {
             throw UsageError("option --deviation-samples must be an integer >= 0 (0: every vertex and face)");
           }
           o.deviationSamples = static_cast<std::size_t>(d);
         },
         "samples of each mesh's level-set deviation in report.json (default 100000; 0: every vertex and face centre)")
      ->type_name("N");
}

/// --refine-levels N of fit and mesh (PolygonizeOptions::refineLevels), --refine-dilation N,
/// --refine-tolerance F (SurfaceOptions::refineTolerance) and --no-neck-pass (SurfaceOptions::neckPassMaxFaces).
inline void addRefineOptions(CLI::App& app, SurfaceOptions& surface) {
  PolygonizeOptions& o = surface.polygonize;
  app.add_flag_callback("--no-neck-pass", [&surface] { surface.neckPassMaxFaces = 0; },
                        "do not extract a level set again where its mesh stays farther than 0.1% of the largest side "
                        "from it (the neck pass: the cells there refined one level more; meshes up to 2M triangles)");
  addNumber(app, "refine-tolerance", surface.refineTolerance,
            "refine only where the grid's contour is farther than F of the largest side from the level set (default "
            "5e-4; 0: every cell with a layer one node thick)")
      ->check([](const std::string& v) {
        const double d = parseFinite(v, "refine-tolerance");
        if (d < 0 || d > 1) throw UsageError("option --refine-tolerance must be between 0 and 1");
        return std::string();
      });
  addInteger(app, "refine-levels", o.refineLevels,
             "contour cells where the grid is too coarse for the field (a plate or gap about one node thick) on a "
             "grid 2^N times finer, N = 0..3 (default 2; 0: off)")
      ->check([](const std::string& v) {
        const double d = parseFinite(v, "refine-levels");
        if (d != std::floor(d) || d < 0 || d > 3) throw UsageError("option --refine-levels must be 0, 1, 2 or 3");
        return std::string();
      });
  addInteger(app, "refine-dilation", o.refineDilation,
             "refine the cells within N cells of such a cell too, N = 0..4 (default 1)")
      ->check([](const std::string& v) {
        const double d = parseFinite(v, "refine-dilation");
        if (d != std::floor(d) || d < 0 || d > 4) throw UsageError("option --refine-dilation must be 0 to 4");
        return std::string();
      });
}

/// The missing folders above an output file (mesh, section, denoise, normals -o a/b/out.ply), created
/// as fit and slice create their output folder; removed again (when still empty) unless keep() was
/// called, so that a failed command leaves nothing behind.
class OutputFolders {
 public:
  explicit OutputFolders(const std::filesystem::path& folder) {
    namespace fs = std::filesystem;
    std::error_code ec;
    for (fs::path p = folder; !p.empty() && !fs::exists(p, ec); p = p.parent_path()) {
      created_.push_back(p);
      if (p == p.parent_path()) break;
    }
    if (created_.empty()) return;
    fs::create_directories(folder, ec);
    if (ec || !fs::is_directory(folder)) {
      throw IoError(folder.string() + ": cannot create the output folder (" + ec.message() + ")");
    }
  }
  /// For an output file: the folder it lies in.
  static OutputFolders forFile(const std::string& file) { return OutputFolders(std::filesystem::path(file).parent_path()); }
  OutputFolders(OutputFolders&&) = default;
  OutputFolders(const OutputFolders&) = delete;
  OutputFolders& operator=(const OutputFolders&) = delete;
  OutputFolders& operator=(OutputFolders&&) = delete;
  ~OutputFolders() {
    if (kept_) return;
    std::error_code ec;
    for (const auto& p : created_) std::filesystem::remove(p, ec);  // deepest first; only empty ones go
  }
  void keep() { kept_ = true; }

 private:
  std::vector<std::filesystem::path> created_;
  bool kept_ = false;
};

/// -o of the commands that write a folder (fit, slice): refuses a name that looks like a file ("out.ply")
/// and is not an existing folder, instead of making a folder of that name.
inline void checkOutputFolderName(const std::string& dir, const char* command) {
  namespace fs = std::filesystem;
  const fs::path p(dir);
  std::string ext = p.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  static const char* const kFileTypes[] = {".ply", ".obj", ".stl", ".3mf", ".dpxf", ".json", ".png", ".svg",
                                           ".cli", ".xyz", ".txt", ".zip", ".sl1"};
  std::error_code ec;
  if (fs::is_directory(p, ec)) return;
  for (const char* t : kFileTypes) {
    if (ext == t) {
      throw UsageError(std::string(command) + " writes several files into a folder: -o names that folder, and '" + dir +
                       "' looks like a file name (use e.g. -o " + p.parent_path().append(p.stem().string()).string() +
                       ")");
    }
  }
}

/// What a finished mesh's summary line says of its self-intersections: the pairs the projection's undo
/// left (with a face it moved or moved back), when there are any.
inline std::string crossingNote(const duplexfit::ProjectReport& p) {
  if (!p.selfIntersectionsChecked || p.selfIntersectionsLeft == 0) return "";
  return ", " + std::to_string(p.selfIntersectionsLeft) + " self-intersecting triangle pair(s) left by the projection";
}

/// The candidate nearest to `word` by edit distance (insertions, deletions, substitutions and swaps of
/// neighbours), when it is close enough to be a typo: at most 1 edit for words up to 4 letters, 2 up to
/// 8, 3 beyond; or a candidate that starts with `word` (an abbreviation). Empty when none is.
inline std::string nearestWord(const std::string& word, const std::vector<std::string>& candidates) {
  const auto distance = [](const std::string& a, const std::string& b) {
    std::vector<std::vector<std::size_t>> d(a.size() + 1, std::vector<std::size_t>(b.size() + 1));
    for (std::size_t i = 0; i <= a.size(); ++i) d[i][0] = i;
    for (std::size_t j = 0; j <= b.size(); ++j) d[0][j] = j;
    for (std::size_t i = 1; i <= a.size(); ++i) {
      for (std::size_t j = 1; j <= b.size(); ++j) {
        d[i][j] = std::min({d[i - 1][j] + 1, d[i][j - 1] + 1, d[i - 1][j - 1] + (a[i - 1] == b[j - 1] ? 0 : 1)});
        if (i > 1 && j > 1 && a[i - 1] == b[j - 2] && a[i - 2] == b[j - 1]) d[i][j] = std::min(d[i][j], d[i - 2][j - 2] + 1);
      }
    }
    return d[a.size()][b.size()];
  };
  const std::size_t allowed = word.size() <= 4 ? 1 : word.size() <= 8 ? 2 : 3;
  std::string best;
  std::size_t bestDistance = allowed + 1;
  for (const std::string& c : candidates) {
    const std::size_t dist = distance(word, c);
    if (dist < bestDistance) {
      bestDistance = dist;
      best = c;
    }
  }
  if (best.empty() && word.size() >= 3) {
    for (const std::string& c : candidates) {
      if (c.rfind(word, 0) == 0) return c;
    }
  }
  return best;
}

/// "unknown option --ofset (did you mean --offset?)": the nearest long option of the command.
inline std::string unknownOptionMessage(const CLI::App& app, const std::string& option) {
  std::vector<std::string> names;
  for (const CLI::Option* o : app.get_options()) {
    for (const std::string& n : o->get_lnames()) names.push_back(n);
  }
  const std::string bare = option.substr(option.find_first_not_of('-'));
  const std::string near = nearestWord(bare, names);
  return "unknown option " + option + (near.empty() ? "" : " (did you mean --" + near + "?)") +
         "; duplexfit " + app.get_name() + " --help lists its options";
}

/// Parses the command's arguments (argv[0] is the command's name). Returns true when --help was printed
/// (the command then exits 0). Unknown options, surplus arguments and missing values are UsageErrors
/// worded as before CLI11 ("unknown option --x", "unexpected argument 'x'", "option --x needs a value"),
/// and an option given twice takes its last value, as before;
/// CLI11's other errors keep its wording and point to the command's --help.
inline bool parse(CLI::App& app, int argc, char** argv) {
  app.allow_extras();
  // An option given twice: the last one counts (as before CLI11), instead of CLI11's error; repeatable
  // options (TakeAll, addDrainHoles) keep every occurrence.
  for (CLI::Option* option : app.get_options()) {
    if (option->nonpositional() && option->get_multi_option_policy() != CLI::MultiOptionPolicy::TakeAll) {
      option->multi_option_policy(CLI::MultiOptionPolicy::TakeLast);
    }
  }
  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp&) {
    std::cout << app.help();
    return true;
  } catch (const CLI::ArgumentMismatch& e) {
    // "--offset: 1 required D missing": worded as before CLI11.
    const std::string what = e.what();
    const std::size_t colon = what.find(':');
    if (colon != std::string::npos && what.find("required", colon) != std::string::npos &&
        what.find("missing", colon) != std::string::npos) {
      throw UsageError("option " + what.substr(0, colon) + " needs a value");
    }
    throw UsageError(what + " (try duplexfit " + app.get_name() + " --help)");
  } catch (const CLI::ParseError& e) {
    throw UsageError(std::string(e.what()) + " (try duplexfit " + app.get_name() + " --help)");
  }
  for (const std::string& extra : app.remaining()) {
    if (extra.rfind("--", 0) == 0 && extra.size() > 2) {
      throw UsageError(unknownOptionMessage(app, extra.substr(0, extra.find('='))));
    }
    if (extra.size() > 1 && extra[0] == '-' && extra != "-") throw UsageError(unknownOptionMessage(app, extra));
  }
  if (!app.remaining().empty()) throw UsageError("unexpected argument '" + app.remaining().front() + "'");
  return false;
}

}  // namespace duplexfit::cli
