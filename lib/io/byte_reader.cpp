// Buffered sequential file reading with offset and line tracking, tokenising and number parsing for
// the PLY, XYZ, OBJ and STL readers.
#include "byte_reader.hpp"

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <charconv>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <system_error>

#include "duplexfit/error.hpp"

namespace duplexfit::io {

namespace {
constexpr std::size_t kBufferSize = std::size_t{1} << 16;
}  // namespace

ByteReader::ByteReader(std::string path) : path_(std::move(path)) {
  std::error_code ec;
  if (std::filesystem::is_directory(path_, ec)) fail("cannot open: it is a folder, not a file");
  file_ = std::fopen(path_.c_str(), "rb");
  if (file_ == nullptr) fail(std::string("cannot open: ") + std::strerror(errno));
  const auto size = std::filesystem::file_size(path_, ec);
  if (ec) {
    std::fclose(file_);
    file_ = nullptr;
    fail("cannot read the file size: " + ec.message());
  }
  size_ = size;
  if (size_ == 0) {
    std::fclose(file_);
    file_ = nullptr;
    fail("empty file");
  }
  buffer_.resize(kBufferSize);
}

ByteReader::~ByteReader() {
  if (file_ != nullptr) std::fclose(file_);
}

void ByteReader::fail(const std::string& what) const { throw IoError(path_ + ": " + what); }

bool ByteReader::refill() {
  if (pos_ < end_) return true;
  consumed_ += end_;
  pos_ = end_ = 0;
  end_ = std::fread(buffer_.data(), 1, buffer_.size(), file_);
  if (end_ == 0 && std::ferror(file_) != 0) {
    fail("read error at byte offset " + std::to_string(consumed_) + ": " + std::strerror(errno));
  }
  return end_ > 0;
}

ByteReader::LineStatus ByteReader::readLine(std::string& line, std::size_t maxLength) {
  line.clear();
  bool any = false;
  while (refill()) {
    any = true;
    const char* begin = buffer_.data() + pos_;
    const char* stop = buffer_.data() + end_;
    const char* nl = static_cast<const char*>(std::memchr(begin, '\n', std::size_t(stop - begin)));
    const char* take = nl != nullptr ? nl : stop;
    if (line.size() + std::size_t(take - begin) > maxLength) return LineStatus::TooLong;
    line.append(begin, take);
    pos_ += std::size_t(take - begin);
    if (nl != nullptr) {
      ++pos_;
      break;
    }
  }
  if (!any) return LineStatus::EndOfFile;
  ++line_;
  if (!line.empty() && line.back() == '\r') line.pop_back();
  return LineStatus::Ok;
}

std::size_t ByteReader::read(void* dst, std::size_t n) {
  auto* out = static_cast<char*>(dst);
  std::size_t done = 0;
  // Fast path: the bytes are already in the buffer.
  if (end_ - pos_ >= n) {
    std::memcpy(out, buffer_.data() + pos_, n);
    pos_ += n;
    return n;
  }
  while (done < n && refill()) {
    const std::size_t take = std::min(n - done, end_ - pos_);
    std::memcpy(out + done, buffer_.data() + pos_, take);
    pos_ += take;
    done += take;
  }
  return done;
}

std::uint64_t ByteReader::skip(std::uint64_t n) {
  std::uint64_t done = 0;
  // Beyond the buffer, seek (a rank reading its own row range of a large file does not read the rest).
  const std::uint64_t buffered = end_ - pos_;
  if (n > buffered + buffer_.size()) {
    const std::uint64_t target = std::min<std::uint64_t>(offset() + n, size_);
    if (fseeko(file_, static_cast<off_t>(target), SEEK_SET) == 0) {
      done = target - offset();
      consumed_ = target;
      pos_ = end_ = 0;
      return done;
    }
  }
  while (done < n && refill()) {
    const std::uint64_t take = std::min<std::uint64_t>(n - done, end_ - pos_);
    pos_ += static_cast<std::size_t>(take);
    done += take;
  }
  return done;
}

void splitWhitespace(std::string_view text, std::vector<std::string_view>& tokens) {
  tokens.clear();
  auto isSpace = [](char c) {
    return c == ' ' || c == '\t' || c == '\r' || c == '\v' || c == '\f';
  };
  std::size_t i = 0;
  while (i < text.size()) {
    while (i < text.size() && isSpace(text[i])) ++i;
    const std::size_t start = i;
    while (i < text.size() && !isSpace(text[i])) ++i;
    if (i > start) tokens.push_back(text.substr(start, i - start));
  }
}

bool parseNumber(std::string_view token, double& value) {
  if (!token.empty() && token.front() == '+') token.remove_prefix(1);
  if (token.empty() || token.front() == '+') return false;
  const char* first = token.data();
  const char* last = token.data() + token.size();
  const auto [ptr, ec] = std::from_chars(first, last, value);
  if (ptr != last) return false;
  if (ec == std::errc::result_out_of_range) {
    // from_chars leaves the value unset on overflow and underflow; strtod gives ±HUGE_VAL or the
    // rounded tiny value, which is what a text reader should see.
    const std::string copy(token);
    value = std::strtod(copy.c_str(), nullptr);
    return true;
  }
  return ec == std::errc();
}

bool parseCount(std::string_view token, std::int64_t& value) {
  if (!token.empty() && token.front() == '+') token.remove_prefix(1);
  if (token.empty() || token.front() == '-' || token.front() == '+') return false;
  const char* last = token.data() + token.size();
  const auto [ptr, ec] = std::from_chars(token.data(), last, value);
  return ec == std::errc() && ptr == last;
}

std::string quoted(std::string_view token) {
  std::string out = "'";
  const std::size_t limit = 40;
  for (std::size_t i = 0; i < token.size() && i < limit; ++i) {
    const auto c = static_cast<unsigned char>(token[i]);
    if (c >= 0x20 && c < 0x7f) {
      out += static_cast<char>(c);
    } else {
      static const char* hex = "0123456789abcdef";
      out += "\\x";
      out += hex[c >> 4];
      out += hex[c & 15];
    }
  }
  if (token.size() > limit) out += "...";
  return out + "'";
}

std::string lowerExtension(const std::string& path) {
  std::string ext = std::filesystem::path(path).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return ext;
}

bool hostIsLittleEndian() noexcept {
  const std::uint16_t probe = 1;
  unsigned char first = 0;
  std::memcpy(&first, &probe, 1);
  return first == 1;
}

}  // namespace duplexfit::io
