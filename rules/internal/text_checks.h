#pragma once

// Checks on texts before SWI-Prolog's reader sees them: rule files, dry-run candidates and queries.
// Internal to rules/.

#include <SWI-Prolog.h>

#include <cstddef>
#include <optional>
#include <string>
#include <string_view>

namespace wm::rules::internal {

/// What SWI-Prolog's reader must not see in a text. Found by fuzzing under AddressSanitizer, SWI-Prolog 9.0.4's
/// reader reads a freed buffer (strtol on the term's raw text after the buffer grew) on malformed UTF-8, and on a
/// number followed by a quote (0'c character codes, 16'FF radix numbers) that lies where the term's raw text
/// crosses 512, 1024, 2048, ... bytes; so no text reaches it unchecked.
struct TextProblem {
  std::size_t line = 0;  // 1-based
  std::size_t byte = 0;  // offset in the text
  std::string what;      // "not UTF-8" | "a NUL byte" | "a character code or radix number (0'...): ..."

  /// "byte <n>: <what>"
  std::string where() const { return "byte " + std::to_string(byte) + ": " + what; }
};

/// The first problem of `text`; nullopt when it is UTF-8 without NUL and quoted_number_problem() finds nothing.
std::optional<TextProblem> text_problem(std::string_view text);

/// The first number followed by a quote (0'c, 16'FF) outside comments and quoted texts, refused wherever it lies:
/// where the reader's buffer boundary falls depends on layout and comments the check cannot predict exactly.
std::optional<TextProblem> quoted_number_problem(std::string_view text);

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
