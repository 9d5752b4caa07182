#pragma once

#include <cmath>
#include <filesystem>
#include <memory>
#include <stdexcept>
#include <string>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "clients/wmctl/http_client.h"
#include "support/wmd_process.h"

namespace wm::testing {

using nlohmann::json;

/// A file of the real data beside the checkout (../shared/data); throws when it is missing.
inline std::filesystem::path shared(const std::string& relative) {
  const auto path = std::filesystem::path(WM_SHARED_DATA) / relative;
  if (!std::filesystem::exists(path)) throw std::runtime_error("missing real data file " + path.string());
  return path;
}

/// The lab of the foundation issue: a solid wall, a rotated not_deformable table, free space elsewhere.
inline json lab_plan() {
  return json::parse(R"({
    "name": "lab-e2e", "units": "m",
    "objects": [
      {"id": "wall-n", "kind": "wall", "attributes": ["solid"], "pose": {"x": 0, "y": 0, "theta": 0},
       "segments": [[[0, 10], [20, 10]]]},
      {"id": "table-1", "kind": "table", "attributes": ["not_deformable"], "pose": {"x": 5, "y": 5, "theta": 0.3},
       "polygon": [[-0.6, -0.4], [0.6, -0.4], [0.6, 0.4], [-0.6, 0.4]]}]})");
}

/// Starts wmd on a fresh database in a temporary directory; restart() keeps the file.
class ServerFixture : public ::testing::Test {
 protected:
  void SetUp() override { start(); }

  void start() {
    std::vector<std::string> args{"--db", (dir_.path() / "wm.db").string(), "--port", "0", "--rules", rules_dir_};
    args.insert(args.end(), extra_args_.begin(), extra_args_.end());
    server_ = std::make_unique<WmdProcess>(args);
    client_ = std::make_unique<client::HttpClient>(server_->url());
  }
  void restart() {
    ASSERT_EQ(server_->stop(), 0) << server_->output();
    start();
  }

  client::HttpResult call(const std::string& method, const std::string& target, const std::string& body = {},
                          const std::string& type = "application/json") {
    return client_->request(method, target, body, type);
  }
  json get_json(const std::string& target) {
    auto r = call("GET", target);
    EXPECT_EQ(r.status, 200) << r.body;
    return json::parse(r.body);
  }
  json send_json(const std::string& method, const std::string& target, const json& body, int expected_status = 200) {
    auto r = call(method, target, body.dump());
    EXPECT_EQ(r.status, expected_status) << r.body;
    return json::parse(r.body);
  }

  TempDir dir_;
  std::string rules_dir_ = WM_RULES_DIR;
  std::vector<std::string> extra_args_;
  std::unique_ptr<WmdProcess> server_;
  std::unique_ptr<client::HttpClient> client_;
};

}  // namespace wm::testing
