#pragma once

#include <charconv>
#include <cstdio>
#include <stdexcept>
#include <string>
#include <string_view>
#include <type_traits>

namespace wm {

/// A number given on a command line or in a config file, read whole by std::from_chars: no sign where T is
/// unsigned, no leading space or '+', no trailing text, and within [min, max] (std::stoul would take "-5" as
/// 2^64 − 5 and "3x" as 3; std::stod would take "0.5m" as 0.5 and "nan" as NaN).
/// @throw std::invalid_argument naming the flag, the range and the text.
template <typename T>
T parse_number(std::string_view flag, std::string_view text, T min, T max) {
  static_assert(std::is_arithmetic_v<T>);
  const auto shown = [](T v) {
    if constexpr (std::is_floating_point_v<T>) {
      char buffer[32];
      std::snprintf(buffer, sizeof buffer, "%g", static_cast<double>(v));
      return std::string(buffer);
    } else {
      return std::to_string(v);
    }
  };
  T value{};
  const auto [end, error] = std::from_chars(text.data(), text.data() + text.size(), value);
  if (text.empty() || error != std::errc() || end != text.data() + text.size() || !(value >= min && value <= max))
    throw std::invalid_argument(std::string(flag) + ": expected a number in [" + shown(min) + ", " + shown(max) +
                                "], got '" + std::string(text) + "'");
  return value;
}

}  // namespace wm
