// wmd's options as users read about them: every flag of the usage text appears in the README's wmd synopsis.
#include "server/config/server_config.h"

#include <gtest/gtest.h>

#include <fstream>
#include <regex>
#include <set>
#include <sstream>
#include <string>

namespace wm::testing {
namespace {

// The flags at the start of the usage text's lines ("  --name ...").
std::set<std::string> usage_flags() {
  std::set<std::string> flags;
  std::istringstream lines(config::usage());
  const std::regex option(R"(^\s+(--[a-z0-9-]+))");
  std::smatch match;
  for (std::string line; std::getline(lines, line);)
    if (std::regex_search(line, match, option)) flags.insert(match[1]);
  return flags;
}

// The code block after the README's "## wmd" heading.
std::string readme_synopsis() {
  std::ifstream in(std::string(WM_SOURCE_DIR) + "/README.md");
  std::stringstream text;
  text << in.rdbuf();
  const auto all = text.str();
  const auto section = all.find("\n## wmd\n");
  if (section == std::string::npos) return "";
  const auto open = all.find("```", section);
  const auto close = all.find("```", open + 3);
  return open == std::string::npos || close == std::string::npos ? "" : all.substr(open, close - open);
}

TEST(ServerConfigTest, TheReadmeSynopsisNamesEveryFlagOfTheUsage) {
  const auto synopsis = readme_synopsis();
  ASSERT_FALSE(synopsis.empty()) << "no code block under '## wmd' in README.md";
  const auto flags = usage_flags();
  EXPECT_GT(flags.size(), 30u);
  for (const auto& flag : flags) {
    const std::regex whole(flag + R"((?![a-z0-9-]))");
    EXPECT_TRUE(std::regex_search(synopsis, whole)) << flag << " is missing from the README's wmd synopsis";
  }
}

}  // namespace
}  // namespace wm::testing
