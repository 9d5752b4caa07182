// parse_number: whole text only, in range, one error that names the flag, the range and the text.
#include "common/parse_number.h"

#include <gtest/gtest.h>

#include <cstddef>
#include <cstdint>
#include <stdexcept>
#include <string>

namespace wm {
namespace {

std::string error_of(const auto& parse) {
  try {
    parse();
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return "no error";
}

TEST(ParseNumberTest, ReadsWholeNumbersWithinTheRange) {
  EXPECT_EQ(parse_number<std::size_t>("--seed", "0", 0, 10), 0u);
  EXPECT_EQ(parse_number<std::size_t>("--seed", "10", 0, 10), 10u);
  EXPECT_EQ(parse_number<int>("--beams", "-3", -5, 5), -3);
  EXPECT_DOUBLE_EQ(parse_number<double>("--step", "0.25", 0.01, 100), 0.25);
  EXPECT_DOUBLE_EQ(parse_number<double>("--step", "1e-2", 0.01, 100), 0.01);
  EXPECT_EQ(parse_number<std::uint64_t>("--bytes", "18446744073709551615", 0, UINT64_MAX), UINT64_MAX);
}

TEST(ParseNumberTest, RefusesSignsTrailingTextNanAndNumbersOutOfRange) {
  for (const std::string text : {"", "-5", "+5", " 5", "5 ", "3x", "0x10", "11", "99999999999999999999999"})
    EXPECT_THROW(parse_number<std::size_t>("--seed", text, 0, 10), std::invalid_argument) << text;
  for (const std::string text : {"nan", "inf", "-inf", "0.5m", "1e400", "", ".", "100.5"})
    EXPECT_THROW(parse_number<double>("--step", text, 0.01, 100), std::invalid_argument) << text;
}

TEST(ParseNumberTest, TheErrorNamesTheFlagTheRangeAndTheText) {
  EXPECT_EQ(error_of([] { parse_number<std::size_t>("--seed", "-5", 0, 999); }),
            "--seed: expected a number in [0, 999], got '-5'");
  EXPECT_EQ(error_of([] { parse_number<double>("--step", "0.5m", 0.01, 100); }),
            "--step: expected a number in [0.01, 100], got '0.5m'");
}

}  // namespace
}  // namespace wm
