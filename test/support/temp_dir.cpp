// Temporary folders and whole-file access for the tests (temp_dir.hpp).
#include "temp_dir.hpp"

#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <fstream>

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

fs::path scratchDir(const std::string& group, const std::string& name) {
  const fs::path dir = fs::temp_directory_path() / (group + "-" + std::to_string(::getpid())) / name;
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
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
