// AtomicFile: the destination appears only on commit, nothing is left behind after an exception, an
// abandoned write or a failed rename, and missing or unwritable folders give clear IoErrors.
#include <doctest/doctest.h>
#include <sys/stat.h>
#include <unistd.h>

#include <filesystem>
#include <stdexcept>
#include <string>
#include <vector>

#include "duplexfit/atomic_file.hpp"
#include "duplexfit/error.hpp"
#include "duplexfit/io.hpp"
#include "io_test_util.hpp"

namespace {

using duplexfit::AtomicFile;
using duplexfit::IoError;
using duplexfit::testing::checkIoError;
using duplexfit::testing::readBytes;
using duplexfit::testing::TempDir;
using duplexfit::testing::writeBytes;

}  // namespace

TEST_SUITE("io") {

TEST_CASE("atomic file: the content appears under the path only on commit") {
  TempDir dir;
  const std::string path = dir.file("out.bin");
  {
    AtomicFile file(path);
    CHECK(file.path() == path);
    CHECK(file.tempPath().rfind(path + ".tmp-" + std::to_string(::getpid()) + "-", 0) == 0);
    file.write("hello ");
    std::string big(3u << 20, 'x');  // larger than the internal buffer
    big.back() = 'y';
    file.write(big.data(), big.size());
    file.write(" end");
    CHECK_FALSE(std::filesystem::exists(path));
    CHECK(std::filesystem::exists(file.tempPath()));
    file.commit();
    CHECK(file.committed());
    CHECK_THROWS_AS(file.write("more"), IoError);
    CHECK_THROWS_AS(file.commit(), IoError);
  }
  const std::string content = readBytes(path);
  CHECK(content.size() == 6 + (3u << 20) + 4);
  CHECK(content.compare(0, 6, "hello ") == 0);
  CHECK(content.substr(content.size() - 5) == "y end");
  CHECK(dir.entries() == std::vector<std::string>{"out.bin"});
}

TEST_CASE("atomic file: an exception or a missing commit leaves nothing behind") {
  TempDir dir;
  const std::string path = dir.file("out.txt");
  try {
    AtomicFile file(path);
    file.write("partial");
    throw std::runtime_error("simulated failure");
  } catch (const std::runtime_error&) {
  }
  CHECK(dir.entries().empty());
  { AtomicFile abandoned(path); }
  CHECK(dir.entries().empty());

  // An existing file survives an abandoned rewrite untouched.
  writeBytes(path, "original");
  try {
    AtomicFile file(path);
    file.write("replacement");
    throw std::runtime_error("simulated failure");
  } catch (const std::runtime_error&) {
  }
  CHECK(readBytes(path) == "original");
  CHECK(dir.entries() == std::vector<std::string>{"out.txt"});

  // Two writers of one path use different temporary files; the last commit wins.
  AtomicFile a(path), b(path);
  CHECK(a.tempPath() != b.tempPath());
  a.write("a");
  b.write("b");
  a.commit();
  b.commit();
  CHECK(readBytes(path) == "b");
  CHECK(dir.entries() == std::vector<std::string>{"out.txt"});
}

TEST_CASE("atomic file: a failed rename removes the temporary file") {
  TempDir dir;
  const std::string path = dir.file("target");
  AtomicFile file(path);
  file.write("data");
  // The destination becomes a non-empty folder before commit: rename(2) must fail.
  std::filesystem::create_directories(path + "/inside");
  checkIoError([&] { file.commit(); }, path, {"cannot rename"});
  CHECK(dir.entries() == std::vector<std::string>{"target"});
  CHECK_FALSE(file.committed());
}

TEST_CASE("atomic file: missing and unwritable folders are clear IoErrors") {
  TempDir dir;
  const std::string missing = dir.file("nowhere/out.ply");
  checkIoError([&] { AtomicFile file(missing); }, missing, {"folder", "does not exist"});
  const std::string folder = dir.file("folder");
  std::filesystem::create_directory(folder);
  checkIoError([&] { AtomicFile file(folder); }, folder, {"is a folder"});
  if (::geteuid() == 0) {
    DUPLEXFIT_SKIP_PART("the unwritable-folder check, when running as root (root writes anywhere)");
    return;
  }
  const std::string locked = dir.file("locked");
  std::filesystem::create_directory(locked);
  ::chmod(locked.c_str(), 0555);
  const std::string path = locked + "/out.ply";
  checkIoError([&] { AtomicFile file(path); }, path, {"not writable"});
  checkIoError([&] { duplexfit::writeMesh(path, duplexfit::Mesh{}); }, path, {"not writable"});
  ::chmod(locked.c_str(), 0755);
}

}  // TEST_SUITE
