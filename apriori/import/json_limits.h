#pragma once

#include <cstddef>
#include <optional>
#include <string>
#include <string_view>

namespace wm::apriori {

/// Deepest nesting of JSON arrays and objects accepted anywhere (request bodies, floor plans, layer mappings,
/// vector maps). nlohmann's DOM copies, compares and destroys values recursively: 100 000 nested objects
/// overflow the stack (10 000 under ASan). Real documents stay far below: a floor plan nests 6 levels.
inline constexpr std::size_t kMaxJsonDepth = 64;

/// Checks the nesting of JSON text before a parser sees it: one pass over the bytes, counting `[`/`{`
/// against `]`/`}` outside strings (escapes honoured). Says nothing about whether the text is valid JSON;
/// the parser that follows does. Returns the refusal ("nested deeper than 64 levels at byte 1234"), or
/// nullopt when the text stays within `max_depth`. Never throws, allocates only the message.
inline std::optional<std::string> json_nesting_error(std::string_view text, std::size_t max_depth = kMaxJsonDepth) {
  std::size_t depth = 0;
  bool in_string = false;
  for (std::size_t i = 0; i < text.size(); ++i) {
    const char c = text[i];
    if (in_string) {
      if (c == '\\') {
        ++i;  // the escaped character, whatever it is, cannot end the string
      } else if (c == '"') {
        in_string = false;
      }
      continue;
    }
    if (c == '"') {
      in_string = true;
    } else if (c == '[' || c == '{') {
      if (++depth > max_depth)
        return "JSON nested deeper than " + std::to_string(max_depth) + " levels at byte " + std::to_string(i);
    } else if ((c == ']' || c == '}') && depth > 0) {
      --depth;
    }
  }
  return std::nullopt;
}

}  // namespace wm::apriori
