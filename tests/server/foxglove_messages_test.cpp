#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <nlohmann/json.hpp>

#include "server/foxglove/messages.h"
#include "server/world/update.h"
#include "tests/support/lab_plan.h"

namespace wm::foxglove {
namespace {

using nlohmann::json;

// An independent decoder (RFC 4648 alphabet), so a fault in the encoder cannot hide in a shared helper.
std::string unbase64(const std::string& text) {
  const std::string alphabet = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  std::uint32_t bits = 0;
  int count = 0;
  for (const char c : text) {
    if (c == '=') break;
    const auto value = alphabet.find(c);
    if (value == std::string::npos) throw std::invalid_argument("not base64");
    bits = (bits << 6) | static_cast<std::uint32_t>(value);
    count += 6;
    if (count >= 8) {
      count -= 8;
      out += static_cast<char>((bits >> count) & 0xff);
    }
  }
  return out;
}

float float_at(const std::string& bytes, std::size_t offset) {
  std::uint32_t bits = 0;
  for (int b = 0; b < 4; ++b) bits |= std::uint32_t{static_cast<unsigned char>(bytes.at(offset + b))} << (8 * b);
  float value = 0;
  std::memcpy(&value, &bits, 4);
  return value;
}

const float kNaN = std::nanf("");

TEST(FoxgloveMessagesTest, Base64MatchesTheRfc4648Vectors) {
  EXPECT_EQ(base64(""), "");
  EXPECT_EQ(base64("f"), "Zg==");
  EXPECT_EQ(base64("fo"), "Zm8=");
  EXPECT_EQ(base64("foo"), "Zm9v");
  EXPECT_EQ(base64("foob"), "Zm9vYg==");
  EXPECT_EQ(base64("fooba"), "Zm9vYmE=");
  EXPECT_EQ(base64("foobar"), "Zm9vYmFy");
  EXPECT_EQ(base64(std::string("\xff\xfe\x00", 3)), "//4A");
}

TEST(FoxgloveMessagesTest, GridPacksEachCellRowMajorFromTheLowerLeftAsLittleEndianFloat32) {
  // 3 columns × 2 rows of 0.5 m cells whose lower-left corner is at (-1, 2).
  const fusion::GridGeometry region({-1.0, 2.0}, 0.5, 3, 2);
  const std::vector<float> p{0.1f, 0.2f, kNaN, 0.9f, 1.0f, 0.0f};
  const auto grid = json::parse(grid_message(region, {{"probability", p}}, 1'700'000'000'123'456'789ull));
  EXPECT_EQ(grid["timestamp"], json({{"sec", 1'700'000'000}, {"nsec", 123'456'789}}));
  EXPECT_EQ(grid["frame_id"], "map");
  EXPECT_EQ(grid["pose"]["position"], json({{"x", -1.0}, {"y", 2.0}, {"z", 0.0}}));
  EXPECT_EQ(grid["pose"]["orientation"], json({{"x", 0.0}, {"y", 0.0}, {"z", 0.0}, {"w", 1.0}}));
  EXPECT_EQ(grid["column_count"], 3);
  EXPECT_EQ(grid["cell_size"], json({{"x", 0.5}, {"y", 0.5}}));
  EXPECT_EQ(grid["cell_stride"], 4);
  EXPECT_EQ(grid["row_stride"], 12);
  EXPECT_EQ(grid["fields"], json::parse(R"([{"name":"probability","offset":0,"type":7}])"));
  const auto bytes = unbase64(grid["data"].get<std::string>());
  ASSERT_EQ(bytes.size(), 24u);
  for (int row = 0; row < 2; ++row)
    for (int col = 0; col < 3; ++col) {
      const float want = p[static_cast<std::size_t>(row * 3 + col)];
      const float got = float_at(bytes, static_cast<std::size_t>(row * 12 + col * 4));
      if (std::isnan(want)) {
        EXPECT_TRUE(std::isnan(got)) << row << "," << col;
      } else {
        EXPECT_EQ(got, want) << row << "," << col;
      }
    }
}

TEST(FoxgloveMessagesTest, GridInterleavesSeveralFieldsInEachCell) {
  const fusion::GridGeometry region({0.0, 0.0}, 0.05, 2, 1);
  const auto grid = json::parse(grid_message(
      region, {{"belief", {0.25f, 0.5f}}, {"plausibility", {0.75f, 1.0f}}, {"conflict", {0.0f, 0.125f}}}, 0));
  EXPECT_EQ(grid["cell_stride"], 12);
  EXPECT_EQ(grid["row_stride"], 24);
  EXPECT_EQ(grid["fields"][1], json::parse(R"({"name":"plausibility","offset":4,"type":7})"));
  EXPECT_EQ(grid["fields"][2], json::parse(R"({"name":"conflict","offset":8,"type":7})"));
  const auto bytes = unbase64(grid["data"].get<std::string>());
  ASSERT_EQ(bytes.size(), 24u);
  EXPECT_EQ(float_at(bytes, 0), 0.25f);
  EXPECT_EQ(float_at(bytes, 4), 0.75f);
  EXPECT_EQ(float_at(bytes, 8), 0.0f);
  EXPECT_EQ(float_at(bytes, 12), 0.5f);
  EXPECT_EQ(float_at(bytes, 16), 1.0f);
  EXPECT_EQ(float_at(bytes, 20), 0.125f);
}

TEST(FoxgloveMessagesTest, GridRefusesFieldsThatDoNotFitTheRegion) {
  const fusion::GridGeometry region({0.0, 0.0}, 0.05, 2, 2);
  EXPECT_THROW(grid_message(region, {}, 0), std::invalid_argument);
  EXPECT_THROW(grid_message(region, {{"probability", {0.1f, 0.2f, 0.3f}}}, 0), std::invalid_argument);
}

TEST(FoxgloveMessagesTest, CoarseningFactorIsTheSmallestThatFitsTheBound) {
  EXPECT_EQ(coarsening_factor(100, 100, 10'000), 1);
  EXPECT_EQ(coarsening_factor(100, 100, 9'999), 2);  // 50 × 50
  EXPECT_EQ(coarsening_factor(100, 100, 2'500), 2);
  EXPECT_EQ(coarsening_factor(100, 100, 2'499), 3);  // 34 × 34 = 1156
  EXPECT_EQ(coarsening_factor(1'000'000, 3, 4'000'000), 1);
  EXPECT_EQ(coarsening_factor(7, 5, 1), 7);
  EXPECT_THROW(coarsening_factor(7, 5, 0), std::invalid_argument);
}

TEST(FoxgloveMessagesTest, CoarsenedCellsAreTheLargestKnownValueOfTheirBlock) {
  // 5 × 3 cells in blocks of 2: 3 × 2 coarse cells, the last column and row partial.
  const fusion::GridGeometry region({1.0, -1.0}, 0.1, 5, 3);
  const std::vector<float> v{0.1f, 0.4f, kNaN, kNaN, 0.3f,  //
                             0.2f, 0.0f, kNaN, kNaN, kNaN,  //
                             kNaN, kNaN, 0.7f, 0.6f, kNaN};
  const auto [coarse, fields] = coarsened(region, {{"probability", v}}, 2);
  EXPECT_EQ(coarse.width(), 3);
  EXPECT_EQ(coarse.height(), 2);
  EXPECT_DOUBLE_EQ(coarse.resolution_m(), 0.2);
  EXPECT_EQ(coarse.origin_m(), region.origin_m());
  const auto& c = fields.at(0).values;
  ASSERT_EQ(c.size(), 6u);
  EXPECT_EQ(c[0], 0.4f);
  EXPECT_TRUE(std::isnan(c[1]));  // nothing known in that block
  EXPECT_EQ(c[2], 0.3f);
  EXPECT_TRUE(std::isnan(c[3]));
  EXPECT_EQ(c[4], 0.7f);
  EXPECT_TRUE(std::isnan(c[5]));
  // k = 1 changes nothing.
  const auto same = coarsened(region, {{"probability", v}}, 1);
  EXPECT_EQ(same.first.width(), 5);
  EXPECT_EQ(same.second.at(0).values.size(), v.size());
}

world::Element element(std::int64_t number, Eigen::Vector2d p0, Eigen::Vector2d p1, std::string origin) {
  world::Element e;
  e.number = number;
  e.segment = fusion::LineSegment::from_points(p0, p1, Eigen::Matrix2d::Identity() * 1e-4);
  e.origin = std::move(origin);
  e.observer = "robot-1";
  e.support = 3;
  return e;
}

TEST(FoxgloveMessagesTest, AnElementIsOneLineListEntityOfItsSegmentColouredByOrigin) {
  const auto e = element(12, {1.5, -2.0}, {4.25, -2.0}, "scan");
  const auto entity = element_entity(e);
  EXPECT_EQ(entity.id, "e12");
  ASSERT_EQ(entity.segments.size(), 1u);
  EXPECT_EQ(entity.segments[0][0], e.segment.p0());
  EXPECT_EQ(entity.segments[0][1], e.segment.p1());
  EXPECT_DOUBLE_EQ(entity.color.r, 0xec / 255.0);  // the web viewer's scan colour #ec6a00
  EXPECT_DOUBLE_EQ(entity.color.g, 0x6a / 255.0);
  EXPECT_DOUBLE_EQ(entity.color.b, 0.0);
  EXPECT_DOUBLE_EQ(element_entity(element(1, {0, 0}, {1, 0}, "grid")).color.r, 0x9c / 255.0);
  EXPECT_DOUBLE_EQ(element_entity(element(1, {0, 0}, {1, 0}, "client")).color.g, 0x55 / 255.0);
  EXPECT_DOUBLE_EQ(element_entity(element(1, {0, 0}, {1, 0}, "other")).color.r, 0x6b / 255.0);

  const auto update = json::parse(scene_update_message({entity}, {"e3", "e4"}, false, 5'000'000'001ull));
  ASSERT_EQ(update["deletions"].size(), 2u);
  EXPECT_EQ(update["deletions"][0]["type"], 0);  // MATCHING_ID
  EXPECT_EQ(update["deletions"][0]["id"], "e3");
  EXPECT_EQ(update["deletions"][1]["id"], "e4");
  ASSERT_EQ(update["entities"].size(), 1u);
  const auto& ent = update["entities"][0];
  EXPECT_EQ(ent["id"], "e12");
  EXPECT_EQ(ent["frame_id"], "map");
  EXPECT_EQ(ent["timestamp"], json({{"sec", 5}, {"nsec", 1}}));
  ASSERT_EQ(ent["lines"].size(), 1u);
  const auto& line = ent["lines"][0];
  EXPECT_EQ(line["type"], 2);  // LINE_LIST
  const auto p0 = e.segment.p0(), p1 = e.segment.p1();
  EXPECT_EQ(line["points"], json::array({json({{"x", p0.x()}, {"y", p0.y()}, {"z", 0.0}}),
                                         json({{"x", p1.x()}, {"y", p1.y()}, {"z", 0.0}})}));
  EXPECT_NEAR(p0.x(), 1.5, 1e-9);  // the segment as given
  EXPECT_NEAR(p1.x(), 4.25, 1e-9);
  EXPECT_EQ(line["color"]["a"], 1.0);
  EXPECT_EQ(ent["metadata"][0], json({{"key", "origin"}, {"value", "scan"}}));
  for (const char* list : {"arrows", "cubes", "spheres", "cylinders", "triangles", "texts", "models"})
    EXPECT_EQ(ent[list], json::array()) << list;
}

TEST(FoxgloveMessagesTest, AWholeSceneStartsWithADeletionOfEverything) {
  const auto update = json::parse(scene_update_message({}, {}, true, 7));
  ASSERT_EQ(update["deletions"].size(), 1u);
  EXPECT_EQ(update["deletions"][0]["type"], 1);  // ALL
  EXPECT_EQ(update["entities"], json::array());
}

TEST(FoxgloveMessagesTest, ACadObjectIsItsEdgesAsPlacedColouredByAttribute) {
  const world::WorldOptions options;
  const auto state = world::apply_floor_plan(world::WorldState{}, testing::lab_plan(), options).state;
  ASSERT_EQ(state.objects.size(), 2u);
  const auto& wall = state.objects[0];
  const auto& table = state.objects[1];
  const auto wall_entity = object_entity(wall, options);
  EXPECT_EQ(wall_entity.id, "wall-n");
  ASSERT_EQ(wall_entity.segments.size(), 1u);
  // The wall from (0, 10) to (20, 10), in the direction of its line (as GET /api/v1/map gives the edge).
  const auto& [a, b] = wall_entity.segments[0];
  EXPECT_NEAR((a - b).norm(), 20.0, 1e-9);
  EXPECT_NEAR(a.y(), 10.0, 1e-9);
  EXPECT_NEAR(std::min(a.x(), b.x()), 0.0, 1e-9);
  EXPECT_NEAR(std::max(a.x(), b.x()), 20.0, 1e-9);
  EXPECT_EQ(a, world::apriori_edge(wall, 0, options).p0());
  EXPECT_DOUBLE_EQ(wall_entity.color.b, 0xa6 / 255.0);  // solid: #2451a6
  const auto table_entity = object_entity(table, options);
  ASSERT_EQ(table_entity.segments.size(), table.body.edges().size());
  ASSERT_EQ(table_entity.segments.size(), 4u);
  for (std::size_t k = 0; k < 4; ++k) {
    const auto edge = world::apriori_edge(table, k, options);  // what GET /api/v1/map gives as the edge
    EXPECT_EQ(table_entity.segments[k][0], edge.p0()) << k;
    EXPECT_EQ(table_entity.segments[k][1], edge.p1()) << k;
  }
  // The table turned by 0.3 rad about (5, 5): its first corner is not at the drawing's.
  EXPECT_FALSE(table_entity.segments[0][0].isApprox(Eigen::Vector2d(-0.6, -0.4)));
  EXPECT_DOUBLE_EQ(table_entity.color.g, 0x9e / 255.0);  // not_deformable: #1e9e4a
  const auto update = json::parse(scene_update_message({table_entity}, {}, false, 0));
  EXPECT_EQ(update["entities"][0]["lines"][0]["points"].size(), 8u);  // two points per edge
}

TEST(FoxgloveMessagesTest, PosesAndTransformsTurnAboutZ) {
  const double theta = 2.5;
  const auto pose = json::parse(pose_in_frame_message(1.25, -3.5, theta, 1'000'000'000ull));
  EXPECT_EQ(pose["frame_id"], "map");
  EXPECT_EQ(pose["timestamp"], json({{"sec", 1}, {"nsec", 0}}));
  EXPECT_EQ(pose["pose"]["position"], json({{"x", 1.25}, {"y", -3.5}, {"z", 0.0}}));
  const auto& q = pose["pose"]["orientation"];
  EXPECT_DOUBLE_EQ(q["x"].get<double>(), 0.0);
  EXPECT_DOUBLE_EQ(q["y"].get<double>(), 0.0);
  EXPECT_NEAR(2 * std::atan2(q["z"].get<double>(), q["w"].get<double>()), theta, 1e-12);

  const auto tf = json::parse(frame_transforms_message({{"map", "r1/base_link", 2, 3, -1.0, 42}}));
  ASSERT_EQ(tf["transforms"].size(), 1u);
  const auto& t = tf["transforms"][0];
  EXPECT_EQ(t["parent_frame_id"], "map");
  EXPECT_EQ(t["child_frame_id"], "r1/base_link");
  EXPECT_EQ(t["translation"], json({{"x", 2.0}, {"y", 3.0}, {"z", 0.0}}));
  EXPECT_NEAR(2 * std::atan2(t["rotation"]["z"].get<double>(), t["rotation"]["w"].get<double>()), -1.0, 1e-12);
  EXPECT_EQ(t["timestamp"]["nsec"], 42);
}

TEST(FoxgloveMessagesTest, ADecisionIsALogLineNamedByItsRule) {
  world::DecisionRecord d;
  d.seq = 17;
  d.action = rules::Action::confirm;
  d.rule = "solid_confirmed";
  d.element = "wall-n/0";
  d.object = "wall-n";
  d.observer = "robot-1";
  d.origin = "scan";
  d.sensor = "laser";
  d.explanation = "matches the wall";
  const auto log = json::parse(log_message(d, 3'000'000'007ull));
  EXPECT_EQ(log["level"], 2);  // INFO
  EXPECT_EQ(log["name"], "solid_confirmed");
  EXPECT_EQ(log["message"], "decision 17: delete wall-n/0 (object wall-n) by robot-1 (scan/laser): matches the wall");
  EXPECT_EQ(log["timestamp"], json({{"sec", 3}, {"nsec", 7}}));
  EXPECT_EQ(log["file"], "");
  EXPECT_EQ(log["line"], 0);
  d.fallback = true;
  EXPECT_EQ(json::parse(log_message(d, 0))["level"], 3);  // WARNING: the rules failed and the fallback decided
}

}  // namespace
}  // namespace wm::foxglove
