// The JSON that the commands write (report.json, slices.json, --json output) read back with nlohmann-json:
// parse failures fail the test case, lookups by JSON pointer give null (or NaN) when a value is missing,
// so that a check on a missing value fails instead of throwing. Header-only: nlohmann-json is linked to
// the test binary only.
#pragma once

#include <doctest/doctest.h>

#include <cmath>
#include <filesystem>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "temp_dir.hpp"

namespace duplexfit::testing {

using Json = nlohmann::json;

/// `text` parsed as JSON; the calling test case stops (REQUIRE) when it is not JSON.
inline Json parseJson(const std::string& text) {
  Json doc = Json::parse(text, nullptr, /*allow_exceptions=*/false);
  REQUIRE_MESSAGE(!doc.is_discarded(), "not JSON: " << text);
  return doc;
}

/// The file at `path` parsed as JSON (as parseJson).
inline Json readJsonFile(const std::filesystem::path& path) {
  INFO("JSON file " << path.string());
  return parseJson(readFile(path));
}

/// The value at a JSON pointer ("/self_check/ok"), or null when there is none.
inline Json jsonAt(const Json& doc, const std::string& pointer) {
  const Json::json_pointer p(pointer);
  return doc.contains(p) ? doc.at(p) : Json();
}

/// The number at a JSON pointer, or NaN when there is no number there.
inline double jsonNumber(const Json& doc, const std::string& pointer) {
  const Json v = jsonAt(doc, pointer);
  return v.is_number() ? v.get<double>() : std::nan("");
}

/// Every value stored under `key` anywhere in `doc` (in objects at any depth, inside arrays too).
inline std::vector<Json> jsonValuesOf(const Json& doc, const std::string& key) {
  std::vector<Json> found;
  if (doc.is_object()) {
    for (auto it = doc.begin(); it != doc.end(); ++it) {
      if (it.key() == key) found.push_back(it.value());
      const std::vector<Json> below = jsonValuesOf(it.value(), key);
      found.insert(found.end(), below.begin(), below.end());
    }
  } else if (doc.is_array()) {
    for (const Json& e : doc) {
      const std::vector<Json> below = jsonValuesOf(e, key);
      found.insert(found.end(), below.begin(), below.end());
    }
  }
  return found;
}

}  // namespace duplexfit::testing
