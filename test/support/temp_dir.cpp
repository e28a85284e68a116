// Temporary folders and whole-file access for the tests (temp_dir.hpp).
#include "temp_dir.hpp"

#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cstdlib>
#include <fstream>
#include <iostream>
#include <mutex>
#include <set>

namespace fs = std::filesystem;

namespace duplexfit::testing {

TempDir::TempDir(const std::string& prefix) {
  static std::atomic<int> counter{0};
  path_ = fs::temp_directory_path() / (prefix + "-" + std::to_string(::getpid()) + "-" + std::to_string(counter++));
  fs::remove_all(path_);
  fs::create_directories(path_);
}

TempDir::~TempDir() {
  std::error_code ec;
  fs::remove_all(path_, ec);
}

std::vector<std::string> TempDir::entries() const {
  std::vector<std::string> names;
  for (const auto& e : fs::directory_iterator(path_)) names.push_back(e.path().filename().string());
  std::sort(names.begin(), names.end());
  return names;
}

namespace {

std::mutex g_scratchMutex;
std::set<fs::path>& scratchGroups() {
  static std::set<fs::path> groups;
  return groups;
}

}  // namespace

fs::path scratchDir(const std::string& group, const std::string& name) {
  const fs::path groupDir = fs::temp_directory_path() / (group + "-" + std::to_string(::getpid()));
  {
    const std::lock_guard<std::mutex> lock(g_scratchMutex);
    scratchGroups().insert(groupDir);
  }
  const fs::path dir = groupDir / name;
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

void finishScratchDirs(bool passed) {
  const std::lock_guard<std::mutex> lock(g_scratchMutex);
  const char* keep = std::getenv("DUPLEXFIT_KEEP_SCRATCH");
  const bool keepAll = !passed || (keep != nullptr && std::string(keep) == "1");
  for (const fs::path& dir : scratchGroups()) {
    if (keepAll) {
      std::cerr << "[duplexfit tests] scratch files kept in " << dir.string() << "\n";
    } else {
      std::error_code ec;
      fs::remove_all(dir, ec);
    }
  }
  scratchGroups().clear();
}

std::string readFile(const fs::path& path) {
  std::error_code ec;
  const auto size = fs::file_size(path, ec);
  if (ec) return {};
  std::string bytes(static_cast<std::size_t>(size), '\0');
  std::ifstream in(path, std::ios::binary);
  in.read(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  if (!in) return {};
  return bytes;
}

bool writeFile(const fs::path& path, const std::string& bytes) {
  // Remove first: truncating a file in place makes ext4 flush it (auto_da_alloc), which makes the
  // thousands of rewrites of the io fuzz test slow.
  std::error_code ec;
  fs::remove(path, ec);
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  return out.good();
}

}  // namespace duplexfit::testing
