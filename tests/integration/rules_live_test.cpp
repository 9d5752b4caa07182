// The knowledge base as users meet it: rule files edited while wmd runs, queries, dry runs, history.
#include <chrono>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <thread>

#include "e2e_fixture.h"

namespace wm::testing {
namespace {

std::string read_all(const std::filesystem::path& path) {
  std::ifstream in(path);
  std::ostringstream text;
  text << in.rdbuf();
  return text.str();
}

void write_all(const std::filesystem::path& path, const std::string& text) {
  std::ofstream out(path, std::ios::trunc);
  out << text;
}

std::string replaced(std::string text, const std::string& from, const std::string& to) {
  const auto at = text.find(from);
  if (at == std::string::npos) throw std::runtime_error("not found: " + from);
  return text.replace(at, from.size(), to);
}

const char* kWallPrimitive = R"({"source": "robot-7", "segments": [{"p0": [3, 10.004], "p1": [7, 9.998]}]})";

// wmd on a private copy of the shipped rules, which the tests edit on disk.
class RulesLiveTest : public ServerFixture {
 protected:
  void SetUp() override {
    use_rules_copy();
    extra_args_ = {"--allow-dry-run-without-token"};  // the dry-run tests run without a token
    ServerFixture::SetUp();
    send_json("PUT", "/api/v1/floorplan", lab_plan());
  }

  std::filesystem::path rules_file(const std::string& name = "world_model.pl") const {
    return std::filesystem::path(rules_dir_) / name;
  }

  // Waits until GET /api/v1/rules satisfies `done` (the watcher reloads within a fraction of a second).
  template <typename Predicate>
  json wait_for_rules(Predicate done) {
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(15);
    json rules;
    do {
      rules = get_json("/api/v1/rules");
      if (done(rules)) return rules;
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
    } while (std::chrono::steady_clock::now() < deadline);
    ADD_FAILURE() << "rules never reached the expected state: " << rules.dump();
    return rules;
  }

