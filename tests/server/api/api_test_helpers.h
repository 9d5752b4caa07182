#pragma once

// Requests in, responses out, through the api's router: no sockets, a FakeWorldPort behind it.
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>
#include <string>

#include "server/api/router.h"
#include "tests/server/api/fake_world_port.h"
#include "tests/support/lab_plan.h"

namespace wm::testing {

namespace http = boost::beast::http;

inline api::Request make_request(http::verb method, const std::string& target, const std::string& body = "",
                                 const std::string& content_type = "application/json") {
  api::Request request{method, target, 11};
  request.set(http::field::host, "127.0.0.1:8080");
  if (!body.empty()) {
    request.set(http::field::content_type, content_type);
    request.body() = body;
  }
  request.prepare_payload();
  return request;
}

/// The fake service and the api's options, and a way to send them a request.
class ApiTest : public ::testing::Test {
 protected:
  api::Response send(http::verb method, const std::string& target, const std::string& body = "",
                     const std::string& content_type = "application/json") {
    return send(make_request(method, target, body, content_type));
  }
  api::Response send(const api::Request& request) {
    api::Services services{options_, world_};
    services.diagnostics = diagnostics_;
    return api::handle_request(request, services);
  }
  static nlohmann::json json_of(const api::Response& response) {
    return nlohmann::json::parse(response.body(), nullptr, false);
  }
  /// The "error" code of a JSON error answer ("" when it is none).
  static std::string error_of(const api::Response& response) {
    const auto body = json_of(response);
    return body.is_object() ? body.value("error", "") : "";
  }
  static int status_of(const api::Response& response) { return static_cast<int>(response.result_int()); }

  /// A wall and a table, loaded as drawn.
  void load_demo_plan() {
    const apriori::FloorPlan plan = lab_plan();
    world_.load_plan(plan);
  }

  api::ApiOptions options_;
  FakeWorldPort world_;
  const common::Diagnostics* diagnostics_ = nullptr;  // as wmd's when a test sets it
};

}  // namespace wm::testing
