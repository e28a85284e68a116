// Private PLY support shared by the point and mesh readers: header parsing and element-by-element
// body reading (ascii, binary little- and big-endian) with located error messages.
#pragma once

#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "byte_reader.hpp"
#include "duplexfit/io.hpp"

namespace duplexfit::io {

/// Scalar types of PLY properties.
enum class PlyType : std::uint8_t { Int8, UInt8, Int16, UInt16, Int32, UInt32, Float32, Float64 };

/// Size in bytes of a PLY type.
std::size_t plyTypeSize(PlyType type) noexcept;

/// One property of an element: a scalar, or a list with its own count and item types.
struct PlyProperty {
  std::string name;
  PlyType type = PlyType::Float32;  ///< scalar type, or the item type of a list
  bool list = false;
  PlyType countType = PlyType::UInt8;  ///< lists only
};

/// One element declaration ("element vertex 100" and its properties).
struct PlyElement {
  std::string name;
  std::int64_t count = 0;
  std::vector<PlyProperty> properties;
  /// Index of the property called `name`, or -1.
  int find(std::string_view name) const;
  /// Bytes of one binary row, or 0 when the element has a list property (rows vary).
  std::uint64_t fixedRowSize() const;
};

/// Reads a PLY file: the header on construction, then the body element by element.
class PlyReader {
 public:
  /// Opens `path` and parses its header. @throws IoError naming the file and header line.
  explicit PlyReader(const std::string& path);

  PlyEncoding encoding() const noexcept { return encoding_; }
  const std::vector<PlyElement>& elements() const noexcept { return elements_; }
  const std::vector<std::string>& comments() const noexcept { return comments_; }
  /// Index of the element called `name`, or -1.
  int findElement(std::string_view name) const;

  /// Skips the body up to element `index` (which must not be before the current one) and starts
  /// reading it. @throws IoError when the body is truncated.
  void beginElement(std::size_t index);
  /// Reads the next row of the current element: one value per property into `values` (0 for lists)
  /// and the items of property `listProperty` (when ≥ 0) into `list`.
  /// @throws IoError on a truncated body, junk text or a wrong number of values.
  void readRow(std::vector<double>& values, int listProperty, std::vector<double>& list);
  /// Skips `rows` rows of the current element (after beginElement); binary rows of a fixed size are
  /// skipped by seeking. @throws IoError when the body is truncated.
  void skipElementRows(std::int64_t rows) { skipRows(elements_[current_], rows); }

  /// "vertex 12 at line 27" (ascii) or "vertex 12 at byte offset 1234" (binary) for the last row.
  std::string where() const;
  /// Throws IoError("<path>: <what>").
  [[noreturn]] void fail(const std::string& what) const { reader_.fail(what); }
  /// Bytes left after the current position (for capacity guesses).
  std::uint64_t remainingBytes() const noexcept { return reader_.remaining(); }

 private:
  void parseHeader();
  void skipRows(const PlyElement& element, std::int64_t rows);
  void checkFixedElementFits(const PlyElement& element, std::int64_t rows);
  void readAsciiRow(std::vector<double>& values, int listProperty, std::vector<double>& list);
  void readBinaryRow(std::vector<double>& values, int listProperty, std::vector<double>& list,
                     bool keep);
  double readBinaryValue(PlyType type);
  [[noreturn]] void failTruncated();

  ByteReader reader_;
  PlyEncoding encoding_ = PlyEncoding::Ascii;
  bool swap_ = false;
  std::vector<PlyElement> elements_;
  std::vector<std::string> comments_;
  std::size_t current_ = 0;  ///< element being read
  std::int64_t row_ = -1;    ///< rows of the current element read so far, minus one
  bool started_ = false;
  std::uint64_t rowOffset_ = 0;  ///< byte offset of the current row (binary)
  std::size_t rowLine_ = 0;      ///< line of the current row (ascii)
  std::string line_;
  std::vector<std::string_view> tokens_;
  std::vector<double> scratch_;
};

}  // namespace duplexfit::io
