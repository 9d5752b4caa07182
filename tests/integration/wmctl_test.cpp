#include <fstream>
#include <map>
#include <string>
#include <vector>

#include "e2e_fixture.h"

namespace wm::testing {
namespace {

TEST_F(ServerFixture, WmctlLoadsPostsAndShows) {
  const auto plan_file = dir_.path() / "plan.json";
  std::ofstream(plan_file) << lab_plan().dump();
  auto r = run_command(wmctl(server_->url(), "floorplan load " + plan_file.string()));
  EXPECT_EQ(r.status, 0) << r.output;
  EXPECT_NE(r.output.find("loaded floor plan 'lab-e2e': 2 objects, 5 edges"), std::string::npos) << r.output;

  const auto primitives_file = dir_.path() / "primitives.json";
  std::ofstream(primitives_file) << R"({"source": "robot-7", "segments": [{"p0": [3, 10.004], "p1": [7, 9.998]},
                                                                          {"p0": [10, 3], "p1": [13, 3]}]})";
  r = run_command(wmctl(server_->url(), "primitives post " + primitives_file.string()));
  EXPECT_EQ(r.status, 0) << r.output;
  EXPECT_NE(r.output.find("delete"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("solid_confirmed"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("add"), std::string::npos) << r.output;

  r = run_command(wmctl(server_->url(), "--json map"));
  ASSERT_EQ(r.status, 0) << r.output;
  const auto map = json::parse(r.output);
  EXPECT_EQ(map["elements"].size(), 1u);
  EXPECT_EQ(map["elements"][0]["observer"], "robot-7");

  r = run_command(wmctl(server_->url(), "map"));
  EXPECT_EQ(r.status, 0);
  EXPECT_NE(r.output.find("object table-1"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("element e1"), std::string::npos) << r.output;

  r = run_command(wmctl(server_->url(), "decisions --since 1"));
  EXPECT_EQ(r.status, 0);
  EXPECT_NE(r.output.find("1 decisions"), std::string::npos) << r.output;

  // The primitives went through the matcher and the store once each.
  r = run_command(wmctl(server_->url(), "network"));
  EXPECT_EQ(r.status, 0) << r.output;
  EXPECT_NE(r.output.find("network <default network>"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("executor world: load"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("matcher.primitives (1 ports, priority 6): 1 activations"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("store.commit (1 ports, priority 0): 1 activations"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("matcher.primitives [fifo 256]: depth 0 (max 1), 1 in, 0 dropped, 0 refused"),
            std::string::npos)
      << r.output;
}

TEST_F(ServerFixture, WmctlFailsClearly) {
  // The server answers an error: exit 1 with the server's reason.
  const auto bad = dir_.path() / "bad.json";
  std::ofstream(bad) << R"({"objects": [{"id": "a"}]})";
  auto r = run_command(wmctl(server_->url(), "floorplan load " + bad.string()));
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.output.find("400"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("objects[0].kind"), std::string::npos) << r.output;
  // Nobody listens: exit 3 and say so.
  r = run_command(wmctl("http://127.0.0.1:1", "map"));
  EXPECT_EQ(r.status, 3);
  EXPECT_NE(r.output.find("cannot reach the server"), std::string::npos) << r.output;
  // A file that does not exist, an unknown command: usage error, exit 2.
  EXPECT_EQ(run_command(wmctl(server_->url(), "floorplan load /nonexistent.json")).status, 2);
  EXPECT_EQ(run_command(wmctl(server_->url(), "frobnicate")).status, 2);
}

// What each command takes, written out here rather than read from wmctl: {command, operands, {flag, a valid value}}.
struct CommandSpec {
  std::string name;
  std::string operands;
  std::vector<std::pair<std::string, std::string>> flags;
};

std::vector<CommandSpec> command_specs() {
  return {
      {"health", "", {}},
      {"network", "", {}},
      {"floorplan load", "plan.dxf", {{"--mapping", "m.json"}, {"--units", "mm"}, {"--level", "L1"}}},
      {"floorplan show", "", {}},
      {"primitives post", "p.json", {}},
      {"map", "", {{"--format", "dxf"}, {"--out", "map.dxf"}}},
      {"report", "", {}},
      {"decisions", "", {{"--since", "1"}, {"--limit", "5"}, {"--element", "e1"}}},
      {"explain", "e1", {}},
      {"rules", "", {}},
      {"rules reload", "", {}},
      {"rules dry-run", "r.pl", {{"--last", "3"}}},
      {"query", "true", {{"--max", "2"}}},
      {"replay",
       "x.log",
       {{"--limit", "1"},
        {"--every", "2"},
        {"--rate", "10"},
        {"--offset", "1,2"},
        {"--source", "r"},
        {"--range-max", "50"},
        {"--pose-sigma", "0.03,0.01"}}},
      {"grid", "--out g.pgm", {{"--out", "g.pgm"}, {"--layer", "bayes"}, {"--bbox", "0,0,1,1"}}},  // --out required
      {"grid extract", "", {}},
  };
}

// Nobody listens there: a command line that parses gets as far as the connection (or a local file) and no further.
std::string offline(const std::string& args) { return wmctl("http://127.0.0.1:1", args); }

TEST(WmctlUsageTest, HelpListsEveryCommandWithAllTheFlagsItTakes) {
  const auto all = run_command(offline("help"));
  ASSERT_EQ(all.status, 0) << all.output;
  EXPECT_EQ(run_command(offline("--help")).output, all.output);
  for (const auto& spec : command_specs()) {
    EXPECT_NE(all.output.find("  " + spec.name + (spec.operands.empty() && spec.flags.empty() ? "\n" : " ")),
              std::string::npos)
        << spec.name << " missing from\n"
        << all.output;
    const auto one = run_command(offline("help " + spec.name));
    ASSERT_EQ(one.status, 0) << one.output;
    for (const auto& [flag, value] : spec.flags) {
      EXPECT_NE(one.output.find(flag + " "), std::string::npos) << spec.name << ": " << one.output;
    }
  }
}

TEST(WmctlUsageTest, EveryFlagInTheUsageIsAccepted) {
  for (const auto& spec : command_specs()) {
    for (const auto& [flag, value] : spec.flags) {
      const auto r = run_command(offline(spec.name + " " + spec.operands + " " + flag + " " + value));
      EXPECT_EQ(r.output.find("unknown flag"), std::string::npos) << spec.name << " " << flag << ": " << r.output;
      EXPECT_EQ(r.output.find("takes no"), std::string::npos) << spec.name << " " << flag << ": " << r.output;
    }
  }
}

TEST(WmctlUsageTest, AnUnknownFlagIsRefusedWithTheCommandsUsage) {
  for (const auto& spec : command_specs()) {
    const auto r = run_command(offline(spec.name + " " + spec.operands + " --no-such-flag 1"));
    EXPECT_EQ(r.status, 2) << spec.name << ": " << r.output;
    EXPECT_NE(r.output.find("'--no-such-flag'"), std::string::npos) << r.output;
    EXPECT_NE(r.output.find("usage: wmctl [--server URL] [--map ID] [--token TOKEN] [--json] " + spec.name),
              std::string::npos)
        << r.output;
    for (const auto& [flag, value] : spec.flags) EXPECT_NE(r.output.find(flag), std::string::npos) << r.output;
  }
}

TEST(WmctlUsageTest, AnUnknownCommandOrAMissingArgumentIsAUsageError) {
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"frobnicate", "unknown command 'frobnicate'"},
      {"", "no command"},
      {"floorplan", "'floorplan' needs a subcommand: floorplan load, floorplan show"},
      {"replay", "replay needs LOG"},
      {"replay x.log --limit", "--limit needs N"},
      {"health now", "health takes no 'now'"},
      {"grid --layer bayes", "grid needs --out FILE.pgm"},
      {"map --format dxf", "map: --format and --out go together"},
      {"help frobnicate", "help: unknown command 'frobnicate'"},
  };
  for (const auto& [args, message] : cases) {
    const auto r = run_command(offline(args));
    EXPECT_EQ(r.status, 2) << args << ": " << r.output;
    EXPECT_NE(r.output.find("wmctl: " + message), std::string::npos) << args << ": " << r.output;
    EXPECT_NE(r.output.find("usage: wmctl"), std::string::npos) << args << ": " << r.output;
  }
}

}  // namespace
}  // namespace wm::testing
