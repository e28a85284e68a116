// AtomicFile: writes a file under a temporary name next to its destination and renames it into
// place on commit(), so that readers never see a half-written output and a failed write leaves
// nothing.
#pragma once

#include <cstddef>
#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

namespace duplexfit {

/// A file written atomically: the bytes go to "<path>.tmp-<pid>-<n>" in the destination's folder;
/// commit() flushes, fsyncs and renames it onto `path`. Destroying an uncommitted AtomicFile (an
/// exception, an early return) removes the temporary file and leaves `path` untouched.
///
///     AtomicFile out("mesh.ply");
///     out.write(header);
///     out.write(data.data(), data.size());
///     out.commit();
class AtomicFile {
 public:
  /// Creates the temporary file next to `path`.
  /// @throws IoError naming `path` when its folder is missing or not writable.
  explicit AtomicFile(std::string path);
  /// Removes the temporary file unless commit() succeeded. Never throws.
  ~AtomicFile();
  AtomicFile(const AtomicFile&) = delete;
  AtomicFile& operator=(const AtomicFile&) = delete;

  /// Appends `bytes` bytes (buffered). @throws IoError on a write error (e.g. disk full) or after
  /// commit().
  void write(const void* data, std::size_t bytes);
  /// Appends text. @throws IoError as write(data, bytes).
  void write(std::string_view text) { write(text.data(), text.size()); }

  /// Flushes, fsyncs and closes the temporary file, then renames it onto path() (replacing an
  /// existing file). On failure the temporary file is removed. @throws IoError naming path().
  void commit();

  /// The destination path.
  const std::string& path() const noexcept { return path_; }
  /// The temporary file's path ("<path>.tmp-<pid>-<n>").
  const std::string& tempPath() const noexcept { return tempPath_; }
  /// True once commit() has succeeded.
  bool committed() const noexcept { return committed_; }

 private:
  void flushBuffer();
  void writeAll(const char* data, std::size_t bytes);
  void discard() noexcept;
  [[noreturn]] void fail(const std::string& what, int error);

  std::string path_;
  std::string tempPath_;
  int fd_ = -1;
  bool committed_ = false;
  std::vector<char> buffer_;
};

/// Output staging for several files written together: every output goes to a temporary folder
/// ".duplexfit-tmp-<pid>" inside the output folder first, commit() moves each entry into place, and the
/// destructor removes whatever is left, so that a failed run leaves no partial output.
///
///     StagedFolder out("results");          // fails early when "results" cannot be created or written
///     writeMesh(out.path("zero.ply"), mesh);
///     out.commit();
class StagedFolder {
 public:
  /// Creates the output folder (and parents) and the staging folder `.duplexfit-tmp-PID` inside it, after
  /// removing the staging folders of earlier runs whose process no longer exists (killed runs).
  /// @throws IoError when either cannot be created.
  explicit StagedFolder(const std::filesystem::path& outDir);
  /// Removes the staging folder and whatever is still in it, and the output folder (and the parents it
  /// needed) too when this object created them and nothing was committed: a failed run leaves no empty
  /// folder behind. Never throws.
  ~StagedFolder();
  StagedFolder(const StagedFolder&) = delete;
  StagedFolder& operator=(const StagedFolder&) = delete;

  /// The staged path of output `name`; with `folder`, the folder is created. The entry staged LAST is the
  /// set's index (report.json, slices.json): see commit(). @throws IoError.
  std::string path(const std::string& name, bool folder = false);
  /// Moves every staged entry into the output folder (a folder replaces an older one of that name). The
  /// index (the last entry) is removed from the output folder first and moved in last, so whenever the
  /// index is present every entry it names comes from the same run; a run killed half-way leaves no index.
  /// @throws IoError naming the entry that cannot be moved.
  void commit();
  /// The output folder.
  const std::filesystem::path& folder() const noexcept { return outDir_; }

 private:
  std::filesystem::path outDir_, dir_;
  std::vector<std::string> names_;
  std::vector<std::filesystem::path> created_;  ///< folders this object created, deepest first
  bool committed_ = false;
};

}  // namespace duplexfit
