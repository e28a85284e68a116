// Option parsing with CLI11 for the duplexfit subcommands: the shared option groups (device + precision,
// quiet, json, strict), finite numbers and integers with the CLI's messages, and parse(), which turns
// every parse problem into a UsageError (exit status 1) and --help into the command's help text.
#pragma once

#include <CLI/CLI.hpp>

#include <string>
#include <vector>

#include "args.hpp"
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

/// Parses the command's arguments (argv[0] is the command's name). Returns true when --help was printed
/// (the command then exits 0). Unknown options, surplus arguments and missing values are UsageErrors
/// worded as before CLI11 ("unknown option --x", "unexpected argument 'x'", "option --x needs a value"),
/// and an option given twice takes its last value, as before;
/// CLI11's other errors keep its wording and point to the command's --help.
inline bool parse(CLI::App& app, int argc, char** argv) {
  app.allow_extras();
  // An option given twice: the last one counts (as before CLI11), instead of CLI11's error.
  for (CLI::Option* option : app.get_options()) {
    if (option->nonpositional()) option->multi_option_policy(CLI::MultiOptionPolicy::TakeLast);
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
      throw UsageError("unknown option " + extra.substr(0, extra.find('=')));
    }
    if (extra.size() > 1 && extra[0] == '-' && extra != "-") throw UsageError("unknown option " + extra);
  }
  if (!app.remaining().empty()) throw UsageError("unexpected argument '" + app.remaining().front() + "'");
  return false;
}

}  // namespace duplexfit::cli
