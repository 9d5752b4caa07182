#pragma once

#include <gtest/gtest.h>
#include <unistd.h>

#include <atomic>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "rules/engine.h"

namespace wm::rules::testing {

/// The shipped rule file, copied into temporary directories by the tests.
inline std::filesystem::path shipped_world_model() {
  return std::filesystem::path(WM_RULES_PROLOG_DIR) / "world_model.pl";
}

inline std::string read_text(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw std::runtime_error("read_text: cannot open " + path.string());
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

inline void write_text(const std::filesystem::path& path, const std::string& text) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  if (!out) throw std::runtime_error("write_text: cannot open " + path.string());
  out << text;
}

/// Replaces the single occurrence of `from` in `text`; throws if there is not exactly one.
inline std::string replace_once(std::string text, const std::string& from, const std::string& to) {
  const auto at = text.find(from);
  if (at == std::string::npos || text.find(from, at + 1) != std::string::npos) {
    throw std::runtime_error("replace_once: '" + from + "' does not occur exactly once");
  }
  return text.replace(at, from.size(), to);
}

/// A fresh directory under the system temp dir, removed with its content at scope end.
class TempDir {
 public:
  TempDir() {
    static std::atomic<int> counter{0};
    path_ = std::filesystem::temp_directory_path() /
            ("wm_rules_test_" + std::to_string(::getpid()) + "_" + std::to_string(counter++));
    std::filesystem::remove_all(path_);
    std::filesystem::create_directories(path_);
  }
  ~TempDir() {
    std::error_code ec;
    std::filesystem::remove_all(path_, ec);
  }
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;

  const std::filesystem::path& path() const { return path_; }
  std::filesystem::path operator/(const std::string& name) const { return path_ / name; }

 private:
  std::filesystem::path path_;
};

/// A rules dir holding a copy of the shipped world_model.pl.
inline void copy_shipped_rules(const TempDir& dir) {
  write_text(dir / "world_model.pl", read_text(shipped_world_model()));
}

inline EngineOptions options_for(const TempDir& dir) {
  EngineOptions options;
  options.rules_dir = dir.path();
  return options;
}

/// w1: solid wall, t1: not_deformable table, d1: door without attributes.
inline std::vector<ObjectFacts> demo_floor_plan() {
  return {
      {"w1", "wall", {"solid"}, {{"w1_e0", 2.0, 0.0, 4.0}}},
      {"t1", "table", {"not_deformable"}, {{"t1_e0", 1.0, 1.5707963, 0.8}, {"t1_e1", 1.5, 0.0, 0.6}}},
      {"d1", "door", {}, {{"d1_e0", 3.0, 0.0, 0.9}}},
  };
}

inline DecisionQuery matched(std::string element, std::optional<std::string> object, double d2 = 0.5,
                             std::string source = "lidar") {
  DecisionQuery query;
  query.observer = std::move(source);
  query.rho_m = 2.0;
  query.phi_rad = 0.0;
  query.length_m = 3.5;
  query.element_id = std::move(element);
  query.object_id = std::move(object);
  query.mahalanobis_sq = d2;
  return query;
}

inline DecisionQuery unmatched(std::string source = "lidar") {
  DecisionQuery query;
  query.observer = std::move(source);
  query.rho_m = 1.25;
  query.phi_rad = -0.5;
  query.length_m = 2.0;
  return query;
}

/// A rule file answering `add`/`custom` for every case, except for the given source-specific clause
/// placed first (e.g. a loop or an error for source `spin`); `helpers` go after decide/5.
inline std::string rules_with_first_clause(const std::string& first_clause, const std::string& helpers = "") {
  return first_clause + "\n" + "decide(observation(_, _, _, _), _, add, custom, \"custom rules\").\n" + helpers + "\n";
}

/// An engine on a copy of the shipped rules (in dir_, for tests that edit them) with the demo floor plan.
class ShippedRulesTest : public ::testing::Test {
 protected:
  ShippedRulesTest() : engine_((copy_shipped_rules(dir_), options_for(dir_))) {
    engine_.set_floor_plan(demo_floor_plan());
  }

  TempDir dir_;  // declared before engine_: the copy is made first
  Engine engine_;
};

}  // namespace wm::rules::testing
