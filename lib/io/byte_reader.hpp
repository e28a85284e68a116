// Private helpers of the readers: a buffered file reader that tracks the byte offset and the line
// number (for error messages), whitespace tokenising and locale-free number parsing.
#pragma once

#include <cstdint>
#include <cstdio>
#include <string>
#include <string_view>
#include <vector>

namespace duplexfit::io {

/// Reads a file sequentially through a buffer. Errors are IoError messages starting with the path.
class ByteReader {
 public:
  /// Opens `path` for reading. @throws IoError when it cannot be opened, is a folder, or is empty.
  explicit ByteReader(std::string path);
  ~ByteReader();
  ByteReader(const ByteReader&) = delete;
  ByteReader& operator=(const ByteReader&) = delete;

  enum class LineStatus { Ok, EndOfFile, TooLong };
  /// Reads up to the next '\n' (dropped, with a trailing '\r'). EndOfFile when nothing is left;
  /// TooLong (the reader then stands at an unspecified position) past `maxLength` bytes.
  LineStatus readLine(std::string& line, std::size_t maxLength);
  /// Copies up to `n` bytes into `dst`; returns how many were copied (fewer only at end of file).
  std::size_t read(void* dst, std::size_t n);
  /// Skips up to `n` bytes; returns how many were skipped.
  std::uint64_t skip(std::uint64_t n);

  const std::string& path() const noexcept { return path_; }
  std::uint64_t size() const noexcept { return size_; }
  std::uint64_t offset() const noexcept { return consumed_ + pos_; }
  std::uint64_t remaining() const noexcept { return size_ - offset(); }
  /// Number of lines read by readLine so far (the current line's number after a read).
  std::size_t line() const noexcept { return line_; }

  /// Throws IoError("<path>: <what>").
  [[noreturn]] void fail(const std::string& what) const;

 private:
  bool refill();

  std::string path_;
  std::FILE* file_ = nullptr;
  std::uint64_t size_ = 0;
  std::vector<char> buffer_;
  std::size_t pos_ = 0, end_ = 0;  ///< unread bytes are buffer_[pos_, end_)
  std::uint64_t consumed_ = 0;     ///< file offset of buffer_[0]
  std::size_t line_ = 0;
};

/// Splits `text` at spaces, tabs, '\r', '\v' and '\f' (views into `text`).
void splitWhitespace(std::string_view text, std::vector<std::string_view>& tokens);

/// Parses a whole token as a decimal or scientific number ("nan"/"inf" parse as such).
/// Values beyond double's range parse as ±inf, tiny ones as 0 or subnormals. False on junk.
bool parseNumber(std::string_view token, double& value);

/// Parses a whole token as a non-negative decimal integer that fits in int64.
bool parseCount(std::string_view token, std::int64_t& value);

/// The token quoted for an error message, shortened to 40 characters and with control bytes
/// escaped.
std::string quoted(std::string_view token);

/// Lowercase extension of a path including the dot (".ply"), or "" when it has none.
std::string lowerExtension(const std::string& path);

/// True when this machine stores integers little-endian first.
bool hostIsLittleEndian() noexcept;

}  // namespace duplexfit::io
