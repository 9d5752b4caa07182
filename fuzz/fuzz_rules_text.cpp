// POST /api/v1/rules/dry-run candidates: rule-file text loaded aside, checked and self-tested. The first byte
// chooses the file: even replaces the shipped world_model.pl (fuzzing decide/5 itself), odd adds "extra.pl"
// beside it (directives, clauses for other modules). Expected: decisions or a RuleError (load errors with
// file:line) or std::invalid_argument.
#include <cstddef>
#include <cstdint>
#include <stdexcept>
#include <string>

#include "fuzz/engine_fixture.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static wm::fuzz::EngineFixture fixture;
  if (size == 0) return 0;
  wm::rules::RuleText candidate{(data[0] & 1) ? "extra.pl" : "world_model.pl",
                                std::string(wm::fuzz::as_text(data + 1, size - 1))};
  try {
    fixture.engine().dry_run(candidate, {});
  } catch (const wm::rules::RuleError&) {
  } catch (const std::invalid_argument&) {
  }
  return 0;
}
