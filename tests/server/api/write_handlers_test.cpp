// The handlers that change state, plus queries and dry runs: each route's success and its documented refusals
// (400, 401, 403, 409, 415, 422, 503), through the router, against a fake of the service port.
#include <gtest/gtest.h>

#include "server/api/handlers.h"
#include "tests/server/api/api_test_helpers.h"

namespace wm::testing {
namespace {

using http::verb;

constexpr const char* kPrimitives = R"({"source": "robot-1", "segments": [{"p0": [1, 2], "p1": [4, 2.05]}]})";
constexpr const char* kScan = R"({"sensor": "laser", "source": "robot-1", "pose": {"x": 0, "y": 0, "theta": 0},
  "angle_min": -0.1, "angle_increment": 0.1, "ranges": [2, 2, 2], "range_max": 8})";
constexpr const char* kPlan = R"({"name": "lab", "objects": [{"id": "wall-n", "kind": "wall", "attributes": ["solid"],
  "segments": [[[0, 10], [20, 10]]]}]})";

class WriteHandlersTest : public ApiTest {};

TEST_F(WriteHandlersTest, PrimitivesAreParsedAndPostedWithTheirRequestId) {
  auto request = make_request(verb::post, "/api/v1/primitives", kPrimitives);
  request.set("Idempotency-Key", "\"abc-1\"");
  const auto response = send(request);
  ASSERT_EQ(status_of(response), 200) << response.body();
  const auto body = json_of(response);
  EXPECT_EQ(body["seq"], 7);
  EXPECT_EQ(body["decisions"][0]["action"], "add");
  EXPECT_EQ(world_.last_observation->observer, "robot-1");
  EXPECT_EQ(world_.last_request_id, "abc-1");
  EXPECT_EQ(world_.last_payload, kPrimitives);
  EXPECT_EQ(response["Idempotent-Replayed"], "");
  world_.replay = true;
  EXPECT_EQ(send(request)["Idempotent-Replayed"], "true");
}

TEST_F(WriteHandlersTest, PrimitivesRefusals) {
  auto response = send(verb::post, "/api/v1/primitives", R"({"segments": [{"p0": [1, 2], "p1": [1e400, 2]}]})");
  EXPECT_EQ(status_of(response), 400);
  response = send(verb::post, "/api/v1/primitives", R"({"segments": [{"p0": [1, 2], "p1": ["x", 2]}]})");
  EXPECT_EQ(status_of(response), 400);
  EXPECT_EQ(json_of(response)["detail"], "segments[0].p1[0]: expected a number");
  response = send(verb::post, "/api/v1/primitives", "");
  EXPECT_EQ(status_of(response), 400);
  EXPECT_EQ(json_of(response)["detail"], "empty body");
  response = send(verb::post, "/api/v1/primitives", kPrimitives, "text/plain");
  EXPECT_EQ(status_of(response), 415);
  EXPECT_EQ(error_of(response), "unsupported_media_type");
  auto bad_id = make_request(verb::post, "/api/v1/primitives", kPrimitives);
  bad_id.set("Idempotency-Key", "with space");
  response = send(bad_id);
  EXPECT_EQ(status_of(response), 400);
  EXPECT_NE(json_of(response)["detail"].get<std::string>().find("Idempotency-Key"), std::string::npos);
  world_.fail_next(std::make_exception_ptr(service::RequestIdConflict("request id 'a' was used with another body")));
  EXPECT_EQ(status_of(send(verb::post, "/api/v1/primitives", kPrimitives)), 409);
  world_.fail_next(std::make_exception_ptr(service::Busy("the world model's write queue is full")));
  EXPECT_EQ(status_of(send(verb::post, "/api/v1/primitives", kPrimitives)), 503);
  EXPECT_EQ(world_.calls, (std::vector<std::string>{"post_primitives", "post_primitives"}));
}

TEST_F(WriteHandlersTest, WritesNeedTheTokenWhenOneIsConfigured) {
  options_.token = "s3cret";
  for (const auto& [method, target, body] : {std::tuple{verb::post, "/api/v1/primitives", kPrimitives},
                                             {verb::post, "/api/v1/scans", kScan},
                                             {verb::put, "/api/v1/floorplan", kPlan},
                                             {verb::post, "/api/v1/rules/reload", ""},
                                             {verb::post, "/api/v1/grid/extract", ""}}) {
    auto request = make_request(method, target, body);
    EXPECT_EQ(status_of(send(request)), 401) << target;
    request.set(http::field::authorization, "bearer   s3cret");
    EXPECT_EQ(status_of(send(request)), 200) << target;
  }
}

