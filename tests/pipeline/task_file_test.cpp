#include <gtest/gtest.h>

#include "pipeline/network.h"

namespace wm::pipeline {
namespace {

std::string parse_error(const std::string& yaml) {
  try {
    parse_task(yaml, "net.yaml");
  } catch (const NetworkError& e) {
    return e.what();
  }
  return "";
}

TEST(TaskFileTest, ReadsComponentsConnectionsAndExecutors) {
  const auto spec = parse_task(R"(
description: two stages
components:
  grid:
    kind: grid
    functions: [laser, sonar]
    priorities: [laser, sonar]
    ports: {laser: {capacity: 8, policy: latest}}
    params: {every: 5}
  lines: {kind: grid_lines}
connections:
  - grid.tick -> lines.tick
executors:
  maps: [grid]
  slow: [lines]
)",
                               "net.yaml");
  ASSERT_EQ(spec.components.size(), 2u);
  EXPECT_EQ(spec.components[0].name, "grid");
  EXPECT_EQ(*spec.components[0].functions, (std::vector<std::string>{"laser", "sonar"}));
  EXPECT_EQ(spec.components[0].capacities.at("laser"), 8u);
  EXPECT_EQ(spec.components[0].policies.at("laser"), PortPolicy::latest);
  EXPECT_EQ(spec.components[0].params.number("every", 0, 0, 100), 5);
  EXPECT_FALSE(spec.components[1].functions.has_value());
  ASSERT_EQ(spec.connections.size(), 1u);
  EXPECT_EQ(spec.connections[0].from_component, "grid");
  EXPECT_EQ(spec.connections[0].to_port, "tick");
  ASSERT_EQ(spec.executors.size(), 2u);
  EXPECT_EQ(spec.executors[1].name, "slow");
  EXPECT_EQ(spec.executors[1].components, (std::vector<std::string>{"lines"}));
}

TEST(TaskFileTest, RefusesWithTheFileLineAndReason) {
  EXPECT_NE(parse_error("components: {a: {kind: k}}\nexecutors: {e: [a]}\nconnections: [a.out b.in]\n")
                .find("net.yaml:3: connection 'a.out b.in' must read 'a.out -> b.in'"),
            std::string::npos);
  EXPECT_NE(parse_error("components: {a: {kind: k, ports: {x: {capacity: 0}}}}\nexecutors: {e: [a]}\n")
                .find("capacity of 'x' must be a whole number in [1, 1000000]"),
            std::string::npos);
  EXPECT_NE(parse_error("components: {a: {kind: k, ports: {x: {policy: lifo}}}}\nexecutors: {e: [a]}\n")
                .find("policy of 'x' must be fifo or latest"),
            std::string::npos);
  EXPECT_NE(parse_error("components: {a: {knd: k}}\nexecutors: {e: [a]}\n").find("unknown key 'knd'"),
            std::string::npos);
  EXPECT_NE(parse_error("components: {a: {kind: k}}\n").find("'executors' must map"), std::string::npos);
  EXPECT_NE(parse_error("components: [\n").find("net.yaml:"), std::string::npos);
  EXPECT_NE(parse_error("- a\n").find("net.yaml: a task file is a map"), std::string::npos);
  Params params(std::map<std::string, std::string>{{"every", "ten"}});
  EXPECT_THROW(params.number("every", 0, 0, 100), std::invalid_argument);
}

TEST(TaskFileTest, MissingFileNamed) {
  try {
    read_task_file("/nonexistent/net.yaml");
    FAIL();
  } catch (const NetworkError& e) {
    EXPECT_STREQ(e.what(), "/nonexistent/net.yaml: cannot be read");
  }
}

}  // namespace
}  // namespace wm::pipeline
