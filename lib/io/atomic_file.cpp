// AtomicFile on POSIX: O_EXCL temporary file next to the destination, fsync, rename(2) (atomic
// within one file system), then a best-effort fsync of the folder so the rename itself is durable.
#include "duplexfit/atomic_file.hpp"

#include <fcntl.h>
#include <signal.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <string>
#include <system_error>
#include <vector>

#include "duplexfit/error.hpp"

namespace duplexfit {

namespace {

constexpr std::size_t kBufferSize = std::size_t{1} << 20;

std::string folderOf(const std::string& path) {
  const std::string parent = std::filesystem::path(path).parent_path().string();
  return parent.empty() ? std::string(".") : parent;
}

}  // namespace

AtomicFile::AtomicFile(std::string path) : path_(std::move(path)) {
  if (path_.empty()) throw IoError("AtomicFile: empty output path");
  std::error_code ec;
  if (std::filesystem::is_directory(path_, ec)) {
    throw IoError(path_ + ": cannot write: it is a folder");
  }
  static std::atomic<unsigned long> counter{0};
  tempPath_ = path_ + ".tmp-" + std::to_string(static_cast<long>(::getpid())) + "-" +
              std::to_string(counter.fetch_add(1));
  fd_ = ::open(tempPath_.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0666);
  if (fd_ < 0) {
    const int error = errno;
    const std::string folder = folderOf(path_);
    if (error == ENOENT || error == ENOTDIR) {
      throw IoError(path_ + ": cannot write: folder '" + folder + "' does not exist");
    }
    if (error == EACCES || error == EPERM || error == EROFS) {
      throw IoError(path_ + ": cannot write: folder '" + folder + "' is not writable (" +
                    std::strerror(error) + ")");
    }
    throw IoError(path_ + ": cannot create the temporary file '" + tempPath_ +
                  "': " + std::strerror(error));
  }
  buffer_.reserve(kBufferSize);
}

AtomicFile::~AtomicFile() { discard(); }

void AtomicFile::discard() noexcept {
  if (fd_ >= 0) {
    ::close(fd_);
    fd_ = -1;
    if (!committed_) ::unlink(tempPath_.c_str());
  }
}

void AtomicFile::fail(const std::string& what, int error) {
  discard();
  throw IoError(path_ + ": " + what + ": " + std::strerror(error));
}

void AtomicFile::write(const void* data, std::size_t bytes) {
  if (fd_ < 0) {
    throw IoError(path_ + (committed_ ? ": write after commit" : ": write after a failed write"));
  }
  const auto* p = static_cast<const char*>(data);
  if (buffer_.size() + bytes > kBufferSize) flushBuffer();
  if (bytes >= kBufferSize) {
    writeAll(p, bytes);
  } else {
    buffer_.insert(buffer_.end(), p, p + bytes);
  }
}

void AtomicFile::writeAll(const char* data, std::size_t bytes) {
  std::size_t done = 0;
  while (done < bytes) {
    const ssize_t n = ::write(fd_, data + done, bytes - done);
    if (n < 0) {
      if (errno == EINTR) continue;
      fail("write error", errno);
    }
    done += static_cast<std::size_t>(n);
  }
}

void AtomicFile::flushBuffer() {
  writeAll(buffer_.data(), buffer_.size());
  buffer_.clear();
}

void AtomicFile::commit() {
  if (fd_ < 0) {
    throw IoError(path_ + (committed_ ? ": already committed" : ": commit after a failed write"));
  }
  flushBuffer();
  if (::fsync(fd_) != 0) fail("fsync failed", errno);
  const int fd = fd_;
  fd_ = -1;
  if (::close(fd) != 0) {
    const int error = errno;
    ::unlink(tempPath_.c_str());
    throw IoError(path_ + ": close failed: " + std::strerror(error));
  }
  if (std::rename(tempPath_.c_str(), path_.c_str()) != 0) {
    const int error = errno;
    ::unlink(tempPath_.c_str());
    throw IoError(path_ + ": cannot rename '" + tempPath_ + "' onto it: " + std::strerror(error));
  }
  committed_ = true;
  // Make the new directory entry durable too; failure here cannot undo the rename, so ignore it.
  const int dir = ::open(folderOf(path_).c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (dir >= 0) {
    ::fsync(dir);
    ::close(dir);
  }
}

namespace {

/// Removes `.duplexfit-tmp-PID` folders in `folder` whose process has gone (kill(PID, 0) fails with ESRCH):
/// what a run killed by SIGKILL, or before its handlers ran, left behind. A folder of a live process is
/// kept, whatever that process is.
void removeStaleStaging(const std::filesystem::path& folder) {
  namespace fs = std::filesystem;
  const std::string prefix = ".duplexfit-tmp-";
  std::error_code ec;
  std::vector<fs::path> stale;
  for (fs::directory_iterator it(folder, ec), end; !ec && it != end; it.increment(ec)) {
    const std::string name = it->path().filename().string();
    if (name.size() <= prefix.size() || name.compare(0, prefix.size(), prefix) != 0) continue;
    const std::string digits = name.substr(prefix.size());
    if (digits.size() > 9 || digits.find_first_not_of("0123456789") != std::string::npos) continue;
    const long pid = std::stol(digits);
    if (pid <= 0 || pid == static_cast<long>(getpid())) continue;
    if (::kill(static_cast<pid_t>(pid), 0) != 0 && errno == ESRCH) stale.push_back(it->path());
  }
  for (const fs::path& p : stale) fs::remove_all(p, ec);
}

}  // namespace

StagedFolder::StagedFolder(const std::filesystem::path& outDir) : outDir_(outDir) {
  namespace fs = std::filesystem;
  std::error_code ec;
  for (fs::path p = outDir_; !p.empty() && !fs::exists(p, ec); p = p.parent_path()) {
    created_.push_back(p);
    if (p == p.parent_path()) break;
  }
  fs::create_directories(outDir_, ec);
  if (ec || !fs::is_directory(outDir_)) {
    throw IoError(outDir_.string() + ": cannot create the output folder (" + ec.message() + ")");
  }
  removeStaleStaging(outDir_);
  dir_ = outDir_ / (".duplexfit-tmp-" + std::to_string(getpid()));
  fs::remove_all(dir_, ec);
  fs::create_directory(dir_, ec);
  if (ec) {
    const std::string message = ec.message();
    for (const fs::path& p : created_) fs::remove(p, ec);
    throw IoError(outDir_.string() + ": the output folder is not writable (" + message + ")");
  }
}

StagedFolder::~StagedFolder() {
  std::error_code ec;
  std::filesystem::remove_all(dir_, ec);
  // Only when empty: remove() of a non-empty folder fails and leaves it.
  if (!committed_) {
    for (const std::filesystem::path& p : created_) std::filesystem::remove(p, ec);
  }
}

std::string StagedFolder::path(const std::string& name, bool folder) {
  names_.push_back(name);
  if (folder) {
    std::error_code ec;
    std::filesystem::create_directory(dir_ / name, ec);
    if (ec) throw IoError((outDir_ / name).string() + ": cannot create (" + ec.message() + ")");
  }
  return (dir_ / name).string();
}

void StagedFolder::commit() {
  namespace fs = std::filesystem;
  if (names_.empty()) return;
  std::error_code ec;
  // The index goes first, so no reader sees the old index beside a mix of old and new entries.
  const std::string& index = names_.back();
  if (!fs::is_directory(outDir_ / index)) fs::remove(outDir_ / index, ec);
  committed_ = true;  // from here on the output folder holds (part of) this run
  for (const std::string& n : names_) {
    ec.clear();
    if (fs::is_directory(dir_ / n)) fs::remove_all(outDir_ / n, ec);
    fs::rename(dir_ / n, outDir_ / n, ec);
    if (ec) throw IoError((outDir_ / n).string() + ": cannot move the output into place (" + ec.message() + ")");
  }
}

}  // namespace duplexfit
