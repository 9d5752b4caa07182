#pragma once

// The knowledge base the query and rule-text harnesses fuzz: one rules::Engine per process (SWI-Prolog starts
// once per process) on a temporary copy of the shipped rules, with a small plan, elements and decisions, so
// that queries and candidate rules find facts to work on.
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <iterator>
#include <memory>
#include <string>

#include "fuzz/fuzz_support.h"
#include "rules/engine.h"

namespace wm::fuzz {

class EngineFixture {
 public:
  EngineFixture() {
    dir_ = std::filesystem::temp_directory_path() / ("wm-fuzz-rules-" + std::to_string(::getpid()));
    std::filesystem::create_directories(dir_);
    std::ifstream in(std::filesystem::path(WM_RULES_PROLOG_DIR) / "world_model.pl", std::ios::binary);
    std::ofstream out(dir_ / "world_model.pl", std::ios::binary | std::ios::trunc);
    out << std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
    if (!in || !out) fail("cannot copy the shipped rules to " + dir_.string());
    out.close();
    rules::EngineOptions options;
    options.rules_dir = dir_;
    // Tighter than the server's defaults (200 000 inferences, 1 s) so that endless goals cost little fuzzing
    // time; the limits are enforced the same way.
    options.inference_limit = 50000;
    options.time_limit_s = 0.25;
    // The first load runs the self-check under that time limit; on a machine busy with other fuzzing workers and
    // builds it can miss it (seen once in fork mode). A start-up failure is not a finding: try again.
    for (int attempt = 1;; ++attempt) {
      try {
        engine_ = std::make_unique<rules::Engine>(options);
        break;
      } catch (const rules::RuleError&) {
        if (attempt == 5) throw;
        ::sleep(1);
      }
    }
    engine_->set_floor_plan(
        {{"w1", "wall", {"solid"}, {{"w1_e0", 2.0, 0.0, 4.0}}},
         {"t1", "table", {"not_deformable"}, {{"t1_e0", 1.0, 1.5708, 1.2}, {"t1_e1", 3.0, 0.0, 0.8}}},
         {"d1", "door", {"movable"}, {{"d1_e0", 5.0, 3.1416, 0.9}}}});
    engine_->set_elements(
        {{"e1", "client", "robot-1", 4.0, 0.5, 2.0, 3, 1.7e9}, {"e2", "scan", "robot-2", 1.0, -1.0, 0.5, 1, 1.7e9}});
    engine_->add_decisions({{1, "delete", "solid_confirmed", "w1_e0", "w1", "robot-1", 1.7e9},
                            {2, "add", "unmatched", "e1", std::nullopt, "robot-1", 1.7e9}},
                           10000);
  }
  ~EngineFixture() {
    engine_.reset();
    std::error_code ec;
    std::filesystem::remove_all(dir_, ec);
  }
  EngineFixture(const EngineFixture&) = delete;
  EngineFixture& operator=(const EngineFixture&) = delete;

  rules::Engine& engine() { return *engine_; }

 private:
  std::filesystem::path dir_;
  std::unique_ptr<rules::Engine> engine_;
};

}  // namespace wm::fuzz