TEST_F(WriteHandlersTest, CrossSiteWritesAreRefusedAndSameOriginPasses) {
  auto request = make_request(verb::post, "/api/v1/primitives", kPrimitives);
  request.set(http::field::origin, "http://attacker.example");
  EXPECT_EQ(status_of(send(request)), 403);
  request.set(http::field::origin, "http://127.0.0.1:8080");
  EXPECT_EQ(status_of(send(request)), 200);
  options_.allowed_origins = {"http://viewer.example:3000"};
  request.set(http::field::origin, "http://viewer.example:3000");
  EXPECT_EQ(status_of(send(request)), 200);
}

TEST_F(WriteHandlersTest, TwoOriginHeadersAreRefusedWhicheverComesFirst) {
  for (const auto& [first, second] : {std::pair{"http://127.0.0.1:8080", "http://attacker.example"},
                                      std::pair{"http://attacker.example", "http://127.0.0.1:8080"},
                                      std::pair{"http://127.0.0.1:8080", "http://127.0.0.1:8080"}}) {
    auto request = make_request(verb::post, "/api/v1/primitives", kPrimitives);
    request.insert(http::field::origin, first);
    request.insert(http::field::origin, second);
    const auto response = send(request);
    EXPECT_EQ(status_of(response), 403) << first << ", " << second;
    EXPECT_EQ(json_of(response)["error"], "forbidden_origin");
  }
  EXPECT_TRUE(world_.calls.empty());
}

TEST_F(WriteHandlersTest, ScansAreParsedAndAnsweredWithTheirLines) {
  const auto response = send(verb::post, "/api/v1/scans", kScan);
  ASSERT_EQ(status_of(response), 200) << response.body();
  const auto body = json_of(response);
  EXPECT_EQ(body["grid_revision"], 4);
  EXPECT_EQ(body["lines"]["observation"], 8);
  EXPECT_EQ(body["lines"]["decisions"][0]["action"], "merge");
  EXPECT_EQ(body["pose"]["x"], 1.02);
  EXPECT_NEAR(body["pose"]["dx"].get<double>(), 0.02, 1e-12);
  EXPECT_EQ(body["pose"]["dy"], 0.0);
  EXPECT_NEAR(body["pose"]["dtheta"].get<double>(), 0.01, 1e-12);
  EXPECT_EQ(body["pose"]["aligned"], true);
  EXPECT_EQ(std::string(world_.last_scan->sensor()), "laser");
  EXPECT_EQ(status_of(send(verb::post, "/api/v1/scans", R"({"sensor": "radar"})")), 400);
  EXPECT_EQ(status_of(send(verb::post, "/api/v1/scans", kScan, "text/plain")), 415);
}

TEST_F(WriteHandlersTest, ScansMayComeAsCborAndInBatches) {
  const auto cbor_bytes = nlohmann::json::to_cbor(nlohmann::json::parse(kScan));
  const std::string cbor(cbor_bytes.begin(), cbor_bytes.end());
  auto response = send(verb::post, "/api/v1/scans", cbor, "application/cbor");
  ASSERT_EQ(status_of(response), 200) << response.body();
  EXPECT_EQ(response[http::field::content_type].substr(0, 16), "application/json");
  EXPECT_EQ(json_of(response)["grid_revision"], 4);
  EXPECT_EQ(world_.last_scan->observer, "robot-1");
  EXPECT_EQ(world_.last_payload, cbor);  // the bytes posted are what a retry is compared with

  const auto batch = nlohmann::json{{"scans", {nlohmann::json::parse(kScan), nlohmann::json::parse(kScan)}}};
  auto request = make_request(verb::post, "/api/v1/scans", batch.dump());
  request.set("Idempotency-Key", "batch-1");
  response = send(request);
  ASSERT_EQ(status_of(response), 200) << response.body();
  const auto body = json_of(response);
  ASSERT_EQ(body["scans"].size(), 2u);
  EXPECT_EQ(body["scans"][0]["seq"], 10);
  EXPECT_EQ(body["scans"][1]["seq"], 11);
  EXPECT_EQ(world_.last_batch.size(), 2u);
  EXPECT_EQ(world_.last_request_id, "batch-1");
  world_.replay = true;
  EXPECT_EQ(send(request)["Idempotent-Replayed"], "true");

  response = send(verb::post, "/api/v1/scans", cbor, "application/octet-stream");
  EXPECT_EQ(status_of(response), 415);
  EXPECT_EQ(error_of(response), "unsupported_media_type");
  response = send(verb::post, "/api/v1/scans", R"({"scans": [{"sensor": "radar"}]})");
  EXPECT_EQ(status_of(response), 400);
  EXPECT_EQ(json_of(response)["detail"], "scans[0].sensor: expected \"laser\" or \"sonar\"");
  EXPECT_EQ(world_.calls, (std::vector<std::string>{"post_scan", "post_scans", "post_scans"}));
}

