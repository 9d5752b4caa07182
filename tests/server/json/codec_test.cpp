#include "server/json/codec.h"

#include <gtest/gtest.h>

#include "server/json/codec_error.h"

namespace wm::json_codec {
namespace {

std::string refusal(const std::string& body) {
  try {
    parse_primitives(body, world::WorldOptions{}, PrimitiveLimits{});
  } catch (const CodecError& e) {
    EXPECT_EQ(e.kind(), CodecError::Kind::bad_request);
    return e.what();
  }
  return "<accepted>";
}

TEST(CodecTest, ParsesPrimitivesWithAndWithoutCovariance) {
  const auto obs = parse_primitives(
      R"({"source": "robot-1", "stamp": 12.5, "segments": [{"p0": [1, 2], "p1": [4, 2.05], "cov": [[1e-4, 0], [0, 2e-4]]},
                                                            {"p0": [0, 0], "p1": [0, 3]}]})",
      world::WorldOptions{}, PrimitiveLimits{});
  EXPECT_EQ(obs.observer, "robot-1");
  EXPECT_DOUBLE_EQ(obs.stamp_s, 12.5);
  ASSERT_EQ(obs.segments.size(), 2u);
  EXPECT_DOUBLE_EQ(obs.segments[0].segment.line.cov(1, 1), 2e-4);
  // The second has the default: σ 1 cm across its midpoint (t = 1.5 m along the line), σ 0.01 rad.
  const auto& c = obs.segments[1].segment.line.cov;
  EXPECT_NEAR(c(1, 1), 1e-4, 1e-15);
  EXPECT_NEAR(std::abs(c(0, 1)), 1.5e-4, 1e-12);
  EXPECT_NEAR(c(0, 0), 1e-4 + 2.25e-4, 1e-12);
}

TEST(CodecTest, RefusalsNameTheField) {
  EXPECT_NE(refusal(R"({"segments": [{"p0": [1, 2], "p1": [4, true]}]})").find("segments[0].p1[1]"), std::string::npos);
  EXPECT_NE(refusal(R"({"segments": [{"p0": [1, 2], "p1": [4, 2], "cov": [[1, 2], [3, 4]]}]})").find("not symmetric"),
            std::string::npos);
  EXPECT_NE(refusal(R"({"source": 7, "segments": [{"p0": [1, 2], "p1": [4, 2]}]})").find("source"), std::string::npos);
  EXPECT_NE(refusal(R"({"stamp": "now", "segments": [{"p0": [1, 2], "p1": [4, 2]}]})").find("stamp"),
            std::string::npos);
  EXPECT_NE(refusal("{}").find("segments: missing"), std::string::npos);
}

// "observer" is the field's name; "source", its older name, is still accepted. Both at once must agree.
TEST(CodecTest, TheObserverMayBeNamedObserverOrByItsOlderNameSource) {
  const std::string segments = R"("segments": [{"p0": [1, 2], "p1": [4, 2]}])";
  EXPECT_EQ(parse_primitives("{\"observer\": \"r1\", " + segments + "}", {}, {}).observer, "r1");
  EXPECT_EQ(parse_primitives("{\"source\": \"r2\", " + segments + "}", {}, {}).observer, "r2");
  EXPECT_EQ(parse_primitives("{\"observer\": \"r3\", \"source\": \"r3\", " + segments + "}", {}, {}).observer, "r3");
  EXPECT_EQ(parse_primitives("{" + segments + "}", {}, {}).observer, "anonymous");
  EXPECT_NE(refusal("{\"observer\": \"a\", \"source\": \"b\", " + segments + "}").find("older name"),
            std::string::npos);
  EXPECT_NE(refusal("{\"observer\": \"\", " + segments + "}").find("observer"), std::string::npos);
  // No control characters in a name, NUL least of all (a PostgreSQL store could not keep it).
  for (const std::string bad : {"a\\u0000b", "tab\\there", "line\\n", "del\\u007f"})
    EXPECT_NE(refusal("{\"observer\": \"" + bad + "\", " + segments + "}").find("control characters"),
              std::string::npos)
        << bad;
  const std::string scan =
      R"("sensor": "laser", "pose": {"x": 0, "y": 0, "theta": 0}, "angle_min": 0, "angle_increment": 0.1, "ranges": [1, 2],)"
      R"("range_min": 0.1, "range_max": 30)";
  EXPECT_EQ(parse_scan("{\"observer\": \"r4\", " + scan + "}", ScanLimits{}).observer, "r4");
  EXPECT_EQ(parse_scan("{\"source\": \"r5\", " + scan + "}", ScanLimits{}).observer, "r5");
  EXPECT_THROW(parse_scan("{\"observer\": \"a\", \"source\": \"b\", " + scan + "}", ScanLimits{}), CodecError);
}