  json post_wall() { return send_json("POST", "/api/v1/primitives", json::parse(kWallPrimitive)); }
};

TEST_F(RulesLiveTest, AnEditOnDiskDecidesTheNextObservation) {
  EXPECT_EQ(post_wall()["decisions"][0]["rule"], "solid_confirmed");
  const auto before = get_json("/api/v1/rules");
  write_all(rules_file(), replaced(read_all(rules_file()), "delete, solid_confirmed,", "ignore, solid_seen_again,"));
  const auto after = wait_for_rules([&](const json& r) { return r["generation"] != before["generation"]; });
  EXPECT_EQ(after["last_error"], "");
  EXPECT_NE(after["files"][0]["checksum"], before["files"][0]["checksum"]);
  const auto decision = post_wall()["decisions"][0];
  EXPECT_EQ(decision["rule"], "solid_seen_again");
  EXPECT_EQ(decision["action"], "ignore");
}

TEST_F(RulesLiveTest, ABrokenEditIsRejectedAndTheOldRulesKeepDeciding) {
  const auto map_before = get_json("/api/v1/map");
  const auto before = get_json("/api/v1/rules");
  // A syntax error in the clause of the solid-wall rule: plain consult would drop just that clause.
  write_all(rules_file(),
            replaced(read_all(rules_file()), "attribute(Object, solid),", "attribute(Object, solid)) ,,"));
  const auto rejected = wait_for_rules([](const json& r) { return !r["last_error"].get<std::string>().empty(); });
  const std::string error = rejected["last_error"];
  EXPECT_NE(error.find("world_model.pl:"), std::string::npos) << error;
  EXPECT_EQ(rejected["generation"], before["generation"]);
  EXPECT_EQ(rejected["files"][0]["checksum"], before["files"][0]["checksum"]);
  EXPECT_EQ(get_json("/api/v1/map"), map_before);
  EXPECT_EQ(post_wall()["decisions"][0]["rule"], "solid_confirmed");

  // POST /api/v1/rules/reload reports the same problem with its location.
  const auto r = call("POST", "/api/v1/rules/reload", "{}");
  EXPECT_EQ(r.status, 422);
  EXPECT_NE(r.body.find("world_model.pl:"), std::string::npos) << r.body;
}

TEST_F(RulesLiveTest, ALoopingRuleHitsTheLimitAndTheServerAnswersTheNext) {
  write_all(rules_file("spin.pl"),
            "override(observation(spinner, _, _, _), _, delete, spun, \"never\") :- spin.\nspin :- spin.\n");
  wait_for_rules([](const json& r) { return r["files"].size() == 2; });
  auto spinning = json::parse(R"({"source": "spinner", "segments": [{"p0": [10, 3], "p1": [13, 3]}]})");
  const auto looped = send_json("POST", "/api/v1/primitives", spinning)["decisions"][0];
  EXPECT_EQ(looped["rule"], "fallback");
  EXPECT_EQ(looped["action"], "add");
  EXPECT_TRUE(looped["fallback"].get<bool>());
  EXPECT_NE(looped["explanation"].get<std::string>().find("limit"), std::string::npos) << looped.dump();
  EXPECT_NE(get_json("/api/v1/rules")["last_error"].get<std::string>().find("limit"), std::string::npos);
  EXPECT_EQ(post_wall()["decisions"][0]["rule"], "solid_confirmed");
  EXPECT_EQ(get_json("/api/v1/health")["status"], "ok");
}

TEST_F(RulesLiveTest, QueriesAnswerAndDangerousGoalsAreRefused) {
  post_wall();
  send_json("POST", "/api/v1/primitives", json::parse(R"({"segments": [{"p0": [10, 3], "p1": [13, 3]}]})"));
  auto answer = send_json("POST", "/api/v1/query", {{"goal", "attribute(O, solid)"}});
  EXPECT_EQ(answer["solutions"], json::parse(R"([{"O": "wall-n"}])"));
  answer = send_json("POST", "/api/v1/query", {{"goal", "element(E, Source, _, _, _, Length, Support, _)"}});
  ASSERT_EQ(answer["count"], 1);
  EXPECT_EQ(answer["solutions"][0]["E"], "e1");
  EXPECT_EQ(answer["solutions"][0]["Support"], 1);
  EXPECT_NEAR(answer["solutions"][0]["Length"].get<double>(), 3.0, 1e-9);
  answer = send_json("POST", "/api/v1/query", {{"goal", "decision(Seq, Action, Rule, _, _, robot-7, _)"}});
  EXPECT_EQ(answer["count"], 0) << "robot-7 is the atom 'robot-7' only when quoted";
  answer = send_json("POST", "/api/v1/query", {{"goal", "decision(Seq, Action, Rule, _, _, 'robot-7', _)"}});
  ASSERT_EQ(answer["count"], 1);
  EXPECT_EQ(answer["solutions"][0]["Rule"], "solid_confirmed");
  answer = send_json("POST", "/api/v1/query", {{"goal", "between(1, 50, X)"}, {"max_solutions", 5}});
  EXPECT_EQ(answer["count"], 5);
  EXPECT_TRUE(answer["truncated"].get<bool>());

  const auto map_before = get_json("/api/v1/map");
  for (const std::string goal : {"shell('rm -rf /')", "assertz(object(evil, wall))",
                                 "retract(attribute('wall-n', solid))", "open('/etc/passwd', read, S)", "halt"}) {
    const auto r = send_json("POST", "/api/v1/query", {{"goal", goal}}, 403);
    EXPECT_EQ(r["error"], "forbidden_goal") << goal;
  }
  EXPECT_EQ(send_json("POST", "/api/v1/query", {{"goal", "attribute(O,"}}, 400)["error"], "bad_query");
  EXPECT_EQ(send_json("POST", "/api/v1/query", {{"goal", "repeat, fail"}}, 422)["error"], "query_limit");
  EXPECT_EQ(send_json("POST", "/api/v1/query", {{"goal", 42}}, 400)["error"], "bad_request");
  EXPECT_EQ(get_json("/api/v1/map"), map_before);
  EXPECT_EQ(send_json("POST", "/api/v1/query", {{"goal", "attribute(O, solid)"}})["count"], 1);
}

TEST_F(RulesLiveTest, DryRunShowsWhatAnEditWouldChangeWithoutApplyingIt) {
  post_wall();
  post_wall();
  send_json("POST", "/api/v1/primitives", json::parse(R"({"segments": [{"p0": [10, 3], "p1": [13, 3]}]})"));
  const auto map_before = get_json("/api/v1/map");
  const auto candidate = replaced(read_all(rules_file()), "delete, solid_confirmed,", "merge, solid_merged,");
  const auto outcome = send_json("POST", "/api/v1/rules/dry-run", {{"file", "world_model.pl"}, {"text", candidate}});
  EXPECT_EQ(outcome["redecided"], 3);
  ASSERT_EQ(outcome["changed"], 2);
  for (const auto& change : outcome["changes"]) {
    EXPECT_EQ(change["recorded"]["rule"], "solid_confirmed");
    EXPECT_EQ(change["candidate"]["rule"], "solid_merged");
    EXPECT_EQ(change["candidate"]["action"], "merge");
  }
  EXPECT_EQ(send_json("POST", "/api/v1/rules/dry-run",
                      {{"file", "world_model.pl"}, {"text", candidate}, {"last", 1}})["redecided"],
            1);
  EXPECT_EQ(get_json("/api/v1/map"), map_before);
  EXPECT_EQ(post_wall()["decisions"][0]["rule"], "solid_confirmed");
  EXPECT_EQ(read_all(rules_file()).find("solid_merged"), std::string::npos);

  const auto broken = send_json("POST", "/api/v1/rules/dry-run", {{"file", "extra.pl"}, {"text", "foo(.\n"}}, 422);
  EXPECT_NE(broken["detail"].get<std::string>().find("extra.pl:"), std::string::npos) << broken.dump();
}

TEST_F(RulesLiveTest, HistoryExplainsAnElementWithItsNumbers) {
  send_json("POST", "/api/v1/primitives", json::parse(R"({"segments": [{"p0": [10, 3], "p1": [13, 3]}]})"));
  send_json("POST", "/api/v1/primitives", json::parse(R"({"segments": [{"p0": [11, 3.002], "p1": [14, 3.0]}]})"));
  const auto history = get_json("/api/v1/elements/e1/history");
  ASSERT_EQ(history["decisions"].size(), 2u);
  EXPECT_EQ(history["decisions"][0]["action"], "add");
  const auto merge = history["decisions"][1];
  EXPECT_EQ(merge["action"], "merge");
  EXPECT_EQ(merge["rule"], "unknown_element_merged");
  EXPECT_GT(merge["mahalanobis_sq"].get<double>(), 0.0);
  const double var_before = merge["before"]["cov"][0][0];
  const double var_after = merge["after"]["cov"][0][0];
  EXPECT_LT(var_after, var_before) << "fusion must shrink the covariance";

  const auto wall = get_json("/api/v1/objects/wall-n/history");
  EXPECT_TRUE(wall["decisions"].empty());
  EXPECT_EQ(call("GET", "/api/v1/elements/e99/history").status, 404);

  const auto r = run_command(std::string(WM_WMCTL_PATH) + " --server " + server_->url() + " explain e1");
  EXPECT_EQ(r.status, 0) << r.output;
  EXPECT_NE(r.output.find("unknown_element_merged"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("before: rho"), std::string::npos) << r.output;
}

TEST_F(RulesLiveTest, ChangingRulesOverHttpNeedsTheToken) {
  extra_args_ = {"--token", "s3cret"};
  restart();
  EXPECT_EQ(call("POST", "/api/v1/rules/reload", "{}").status, 401);
  EXPECT_EQ(call("POST", "/api/v1/rules/dry-run", R"({"file": "a.pl", "text": "x."})").status, 401);
  const auto ok = client_->request("POST", "/api/v1/rules/reload", "{}", "application/json", "s3cret");
  EXPECT_EQ(ok.status, 200) << ok.body;
  // Queries are read-only and need no token.
  EXPECT_EQ(call("POST", "/api/v1/query", R"({"goal": "true"})").status, 200);
}

}  // namespace
}  // namespace wm::testing
