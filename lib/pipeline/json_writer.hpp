// A minimal JSON writer for the reports (objects, arrays, strings, numbers).
#pragma once

#include <cmath>
#include <cstdio>
#include <ostream>
#include <string>
#include <string_view>

namespace duplexfit::detail {

/// Writes JSON incrementally; the caller nests begin/end calls correctly.
class JsonWriter {
 public:
  explicit JsonWriter(std::ostream& out) : out_(out) {}
  JsonWriter& beginObject() { return open('{'); }
  JsonWriter& endObject() { return close('}'); }
  JsonWriter& beginArray() { return open('['); }
  JsonWriter& endArray() { return close(']'); }
  JsonWriter& key(std::string_view k) {
    separator();
    string(k);
    out_ << ": ";
    afterKey_ = true;
    return *this;
  }
  JsonWriter& value(std::string_view s) {
    separator();
    string(s);
    return *this;
  }
  JsonWriter& value(const char* s) { return value(std::string_view(s)); }
  JsonWriter& null() {
    separator();
    out_ << "null";
    return *this;
  }
  JsonWriter& value(bool b) {
    separator();
    out_ << (b ? "true" : "false");
    return *this;
  }
  JsonWriter& value(double d) {
    separator();
    if (std::isfinite(d)) {
      char buf[32];
      std::snprintf(buf, sizeof buf, "%.10g", d);
      out_ << buf;
    } else {
      out_ << "null";
    }
    return *this;
  }
  template <typename Int, typename = std::enable_if_t<std::is_integral_v<Int>>>
  JsonWriter& value(Int i) {
    separator();
    out_ << i;
    return *this;
  }
  template <typename T>
  JsonWriter& field(std::string_view k, const T& v) {
    key(k);
    return value(v);
  }

 private:
  JsonWriter& open(char c) {
    separator();
    out_ << c;
    ++depth_;
    first_ = true;
    return *this;
  }
  JsonWriter& close(char c) {
    --depth_;
    out_ << '\n' << std::string(2 * static_cast<std::size_t>(depth_), ' ') << c;
    first_ = false;
    if (depth_ == 0) out_ << '\n';
    return *this;
  }
  void separator() {
    if (afterKey_) {
      afterKey_ = false;
      return;
    }
    if (depth_ > 0) {
      if (!first_) out_ << ',';
      out_ << '\n' << std::string(2 * static_cast<std::size_t>(depth_), ' ');
    }
    first_ = false;
  }
  void string(std::string_view s) {
    out_ << '"';
    for (const char ch : s) {
      const auto c = static_cast<unsigned char>(ch);
      if (c == '"' || c == '\\') {
        out_ << '\\' << ch;
      } else if (c < 0x20) {
        char buf[8];
        std::snprintf(buf, sizeof buf, "\\u%04x", c);
        out_ << buf;
      } else {
        out_ << ch;
      }
    }
    out_ << '"';
  }

  std::ostream& out_;
  int depth_ = 0;
  bool first_ = true;
  bool afterKey_ = false;
};

}  // namespace duplexfit::detail
