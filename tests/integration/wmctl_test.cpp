#include <fstream>

#include "e2e_fixture.h"

namespace wm::testing {
namespace {

std::string wmctl(const std::string& server, const std::string& args) {
  return std::string(WM_WMCTL_PATH) + " --server " + server + " " + args;
}

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

}  // namespace
}  // namespace wm::testing
