// POST /api/v1/query goals: Prolog text checked by the sandbox and run under the limits. Expected: solutions or a
// QueryError (syntax, unsafe, limit, failed); a RuleError or std::invalid_argument are refusals too.
#include <cstddef>
#include <cstdint>
#include <stdexcept>
#include <string>

#include "fuzz/engine_fixture.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static wm::fuzz::EngineFixture fixture;
  try {
    fixture.engine().query(std::string(wm::fuzz::as_text(data, size)), 10);
  } catch (const wm::rules::RuleError&) {  // QueryError derives from RuleError
  } catch (const std::invalid_argument&) {
  }
  return 0;
}
