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

// --store takes a PostgreSQL URI, never with a password in it (the command line is readable by other users), and
// --store-schema a name the store can put into SQL; --db stays a file.
TEST(ServerConfigTest, AStoreUriWithAPasswordOrABadSchemaIsRefused) {
  const std::filesystem::path rules = std::string(WM_SOURCE_DIR) + "/rules/prolog";
  const auto parse = [&](std::vector<std::string> args) { return config::parse_command_line(args, rules); };
  auto c = parse({"--store", "postgresql://wm@db.example:5432/site", "--store-schema", "floor-1"});
  EXPECT_EQ(c.store.path, "postgresql://wm@db.example:5432/site");
  EXPECT_EQ(c.store.postgres_schema, "floor-1");
  EXPECT_EQ(parse({"--db", "a.db"}).store.path, "a.db");
  for (const std::string uri :
       {"postgresql://wm:secret@db.example/site", "postgres://wm:@db/site",
        "postgresql://db.example/site?sslmode=require&password=secret", "postgresql://db.example/site?password=secret"})
    EXPECT_THROW(parse({"--store", uri}), config::ConfigError) << uri;
  // A colon after the host (its port) is not a password.
  EXPECT_NO_THROW(parse({"--store", "postgresql://wm@db.example:5432/site?application_name=wmd"}));
  for (const std::string& schema :
       std::vector<std::string>{"", "Floor", "1floor", "a;drop", "a b", "x\"y", std::string(64, 'a')})
    EXPECT_THROW(parse({"--store", "postgresql://wm@db/site", "--store-schema", schema}), config::ConfigError)
        << schema;
}

// The sonar gate and the DS decision thresholds: on/off and three numbers in range, anything else refused.
TEST(ServerConfigTest, SonarGateAndDecisionThresholdsAreCheckedAtStart) {
  const std::filesystem::path rules = std::string(WM_SOURCE_DIR) + "/rules/prolog";
  const auto parse = [&](std::vector<std::string> args) { return config::parse_command_line(args, rules); };
  EXPECT_TRUE(parse({}).service.grids.laser_sonar.gate_sonar) << "on by default";
  EXPECT_FALSE(parse({"--sonar-gate", "off"}).service.grids.laser_sonar.gate_sonar);
  const auto decision = parse({"--ds-decision", "0.7,0.3,1.5"}).service.grids.laser_sonar.decision;
  EXPECT_DOUBLE_EQ(decision.occupied_belief_min, 0.7);
  EXPECT_DOUBLE_EQ(decision.free_plausibility_max, 0.3);
  EXPECT_DOUBLE_EQ(decision.conflict_min, 1.5);
  for (const std::vector<std::string>& bad : {std::vector<std::string>{"--sonar-gate", "yes"},
                                              {"--ds-decision", "0.7,0.3"},
                                              {"--ds-decision", "0.7,nan,0.5"},
                                              {"--ds-decision", "0,0.3,0.5"},
                                              {"--ds-decision", "0.7,1,0.5"},
                                              {"--ds-decision", "0.7,0.3,0.5,1"}})
    EXPECT_THROW(parse(bad), config::ConfigError) << bad[1];
}

}  // namespace
}  // namespace wm::testing
