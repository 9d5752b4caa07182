#include "rules/internal/text_checks.h"

#include <algorithm>
#include <cctype>
#include <fstream>
#include <sstream>

#include "common/utf8.h"
#include "rules/internal/prolog_api.h"
#include "rules/types.h"

namespace wm::rules::internal {

std::optional<TextProblem> text_problem(std::string_view text) {
  std::size_t at = text.find('\0');
  std::string what = "a NUL byte";
  if (const auto bad = common::invalid_utf8_offset(text); bad && *bad < at) {
    at = *bad;
    what = "not UTF-8";
  }
  if (at == std::string_view::npos) return quoted_number_problem(text);
  const auto newlines = std::count(text.begin(), text.begin() + static_cast<std::ptrdiff_t>(at), '\n');
  return TextProblem{1 + static_cast<std::size_t>(newlines), at, what};
}

void check_rule_text(const std::string& name, std::string_view text) {
  if (const auto problem = text_problem(text)) {
    throw RuleError(name + ":" + std::to_string(problem->line) + ": rule text with " + problem->where());
  }
}

void check_rule_file_text(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream text;
  text << in.rdbuf();
  check_rule_text(path, text.str());
}

namespace {

bool continues_name(char c) { return std::isalnum(static_cast<unsigned char>(c)) || c == '_'; }

// Walks `text` as SWI-Prolog's tokenizer sees its structure: comments, quoted atoms, strings, back-quoted texts
// and character literals (0'c) are stepped over; visit(i, line) sees every other byte and stops the walk by
// returning true. Returns whether it was stopped.
template <typename Visit>
bool walk_code(std::string_view text, const Visit& visit) {
  int line = 1;
  for (std::size_t i = 0; i < text.size(); ++i) {
    const char c = text[i];
    if (c == '\n') {
      ++line;
    } else if (c == '%') {
      while (i + 1 < text.size() && text[i + 1] != '\n') ++i;
    } else if (c == '/' && i + 1 < text.size() && text[i + 1] == '*') {
      for (i += 2; i + 1 < text.size() && !(text[i] == '*' && text[i + 1] == '/'); ++i) line += text[i] == '\n';
      ++i;
    } else if (visit(i, line)) {
      return true;
    } else if (c == '0' && i + 1 < text.size() && text[i + 1] == '\'' && (i == 0 || !continues_name(text[i - 1]))) {
      i += 2;  // 0'c: skip the character, an escape's backslash or a doubled quote with it
      if (i < text.size() && (text[i] == '\\' || (text[i] == '\'' && i + 1 < text.size() && text[i + 1] == '\''))) ++i;
    } else if (c == '\'' || c == '"' || c == '`') {
      for (++i; i < text.size(); ++i) {
        if (text[i] == '\\') {
          ++i;
        } else if (text[i] == c) {
          if (i + 1 < text.size() && text[i + 1] == c)
            ++i;  // a doubled quote stands for itself
          else
            break;
        } else if (text[i] == '\n') {
          ++line;
        }
      }
    }
  }
  return false;
}

}  // namespace

std::optional<TextProblem> quoted_number_problem(std::string_view text) {
  std::optional<TextProblem> problem;
  walk_code(text, [&](std::size_t i, int line) {
    if (!std::isdigit(static_cast<unsigned char>(text[i])) || (i > 0 && continues_name(text[i - 1]))) return false;
    std::size_t end = i;
    while (end < text.size() && std::isdigit(static_cast<unsigned char>(text[end]))) ++end;
    if (end >= text.size() || text[end] != '\'') return false;
    problem = TextProblem{static_cast<std::size_t>(line), i,
                          "a character code or radix number (" + std::string(text.substr(i, end + 1 - i)) +
                              "...): SWI-Prolog 9.0.4's reader can read freed memory on these; write the number "
                              "itself (0'a is 97, 16'FF is 255) or use char_code/2"};
    return true;
  });
  return problem;
}

bool nesting_exceeds(std::string_view text, int max, int& line) {
  int depth = 0;
  line = 1;
  return walk_code(text, [&](std::size_t i, int at) {
    const char c = text[i];
    if (c == '(' || c == '[' || c == '{') {
      line = at;
      return ++depth > max;
    }
    if (c == ')' || c == ']' || c == '}') depth = std::max(0, depth - 1);
    return false;
  });
}

foreign_t pl_text_nesting_exceeds(term_t text, term_t max, term_t line) {
  try {
    auto chars = text_of(text);
    int limit = 0;
    if (!chars || !PL_get_integer(max, &limit)) return false;
    int at = 0;
    return nesting_exceeds(*chars, limit, at) && PL_unify_integer(line, at);
  } catch (...) {
    return false;
  }
}

}  // namespace wm::rules::internal