TEST_F(WriteHandlersTest, FloorPlansLoadFromJsonOrTheImportEnvelope) {
  auto response = send(verb::put, "/api/v1/floorplan", kPlan);
  ASSERT_EQ(status_of(response), 200) << response.body();
  auto body = json_of(response);
  EXPECT_EQ(body["objects"], 1);
  EXPECT_EQ(body["edges"], 1);
  EXPECT_EQ(body["version"], 9);
  EXPECT_FALSE(body.contains("report"));
  response = send(
      verb::put, "/api/v1/floorplan",
      R"({"import": {"format": "amrl", "data": "[{\"p0\": {\"x\": 0, \"y\": 0}, \"p1\": {\"x\": 3, \"y\": 0}}]", "name": "vm"}})");
  ASSERT_EQ(status_of(response), 200) << response.body();
  EXPECT_EQ(json_of(response)["name"], "vm");
  EXPECT_TRUE(json_of(response).contains("report"));
  EXPECT_EQ(world_.last_plan->name, "vm");
}

TEST_F(WriteHandlersTest, FloorPlanRefusals) {
  const struct {
    std::string body, content_type;
    int status;
    std::string detail;
  } cases[] = {
      {"", "application/json", 400, "empty body"},
      {kPlan, "text/plain", 415, "application/json"},
      {R"({"objects": [{"id": "a", "kind": "wall", "segments": [[[0, 0]]]}]})", "application/json", 400,
       "objects[0].segments[0]"},
      {R"({"import": {"format": "dwg", "data": "x"}})", "application/json", 400, "import.format"},
      {R"({"import": {"format": "dxf", "data": "x", "colour": 1}})", "application/json", 400, "import.colour"},
      {R"({"import": {"format": "dxf", "data": "x", "units": "furlong"}})", "application/json", 400, "import.units"},
      {"0\nSECTION\n", "image/vnd.dxf", 400, ""},
      {"levels: {L1: {walls: [\xff]}}", "application/yaml", 400, "body: invalid UTF-8 at byte 22 (line 1)"},
  };
  for (const auto& c : cases) {
    const auto response = send(verb::put, "/api/v1/floorplan", c.body, c.content_type);
    EXPECT_EQ(status_of(response), c.status) << c.body << ": " << response.body();
    EXPECT_NE(json_of(response).value("detail", "").find(c.detail), std::string::npos) << response.body();
  }
  EXPECT_TRUE(world_.calls.empty());
}

TEST_F(WriteHandlersTest, RulesReloadAnswersTheNewStatusOr422) {
  auto response = send(verb::post, "/api/v1/rules/reload");
  ASSERT_EQ(status_of(response), 200);
  EXPECT_EQ(json_of(response)["generation"], 2);
  world_.fail_next(std::make_exception_ptr(rules::RuleError("world_model.pl:3: syntax error")));
  response = send(verb::post, "/api/v1/rules/reload");
  EXPECT_EQ(status_of(response), 422);
  EXPECT_EQ(error_of(response), "rule_error");
}

