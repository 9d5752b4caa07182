#pragma once

// Test-only: a scratch directory under the system temp dir.
#include <unistd.h>

#include <filesystem>
#include <random>
#include <string>

namespace wm::testing {

/// A fresh temporary directory, removed at scope end.
class TempDir {
 public:
  TempDir() {
    std::random_device rd;
    path_ = std::filesystem::temp_directory_path() / ("wm-test-" + std::to_string(rd()) + std::to_string(::getpid()));
    std::filesystem::create_directories(path_);
  }
  ~TempDir() {
    std::error_code ignored;
    std::filesystem::remove_all(path_, ignored);
  }
  const std::filesystem::path& path() const { return path_; }

 private:
  std::filesystem::path path_;
};

}  // namespace wm::testing