TEST(CodecTest, ALaserScanMayStateItsUsableRangeAndRangeDependentSigma) {
  const std::string head =
      R"({"sensor": "laser", "pose": {"x": 0, "y": 0, "theta": 0}, "angle_min": 0, "angle_increment": 0.01, )"
      R"("ranges": [35.0, 2.0], "range_max": 80)";
  const auto scan = std::get<fusion::LaserScan>(
      parse_scan(head + R"(, "usable_range": 40, "sigma_range_per_m": 0.001})", ScanLimits{}).scan);
  EXPECT_EQ(scan.usable_range_m, 40.0);
  EXPECT_EQ(scan.sigma_range_per_m, 0.001);
  const auto plain = std::get<fusion::LaserScan>(parse_scan(head + "}", ScanLimits{}).scan);
  EXPECT_EQ(plain.usable_range_m, 0.0);  // the server's default applies
  EXPECT_EQ(plain.sigma_range_per_m, 0.0);
  for (const std::string bad : {R"(, "usable_range": 0})", R"(, "usable_range": -3})", R"(, "usable_range": "far"})",
                                R"(, "sigma_range_per_m": -0.1})", R"(, "sigma_range_per_m": 5})"}) {
    try {
      parse_scan(head + bad, ScanLimits{});
      ADD_FAILURE() << "accepted " << bad;
    } catch (const CodecError& e) {
      EXPECT_EQ(e.kind(), CodecError::Kind::bad_request) << bad;
    }
  }
}

TEST(CodecTest, AScansPoseCovarianceMustBeOne) {
  const std::string head =
      R"({"sensor": "laser", "pose": {"x": 0, "y": 0, "theta": 0}, "angle_min": 0, "angle_increment": 0.01, )"
      R"("ranges": [3.0, 2.0], "range_max": 80, "pose_cov": )";
  const auto scan = parse_scan(head + "[[9e-4, 1e-4, 0], [1e-4, 9e-4, 0], [0, 0, 7.6e-5]]}", ScanLimits{});
  EXPECT_EQ(scan.pose_cov(0, 1), 1e-4);
  EXPECT_TRUE(parse_scan(head + "[[0, 0, 0], [0, 0, 0], [0, 0, 0]]}", ScanLimits{}).pose_cov.isZero());
  EXPECT_EQ(parse_scan(head + "[[1, 1, 0], [1, 1, 0], [0, 0, 1]]}", ScanLimits{}).pose_cov(0, 1), 1.0)
      << "x and y fully correlated: singular, still a covariance";
  for (const std::string bad :
       {"[[1, 2, 0], [2, 1, 0], [0, 0, 1]]}", "[[1, 0.5, 0], [0.4, 1, 0], [0, 0, 1]]}",
        "[[-1, 0, 0], [0, 1, 0], [0, 0, 1]]}", "[[1e-4, 0, 0.01], [0, 1e-4, 0], [0.01, 0, 1e-4]]}", "[[1, 0], [0, 1]]}",
        "[[1, 0, 0], [0, 1, 0], [0, 0, 1e7]]}"}) {
    try {
      parse_scan(head + bad, ScanLimits{});
      ADD_FAILURE() << "accepted " << bad;
    } catch (const CodecError& e) {
      EXPECT_EQ(e.kind(), CodecError::Kind::bad_request) << bad;
      EXPECT_NE(std::string(e.what()).find("pose_cov"), std::string::npos) << e.what();
    }
  }
}

TEST(CodecTest, TooManySegmentsAreRefused) {
  PrimitiveLimits limits;
  limits.max_segments = 1;
  EXPECT_THROW(parse_primitives(R"({"segments": [{"p0": [1, 2], "p1": [4, 2]}, {"p0": [1, 3], "p1": [4, 3]}]})",
                                world::WorldOptions{}, limits),
               CodecError);
}

// Guards the parser's stack: 100 000 nested objects crashed nlohmann's recursive parse; the nesting is checked first.
TEST(CodecTest, ParseJsonRefusesNestingBeyond64LevelsBeforeParsing) {
  const auto nested = [](std::size_t levels) { return std::string(levels, '[') + std::string(levels, ']'); };
  EXPECT_NO_THROW(parse_json(nested(64)));
  EXPECT_NO_THROW(parse_ordered_json(nested(64)));
  const auto message = [](const std::string& text) {
    try {
      parse_json(text);
    } catch (const CodecError& e) {
      EXPECT_EQ(e.kind(), CodecError::Kind::bad_request);
      return std::string(e.what());
    }
    return std::string("<accepted>");
  };
  EXPECT_EQ(message(nested(65)), "JSON nested deeper than 64 levels at byte 64");
  EXPECT_EQ(message(nested(100000)), "JSON nested deeper than 64 levels at byte 64");
  // Brackets inside strings, escaped quotes included, do not count.
  EXPECT_NO_THROW(parse_json("{\"a\": \"" + std::string(1000, '[') + "\\\"" + std::string(1000, '{') + "\"}"));
  EXPECT_EQ(message("[1,"),
            "malformed JSON: [json.exception.parse_error.101] parse error at line 1, column 4: syntax "
            "error while parsing value - unexpected end of input; expected '[', '{', or a literal");
  EXPECT_THROW(parse_ordered_json(nested(65)), CodecError);
}

