#pragma once

// Checks on texts before SWI-Prolog's reader sees them: rule files, dry-run candidates and queries.
// Internal to rules/.

#include <SWI-Prolog.h>

#include <cstddef>
#include <optional>
#include <string>
#include <string_view>

namespace wm::rules::internal {

/// Where a text stops being well-formed UTF-8 without NUL bytes. SWI-Prolog's reader misbehaves on
/// malformed UTF-8 (a heap use-after-free found by fuzzing), so no text reaches it unchecked.
struct TextProblem {
  std::size_t line = 0;  // 1-based
  std::size_t byte = 0;  // offset in the text
  std::string what;      // "not UTF-8" | "a NUL byte"

  /// "byte <n>: <what>"
  std::string where() const { return "byte " + std::to_string(byte) + ": " + what; }
};

/// The first problem of `text`; nullopt when it is UTF-8 without NUL.
std::optional<TextProblem> text_problem(std::string_view text);

/// @throw RuleError("<name>:<line>: rule text with byte <n>: ...") when text_problem() finds one, in the
///        "file:line: message" form of every load problem.
void check_rule_text(const std::string& name, std::string_view text);

/// check_rule_text() on the contents of the file at `path` (an unreadable file passes: the loader
/// reports it).
void check_rule_file_text(const std::string& path);

/// True when brackets ( [ { in `text` nest deeper than `max` outside quotes, character literals (0'c)
/// and comments; `line` (1-based) is where. The reader and the writer of SWI-Prolog recurse in C for
/// each level, so the depth is refused before the text is parsed.
bool nesting_exceeds(std::string_view text, int max, int& line);

/// Foreign predicate wm_engine:text_nesting_exceeds(+Text, +Max, -Line): nesting_exceeds() for Prolog.
/// Never throws (no C++ exception may cross into Prolog); fails on a bad argument.
foreign_t pl_text_nesting_exceeds(term_t text, term_t max, term_t line);

}  // namespace wm::rules::internal
