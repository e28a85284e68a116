// PLY header parsing and element-by-element body reading. Every count read from the file is checked
// against the bytes left before anything is allocated or looped over, so garbage cannot hang or
// exhaust memory.
#include "ply.hpp"

#include <cmath>
#include <cstring>
#include <limits>

namespace duplexfit::io {

namespace {

constexpr std::size_t kMaxHeaderLine = std::size_t{1} << 16;
constexpr std::size_t kMaxBodyLine = std::size_t{1} << 26;

bool parseType(std::string_view name, PlyType& type) {
  struct Entry {
    const char* a;
    const char* b;
    PlyType type;
  };
  static const Entry table[] = {
      {"char", "int8", PlyType::Int8},        {"uchar", "uint8", PlyType::UInt8},
      {"short", "int16", PlyType::Int16},     {"ushort", "uint16", PlyType::UInt16},
      {"int", "int32", PlyType::Int32},       {"uint", "uint32", PlyType::UInt32},
      {"float", "float32", PlyType::Float32}, {"double", "float64", PlyType::Float64}};
  for (const Entry& e : table) {
    if (name == e.a || name == e.b) {
      type = e.type;
      return true;
    }
  }
  return false;
}

bool isInteger(PlyType type) { return type != PlyType::Float32 && type != PlyType::Float64; }

template <typename T>
double load(const unsigned char* bytes) {
  T value;
  std::memcpy(&value, bytes, sizeof value);
  return static_cast<double>(value);
}

/// Decodes one value stored in file byte order (`swap`: reverse to get host order).
double decode(unsigned char* bytes, PlyType type, bool swap) {
  const std::size_t n = plyTypeSize(type);
  if (swap) {
    for (std::size_t i = 0; i < n / 2; ++i) std::swap(bytes[i], bytes[n - 1 - i]);
  }
  switch (type) {
    case PlyType::Int8:
      return load<std::int8_t>(bytes);
    case PlyType::UInt8:
      return load<std::uint8_t>(bytes);
    case PlyType::Int16:
      return load<std::int16_t>(bytes);
    case PlyType::UInt16:
      return load<std::uint16_t>(bytes);
    case PlyType::Int32:
      return load<std::int32_t>(bytes);
    case PlyType::UInt32:
      return load<std::uint32_t>(bytes);
    case PlyType::Float32:
      return load<float>(bytes);
    case PlyType::Float64:
      return load<double>(bytes);
  }
  return 0.0;
}

/// A list length read as a double: a non-negative integer below 2³¹, or -1.
std::int64_t listLength(double value) {
  if (!(value >= 0.0) || value >= 2147483648.0 || value != std::floor(value)) return -1;
  return static_cast<std::int64_t>(value);
}

}  // namespace

std::size_t plyTypeSize(PlyType type) noexcept {
  switch (type) {
    case PlyType::Int8:
    case PlyType::UInt8:
      return 1;
    case PlyType::Int16:
    case PlyType::UInt16:
      return 2;
    case PlyType::Int32:
    case PlyType::UInt32:
    case PlyType::Float32:
      return 4;
    case PlyType::Float64:
      return 8;
  }
  return 1;
}

int PlyElement::find(std::string_view propertyName) const {
  for (std::size_t i = 0; i < properties.size(); ++i) {
    if (properties[i].name == propertyName) return static_cast<int>(i);
  }
  return -1;
}

std::uint64_t PlyElement::fixedRowSize() const {
  std::uint64_t size = 0;
  for (const PlyProperty& p : properties) {
    if (p.list) return 0;
    size += plyTypeSize(p.type);
  }
  return size;
}

PlyReader::PlyReader(const std::string& path) : reader_(path) { parseHeader(); }

int PlyReader::findElement(std::string_view name) const {
  for (std::size_t i = 0; i < elements_.size(); ++i) {
    if (elements_[i].name == name) return static_cast<int>(i);
  }
  return -1;
}

void PlyReader::parseHeader() {
  std::string line;
  auto status = reader_.readLine(line, 16);
  while (!line.empty() && (line.back() == ' ' || line.back() == '\t')) line.pop_back();
  if (status != ByteReader::LineStatus::Ok || line != "ply") {
    fail("not a PLY file (line 1 is not 'ply')");
  }
  bool haveFormat = false;
  std::vector<std::string_view> tokens;
  for (;;) {
    status = reader_.readLine(line, kMaxHeaderLine);
    const std::string at = " at line " + std::to_string(reader_.line() + 1);
    if (status == ByteReader::LineStatus::EndOfFile) {
      fail("PLY header has no end_header line (the file ends" + at + ")");
    }
    if (status == ByteReader::LineStatus::TooLong) {
      fail("PLY header line longer than 64 KiB" + at + " (no end_header?)");
    }
    const std::string here = " at line " + std::to_string(reader_.line());
    splitWhitespace(line, tokens);
    if (tokens.empty()) continue;
    const std::string_view key = tokens[0];
    if (key == "end_header") break;
    if (key == "comment" || key == "obj_info") {
      const std::size_t start = line.find(key) + key.size();
      std::string text = line.substr(std::min(start + 1, line.size()));
      comments_.push_back(std::move(text));
    } else if (key == "format") {
      if (tokens.size() != 3) {
        fail("malformed format line" + here + " (expected 'format <encoding> 1.0')");
      }
      if (tokens[1] == "ascii") {
        encoding_ = PlyEncoding::Ascii;
      } else if (tokens[1] == "binary_little_endian") {
        encoding_ = PlyEncoding::BinaryLittleEndian;
      } else if (tokens[1] == "binary_big_endian") {
        encoding_ = PlyEncoding::BinaryBigEndian;
      } else {
        fail("unknown PLY format " + quoted(tokens[1]) + here +
             " (expected ascii, binary_little_endian or binary_big_endian)");
      }
      double version = 0.0;
      if (!parseNumber(tokens[2], version) || version != 1.0) {
        fail("unsupported PLY version " + quoted(tokens[2]) + here + " (expected 1.0)");
      }
      haveFormat = true;
    } else if (key == "element") {
      if (tokens.size() != 3) {
        fail("malformed element line" + here + " (expected 'element <name> <count>')");
      }
      PlyElement element;
      element.name = std::string(tokens[1]);
      if (!parseCount(tokens[2], element.count)) {
        fail("invalid element count " + quoted(tokens[2]) + here);
      }
      elements_.push_back(std::move(element));
    } else if (key == "property") {
      if (elements_.empty()) fail("property before any element" + here);
      PlyProperty property;
      if (tokens.size() >= 2 && tokens[1] == "list") {
        if (tokens.size() != 5) {
          fail("malformed list property" + here +
               " (expected 'property list <count type> <item type> <name>')");
        }
        if (!parseType(tokens[2], property.countType)) {
          fail("unknown property type " + quoted(tokens[2]) + here);
        }
        if (!isInteger(property.countType)) {
          fail("list count type " + quoted(tokens[2]) + " is not an integer type" + here);
        }
        if (!parseType(tokens[3], property.type)) {
          fail("unknown property type " + quoted(tokens[3]) + here);
        }
        property.list = true;
        property.name = std::string(tokens[4]);
      } else {
        if (tokens.size() != 3) {
          fail("malformed property line" + here + " (expected 'property <type> <name>')");
        }
        if (!parseType(tokens[1], property.type)) {
          fail("unknown property type " + quoted(tokens[1]) + here);
        }
        property.name = std::string(tokens[2]);
      }
      elements_.back().properties.push_back(std::move(property));
    } else {
      fail("unknown PLY header keyword " + quoted(key) + here);
    }
  }
  if (!haveFormat) fail("PLY header has no format line");
  swap_ = encoding_ != PlyEncoding::Ascii &&
          (encoding_ == PlyEncoding::BinaryLittleEndian) != hostIsLittleEndian();
}

std::string PlyReader::where() const {
  const std::string what = elements_[current_].name + " " + std::to_string(row_);
  if (encoding_ == PlyEncoding::Ascii) return what + " at line " + std::to_string(rowLine_);
  return what + " at byte offset " + std::to_string(rowOffset_);
}

void PlyReader::beginElement(std::size_t index) {
  if (!started_) {
    started_ = true;
    current_ = 0;
    row_ = -1;
  }
  while (current_ < index) {
    skipRows(elements_[current_], elements_[current_].count - (row_ + 1));
    ++current_;
    row_ = -1;
  }
  checkFixedElementFits(elements_[current_], elements_[current_].count);
}

void PlyReader::checkFixedElementFits(const PlyElement& element, std::int64_t rows) {
  const std::uint64_t size = element.fixedRowSize();
  if (encoding_ == PlyEncoding::Ascii || size == 0 || rows <= 0) return;
  const std::uint64_t left = reader_.remaining();
  const auto count = static_cast<std::uint64_t>(rows);
  if (count <= left / size) return;
  std::string missing = "more than " + std::to_string(std::numeric_limits<std::int64_t>::max());
  if (count <= std::numeric_limits<std::uint64_t>::max() / size) {
    missing = std::to_string(count * size - left);
  }
  fail("truncated binary body: " + std::to_string(count) + " " + element.name + " elements of " +
       std::to_string(size) + " bytes expected from byte offset " +
       std::to_string(reader_.offset()) + ", but only " + std::to_string(left) +
       " bytes are left (" + missing + " bytes missing; the file ends in " + element.name + " " +
       std::to_string(static_cast<std::uint64_t>(row_ + 1) + left / size) + ")");
}

void PlyReader::skipRows(const PlyElement& element, std::int64_t rows) {
  if (rows <= 0 || element.properties.empty()) return;
  const std::uint64_t size = element.fixedRowSize();
  if (encoding_ != PlyEncoding::Ascii && size > 0) {
    checkFixedElementFits(element, rows);
    reader_.skip(static_cast<std::uint64_t>(rows) * size);
    row_ += rows;
    return;
  }
  for (std::int64_t i = 0; i < rows; ++i) {
    if (encoding_ == PlyEncoding::Ascii) {
      readAsciiRow(scratch_, -1, scratch_);
    } else {
      readBinaryRow(scratch_, -1, scratch_, false);
    }
  }
}

void PlyReader::readRow(std::vector<double>& values, int listProperty, std::vector<double>& list) {
  if (encoding_ == PlyEncoding::Ascii) {
    readAsciiRow(values, listProperty, list);
  } else {
    readBinaryRow(values, listProperty, list, true);
  }
}

void PlyReader::readAsciiRow(std::vector<double>& values, int listProperty,
                             std::vector<double>& list) {
  const PlyElement& element = elements_[current_];
  ++row_;
  // Blank lines between rows are tolerated; each row is one line.
  for (;;) {
    const auto status = reader_.readLine(line_, kMaxBodyLine);
    if (status == ByteReader::LineStatus::EndOfFile) {
      rowLine_ = reader_.line() + 1;
      fail("ascii body ends early at line " + std::to_string(rowLine_) + ": the header declares " +
           std::to_string(element.count) + " " + element.name + " elements, the file has " +
           std::to_string(row_));
    }
    if (status == ByteReader::LineStatus::TooLong) {
      fail("line " + std::to_string(reader_.line() + 1) + " is longer than 64 MiB (" +
           element.name + " " + std::to_string(row_) + ")");
    }
    splitWhitespace(line_, tokens_);
    if (!tokens_.empty()) break;
  }
  rowLine_ = reader_.line();
  const bool keep = &values != &scratch_;
  if (keep) values.assign(element.properties.size(), 0.0);
  std::size_t t = 0;
  auto next = [&](const PlyProperty& p) {
    if (t >= tokens_.size()) {
      fail("too few values for " + where() + ": the line ends before property '" + p.name + "' (" +
           std::to_string(tokens_.size()) + " values on the line)");
    }
    double value = 0.0;
    if (!parseNumber(tokens_[t], value)) {
      fail("non-numeric value " + quoted(tokens_[t]) + " for property '" + p.name + "' of " +
           where());
    }
    ++t;
    return value;
  };
  for (std::size_t p = 0; p < element.properties.size(); ++p) {
    const PlyProperty& property = element.properties[p];
    if (!property.list) {
      const double value = next(property);
      if (keep) values[p] = value;
      continue;
    }
    const std::int64_t n = listLength(next(property));
    if (n < 0) fail("invalid list length for property '" + property.name + "' of " + where());
    const bool wanted = keep && static_cast<int>(p) == listProperty;
    if (wanted) list.clear();
    for (std::int64_t i = 0; i < n; ++i) {
      const double value = next(property);
      if (wanted) list.push_back(value);
    }
  }
  if (t != tokens_.size()) {
    fail("extra values for " + where() + ": " + std::to_string(tokens_.size()) +
         " values on the line, the header declares " + std::to_string(t));
  }
}

double PlyReader::readBinaryValue(PlyType type) {
  unsigned char bytes[8];
  const std::size_t n = plyTypeSize(type);
  if (reader_.read(bytes, n) != n) failTruncated();
  return decode(bytes, type, swap_);
}

void PlyReader::failTruncated() {
  const PlyElement& element = elements_[current_];
  fail("truncated binary body: the file ends at byte offset " + std::to_string(reader_.size()) +
       " in " + element.name + " " + std::to_string(row_) + " of " + std::to_string(element.count) +
       " (the row starts at byte offset " + std::to_string(rowOffset_) + ")");
}

void PlyReader::readBinaryRow(std::vector<double>& values, int listProperty,
                              std::vector<double>& list, bool keep) {
  const PlyElement& element = elements_[current_];
  ++row_;
  rowOffset_ = reader_.offset();
  if (keep) values.assign(element.properties.size(), 0.0);
  for (std::size_t p = 0; p < element.properties.size(); ++p) {
    const PlyProperty& property = element.properties[p];
    if (!property.list) {
      const double value = readBinaryValue(property.type);
      if (keep) values[p] = value;
      continue;
    }
    const std::int64_t n = listLength(readBinaryValue(property.countType));
    if (n < 0) fail("invalid list length for property '" + property.name + "' of " + where());
    const std::uint64_t bytes = static_cast<std::uint64_t>(n) * plyTypeSize(property.type);
    if (bytes > reader_.remaining()) failTruncated();
    if (keep && static_cast<int>(p) == listProperty) {
      list.clear();
      for (std::int64_t i = 0; i < n; ++i) list.push_back(readBinaryValue(property.type));
    } else {
      reader_.skip(bytes);
    }
  }
}

}  // namespace duplexfit::io