TEST_F(WriteHandlersTest, DryRunsNeedATokenOrTheExplicitFlag) {
  const std::string dry_run = R"({"file": "world_model.pl", "text": "decide(_, add, r, x).", "last": 10})";
  auto response = send(verb::post, "/api/v1/rules/dry-run", dry_run);
  EXPECT_EQ(status_of(response), 403);
  EXPECT_EQ(error_of(response), "forbidden");
  options_.allow_dry_run_without_token = true;
  world_.dry_run_answer.redecided = 10;
  world_.dry_run_answer.changes.push_back(
      {FakeWorldPort::decision(rules::Action::add, "e1"), {"merge", "r", "x", false}});
  response = send(verb::post, "/api/v1/rules/dry-run", dry_run);
  ASSERT_EQ(status_of(response), 200) << response.body();
  const auto body = json_of(response);
  EXPECT_EQ(body["redecided"], 10);
  EXPECT_EQ(body["changed"], 1);
  EXPECT_EQ(body["changes"][0]["candidate"]["action"], "merge");
  EXPECT_EQ(world_.last_candidate->name, "world_model.pl");
  for (const std::string bad : {R"({"text": "x"})", R"({"file": "a.pl", "text": "x", "last": 0})",
                                R"({"file": "a.pl", "text": "x", "extra": 1})", "[1]"})
    EXPECT_EQ(status_of(send(verb::post, "/api/v1/rules/dry-run", bad)), 400) << bad;
  EXPECT_EQ(status_of(send(verb::post, "/api/v1/rules/dry-run", dry_run, "text/plain")), 415);
  world_.fail_next(std::make_exception_ptr(rules::RuleError("candidate.pl:1: syntax error")));
  EXPECT_EQ(status_of(send(verb::post, "/api/v1/rules/dry-run", dry_run)), 422);
}

TEST_F(WriteHandlersTest, QueriesAnswerSolutionsAndMapTheirRefusals) {
  rules::QueryValue wall;
  wall.kind = rules::QueryValue::Kind::atom;
  wall.text = "wall-n";
  world_.query_answer = {{"O"}, {{wall}}, false};
  auto response = send(verb::post, "/api/v1/query", R"j({"goal": "attribute(O, solid)"})j");
  ASSERT_EQ(status_of(response), 200);
  EXPECT_EQ(json_of(response)["solutions"][0]["O"], "wall-n");
  EXPECT_EQ(world_.last_goal, "attribute(O, solid)");
  using QE = rules::QueryError;
  for (const auto& [reason, status, error] : {std::tuple{QE::Reason::syntax, 400, "bad_query"},
                                              {QE::Reason::unsafe, 403, "forbidden_goal"},
                                              {QE::Reason::limit, 422, "query_limit"},
                                              {QE::Reason::failed, 422, "query_error"}}) {
    world_.fail_next(std::make_exception_ptr(QE(reason, "x")));
    response = send(verb::post, "/api/v1/query", R"({"goal": "g"})");
    EXPECT_EQ(status_of(response), status);
    EXPECT_EQ(error_of(response), error);
  }
  EXPECT_EQ(status_of(send(verb::post, "/api/v1/query", R"({"goal": ""})")), 400);
  EXPECT_EQ(status_of(send(verb::post, "/api/v1/query", R"({"goal": "g", "max_solutions": 0})")), 400);
  EXPECT_EQ(status_of(send(verb::post, "/api/v1/query", R"({"goal": "g"})", "text/plain")), 415);
  options_.max_query_answer_bytes = 10;
  world_.query_answer.solutions.assign(5, {wall});
  response = send(verb::post, "/api/v1/query", R"({"goal": "g"})");
  EXPECT_EQ(status_of(response), 422);
  EXPECT_EQ(error_of(response), "answer_too_large");
}

TEST_F(WriteHandlersTest, GridExtractAnswersItsSegmentsOrNone) {
  auto body = json_of(send(verb::post, "/api/v1/grid/extract"));
  EXPECT_EQ(body["segments"], 0);
  EXPECT_TRUE(body["observation"].is_null());
  world_.grid.emplace(fusion::GridOptions{});
  body = json_of(send(verb::post, "/api/v1/grid/extract"));
  EXPECT_EQ(body["segments"], 1);
  EXPECT_EQ(body["observation"], 11);
}

}  // namespace
}  // namespace wm::testing
