#pragma once

// Test-only: where a test finds the real data it reads (laser logs, floor plans nobody on the team wrote).
//
// One rule for the whole suite (tests/README.md): a file of the shared real-data directory (CMake's
// WM_SHARED_DATA_DIR, by default ../shared/data beside the checkout) is read there; when it is missing, the copy
// shipped in tests/data/ is read instead; when there is no copy, the test fails with the missing path in its
// message. Never GTEST_SKIP: a green suite must not hide what it did not check.
//
// A test target that includes this header defines WM_SHARED_DATA_DIR and WM_TEST_DATA_DIR (tests/data).
#include <filesystem>
#include <iostream>
#include <stdexcept>
#include <string>

#if !defined(WM_SHARED_DATA_DIR) || !defined(WM_TEST_DATA_DIR)
#error "targets using support/test_data.h define WM_SHARED_DATA_DIR and WM_TEST_DATA_DIR"
#endif

namespace wm::testing {

/// The real-data file `relative` (e.g. "carmen/intel-corrected.log.gz") under WM_SHARED_DATA_DIR; if that is
/// missing, tests/data/`shipped_copy` when one is named and present.
/// @throw std::runtime_error naming the paths looked for when neither exists, which fails the calling test.
inline std::filesystem::path real_data(const std::string& relative, const std::string& shipped_copy = {}) {
  const auto shared = std::filesystem::path(WM_SHARED_DATA_DIR) / relative;
  if (std::filesystem::exists(shared)) return shared;
  if (!shipped_copy.empty()) {
    const auto copy = std::filesystem::path(WM_TEST_DATA_DIR) / shipped_copy;
    if (std::filesystem::exists(copy)) {
      std::cerr << "[test data] " << shared.string() << " is missing; reading the shipped copy " << copy.string()
                << "\n";
      return copy;
    }
    throw std::runtime_error("missing real data: " + shared.string() + " and its shipped copy " + copy.string());
  }
  throw std::runtime_error(
      "missing real data: " + shared.string() +
      " (no copy in tests/data; set the CMake variable WM_SHARED_DATA_DIR to the real-data directory)");
}

}  // namespace wm::testing
