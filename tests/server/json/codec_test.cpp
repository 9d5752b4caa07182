#include "server/json/codec.h"

#include <gtest/gtest.h>

#include "server/api/api_error.h"

namespace wm::json_codec {
namespace {

std::string refusal(const std::string& body) {
  try {
    parse_primitives(body, world::WorldOptions{}, PrimitiveLimits{});
  } catch (const api::ApiError& e) {
    EXPECT_EQ(e.status(), 400);
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
  EXPECT_NE(refusal(R"({"stamp": "now", "segments": [{"p0": [1, 2], "p1": [4, 2]}]})").find("stamp"), std::string::npos);
  EXPECT_NE(refusal("{}").find("segments: missing"), std::string::npos);
}

TEST(CodecTest, TooManySegmentsAreRefused) {
  PrimitiveLimits limits;
  limits.max_segments = 1;
  EXPECT_THROW(parse_primitives(R"({"segments": [{"p0": [1, 2], "p1": [4, 2]}, {"p0": [1, 3], "p1": [4, 3]}]})",
                                world::WorldOptions{}, limits),
               api::ApiError);
}

}  // namespace
}  // namespace wm::json_codec
