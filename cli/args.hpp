// Command-line option parsing shared by the duplexfit subcommands: --key value, --key=value and --flag.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <map>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

namespace duplexfit::cli {

/// A usage mistake: the CLI prints it and exits with status 1.
class UsageError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};


/// A comma-separated list of finite numbers ("0.1,-0.05"), for option --`option`.
inline std::vector<double> parseNumberList(const std::string& text, const char* option) {
  if (text.empty()) throw UsageError(std::string("option --") + option + " needs at least one value");
  std::vector<double> out;
  std::size_t begin = 0;
  while (begin <= text.size()) {
    const std::size_t end = std::min(text.find(',', begin), text.size());
    const std::string item = text.substr(begin, end - begin);
    char* stop = nullptr;
    const double v = std::strtod(item.c_str(), &stop);
    if (item.empty() || stop == item.c_str() || *stop != '\0' || !std::isfinite(v)) {
      throw UsageError(std::string("option --") + option + ": '" + item + "' is not a number");
    }
    out.push_back(v);
    begin = end + 1;
  }
  return out;
}

/// Options as --key value / --key=value pairs and bare --flags.
class Args {
 public:
  Args(int argc, char** argv, int first, const std::vector<std::string>& valued) {
    for (int i = first; i < argc; ++i) {
      std::string a = argv[i];
      if (a.rfind("--", 0) != 0 || a == "--") {
        if (a == "-o" && i + 1 < argc) {  // the one short option: -o OUT
          values_["output"] = argv[++i];
          continue;
        }
        positional_.push_back(a);
        continue;
      }
      std::string key = a.substr(2), value;
      const auto eq = key.find('=');
      if (eq != std::string::npos) {
        value = key.substr(eq + 1);
        key = key.substr(0, eq);
      } else if (std::find(valued.begin(), valued.end(), key) != valued.end()) {
        if (i + 1 >= argc) throw UsageError("option --" + key + " needs a value");
        value = argv[++i];
      } else {
        value = "1";
      }
      values_[key] = value;
    }
  }
  bool flag(const std::string& k) { return take(k).has_value(); }
  std::string str(const std::string& k, const std::string& def) { return take(k).value_or(def); }
  double num(const std::string& k, double def) {
    const auto v = take(k);
    if (!v) return def;
    char* end = nullptr;
    const double d = std::strtod(v->c_str(), &end);
    if (end == v->c_str() || *end != '\0' || !std::isfinite(d)) {
      throw UsageError("option --" + k + ": '" + *v + "' is not a number");
    }
    return d;
  }
  long integer(const std::string& k, long def) {
    const double d = num(k, static_cast<double>(def));
    if (d != std::floor(d)) throw UsageError("option --" + k + " must be an integer");
    return static_cast<long>(d);
  }
  /// Rejects options nobody asked for (typos) and surplus positional arguments.
  void finish(std::size_t maxPositional = 0) const {
    if (!values_.empty()) throw UsageError("unknown option --" + values_.begin()->first);
    if (positional_.size() > maxPositional) throw UsageError("unexpected argument '" + positional_[maxPositional] + "'");
  }
  const std::vector<std::string>& positional() const { return positional_; }

 private:
  std::optional<std::string> take(const std::string& k) {
    const auto it = values_.find(k);
    if (it == values_.end()) return std::nullopt;
    std::string v = it->second;
    values_.erase(it);
    return v;
  }
  std::map<std::string, std::string> values_;
  std::vector<std::string> positional_;
};

/// Exit codes (README): 1 usage, 2 I/O, 3 device, 4 numerical failure with --strict.
constexpr int kUsage = 1, kIo = 2, kDevice = 3, kNumerical = 4;

}  // namespace duplexfit::cli