TEST(CodecTest, ADecisionsBeforeAndAfterAreLabelledByWhatChanged) {
  world::DecisionRecord trim;
  trim.action = rules::Action::trim;
  trim.rule = "grid_trimmed";
  trim.before = {0.0, 1.0, 4.0, 1.0};
  trim.after = {1.0, 1.0, 3.0, 1.0};
  const auto j = decision_json(trim);
  EXPECT_EQ(j["action"], "trim");
  EXPECT_EQ(j["before"]["p0"], nlohmann::json::array({0.0, 1.0}));
  EXPECT_EQ(j["after"]["p1"], nlohmann::json::array({3.0, 1.0}));
  world::DecisionRecord merge;
  merge.action = rules::Action::merge;
  merge.before = {2.0, 0.5, 1e-4, 0.0, 0.0, 4e-4};
  EXPECT_DOUBLE_EQ(decision_json(merge)["before"]["rho"].get<double>(), 2.0);
  EXPECT_DOUBLE_EQ(decision_json(merge)["before"]["cov"][1][1].get<double>(), 4e-4);
  EXPECT_FALSE(decision_json(merge).contains("after"));
}

TEST(CodecTest, InvalidUtf8IsFoundAtItsByte) {
  EXPECT_EQ(invalid_utf8_offset("plain ascii"), std::nullopt);
  EXPECT_EQ(invalid_utf8_offset("pavill\xc3\xb3n \xe2\x82\xac \xf0\x9f\xa4\x96"), std::nullopt);  // ó € 🤖
  EXPECT_EQ(invalid_utf8_offset("main_d\xff\xfeoor"), 6u);
  EXPECT_EQ(invalid_utf8_offset("ab\xc3"), 2u);            // truncated sequence
  EXPECT_EQ(invalid_utf8_offset("\xc0\xaf"), 0u);          // overlong '/'
  EXPECT_EQ(invalid_utf8_offset("x\xe0\x80\xaf"), 1u);     // overlong, 3 bytes
  EXPECT_EQ(invalid_utf8_offset("\xed\xa0\x80"), 0u);      // UTF-16 surrogate D800
  EXPECT_EQ(invalid_utf8_offset("\xf4\x90\x80\x80"), 0u);  // above U+10FFFF
  EXPECT_EQ(invalid_utf8_offset("ok\xe2\x28\xa1"), 2u);    // bad continuation byte
  EXPECT_EQ(invalid_utf8_offset(std::string("a\0b", 3)), std::nullopt);
}

rules::QueryValue atom(std::string text) {
  rules::QueryValue v;
  v.kind = rules::QueryValue::Kind::atom;
  v.text = std::move(text);
  return v;
}

// Guards the answer's size: length(L, 10000000) answered 50 MB. The answer is refused while it is built.
TEST(CodecTest, QueryAnswersAreBoundedInBytesAndNesting) {
  rules::QueryResult result;
  result.variables = {"X"};
  for (int i = 0; i < 100; ++i) result.solutions.push_back({atom(std::string(1000, 'a'))});
  EXPECT_EQ(query_result_json(result, 200'000)["count"], 100);
  try {
    query_result_json(result, 50'000);
    ADD_FAILURE() << "a 100 kB answer passed a 50 kB limit";
  } catch (const CodecError& e) {
    EXPECT_EQ(e.kind(), CodecError::Kind::answer_too_large);
    EXPECT_EQ(std::string(e.what()),
              "the answer is larger than 50000 bytes; ask for fewer solutions (max_solutions) or smaller terms");
  }

  rules::QueryValue deep = atom("x");
  for (int i = 0; i < 100; ++i) {
    rules::QueryValue list;
    list.kind = rules::QueryValue::Kind::list;
    list.items.push_back(std::move(deep));
    deep = std::move(list);
  }
  rules::QueryResult nested;
  nested.variables = {"L"};
  nested.solutions.push_back({deep});
  try {
    query_result_json(nested);
    ADD_FAILURE() << "100 nested lists passed";
  } catch (const CodecError& e) {
    EXPECT_EQ(e.kind(), CodecError::Kind::answer_too_large);
    EXPECT_EQ(std::string(e.what()), "the answer nests lists deeper than 64 levels");
  }
}

// Guards against leaking the file system's layout: /api/v1/health showed the absolute path of the rules directory.
TEST(CodecTest, RulesStatusShowsPathsRelativeToTheRulesDirectorysParent) {
  rules::RulesStatus status{
      {{"/home/robot/wm/rules/prolog/world_model.pl", "ab", 1}, {"/home/robot/wm/rules/prolog/glass.pl", "cd", 2}},
      "/home/robot/wm/rules/prolog/glass.pl:3: Syntax error: Operator expected",
      4};
  const auto j = rules_status_json(status);
  EXPECT_EQ(j["files"][0]["path"], "prolog/world_model.pl");
  EXPECT_EQ(j["files"][1]["path"], "prolog/glass.pl");
  EXPECT_EQ(j["last_error"], "prolog/glass.pl:3: Syntax error: Operator expected");
  EXPECT_EQ(j["generation"], 4);
  EXPECT_EQ(j.dump().find("/home/robot"), std::string::npos);
}

}  // namespace
}  // namespace wm::json_codec
