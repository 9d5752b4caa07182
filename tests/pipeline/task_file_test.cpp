#include <gtest/gtest.h>
#include <sys/stat.h>
#include <unistd.h>

#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iostream>

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

TEST(TaskFileTest, ReadsSubtasksAndRefusesMalformedOnes) {
  const std::string head = "components: {a: {kind: k}, b: {kind: k}}\nexecutors: {e: [a, b]}\n";
  const auto spec = parse_task(
      head + "subtasks:\n  slow: {components: [b], running: false}\n  quick: {components: [a]}\n", "net.yaml");
  ASSERT_EQ(spec.subtasks.size(), 2u);
  EXPECT_EQ(spec.subtasks[0].name, "slow");
  EXPECT_EQ(spec.subtasks[0].components, std::vector<std::string>{"b"});
  EXPECT_FALSE(spec.subtasks[0].running);
  EXPECT_TRUE(spec.subtasks[1].running);
  EXPECT_NE(parse_error(head + "subtasks:\n  s: {components: [b], running: maybe}\n")
                .find("net.yaml:4: subtask 's': running must be true or false"),
            std::string::npos);
  EXPECT_NE(parse_error(head + "subtasks:\n  s: {executors: [e]}\n")
                .find("net.yaml:4: subtask 's': unknown key 'executors' (components, running)"),
            std::string::npos);
  EXPECT_NE(parse_error(head + "subtasks:\n  s: {running: true}\n").find("subtask 's' names no component"),
            std::string::npos);
  EXPECT_NE(parse_error(head + "subtasks: [b]\n").find("'subtasks' must map names to"), std::string::npos);
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

TEST(TaskFileTest, AnExecutorWithoutComponentsIsRefused) {
  EXPECT_NE(parse_error("components: {a: {kind: k}}\nexecutors: {e: [a], idle: []}\n")
                .find("net.yaml:2: executor 'idle' runs no component"),
            std::string::npos);
}

TEST(TaskFileTest, TooManyExecutorsOrComponentsAreRefused) {
  std::string yaml = "components: {a: {kind: k}}\nexecutors:\n";
  for (std::size_t i = 0; i <= kMaxExecutors; ++i) yaml += "  e" + std::to_string(i) + ": [a]\n";
  EXPECT_NE(parse_error(yaml).find("more than 64 executors (each is a thread)"), std::string::npos);
  yaml = "executors: {e: [c0]}\ncomponents:\n";
  for (std::size_t i = 0; i <= kMaxComponents; ++i) yaml += "  c" + std::to_string(i) + ": {kind: k}\n";
  EXPECT_NE(parse_error(yaml).find("more than 256 components"), std::string::npos);
}

std::string read_error(const std::string& path) {
  try {
    read_task_file(path);
  } catch (const NetworkError& e) {
    return e.what();
  }
  return "";
}

TEST(TaskFileTest, MissingFileNamed) {
  EXPECT_EQ(read_error("/nonexistent/net.yaml"), "/nonexistent/net.yaml: cannot be read (No such file or directory)");
}

TEST(TaskFileTest, OnlyARegularFileOfBoundedSizeIsRead) {
  // Each of these used to block or read forever; a death test bounds the time so that a hang fails.
  EXPECT_EXIT(
      {
        ::alarm(10);
        const auto dir = std::filesystem::temp_directory_path() / ("task_fifo_" + std::to_string(::getpid()));
        std::filesystem::create_directories(dir);
        const auto fifo = (dir / "net.yaml").string();
        const bool made = ::mkfifo(fifo.c_str(), 0600) == 0;
        const auto fifo_error = read_error(fifo);
        std::filesystem::remove_all(dir);
        bool ok = made && fifo_error == fifo + ": not a regular file";
        for (const std::string path : {"/dev/zero", "/dev/urandom", "/tmp"}) {
          const auto error = read_error(path);
          ok = ok && error == path + ": not a regular file";
          std::cerr << path << ": " << error << "\n";  // shown when the test fails
        }
        std::exit(ok ? 0 : 1);
      },
      ::testing::ExitedWithCode(0), "");

  const auto big = std::filesystem::temp_directory_path() / ("task_big_" + std::to_string(::getpid()) + ".yaml");
  {
    std::ofstream out(big);
    out << "description: \"" << std::string(kMaxTaskFileBytes, 'x') << "\"\n";
  }
  EXPECT_EQ(read_error(big.string()), big.string() + ": larger than 1024 KiB: not a task file");
  std::filesystem::remove(big);
}

}  // namespace
}  // namespace wm::pipeline
