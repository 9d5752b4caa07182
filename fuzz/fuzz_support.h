#pragma once

// Shared by the libFuzzer harnesses (test-only code, never linked into a product target).
#include <cstdio>
#include <cstdlib>
#include <string>
#include <string_view>

#include "apriori/floor_plan.h"

namespace wm::fuzz {

/// Stops the run with a message: libFuzzer reports the abort as a crash and saves the input.
[[noreturn]] inline void fail(const std::string& what) {
  std::fprintf(stderr, "fuzz finding: %s\n", what.c_str());
  std::abort();
}

/// A plan the server accepts is stored as its canonical JSON and parsed again at start-up, so the canonical
/// text must load and give back the same text (floor_plan.h promises parse(to_json_text(p)) == p).
inline void check_round_trip(const apriori::FloorPlan& plan) {
  const auto text = apriori::to_json_text(plan);
  apriori::FloorPlan again;
  try {
    again = apriori::parse_floor_plan_json(text);
  } catch (const apriori::FloorPlanError& e) {
    fail(std::string("the canonical JSON of an accepted plan does not load: ") + e.what());
  }
  if (apriori::to_json_text(again) != text) fail("the canonical JSON of an accepted plan changes when loaded again");
}

inline std::string_view as_text(const unsigned char* data, std::size_t size) {
  return {reinterpret_cast<const char*>(data), size};
}

}  // namespace wm::fuzz
