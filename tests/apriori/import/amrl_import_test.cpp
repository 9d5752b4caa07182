#include "apriori/import/amrl_import.h"

#include <gtest/gtest.h>

#include <stdexcept>

namespace wm::apriori {
namespace {

std::string error_path(const std::string& text) {
  try {
    import_amrl_vectormap(text);
  } catch (const FloorPlanError& e) {
    return e.path();
  }
  return "<no error>";
}

TEST(AmrlImportTest, OneWallPerSegmentPosedAtItsMiddle) {
  const auto r = import_amrl_vectormap(R"([{"p0": {"x": 0, "y": 0}, "p1": {"x": 4, "y": 2}},
                                           {"p0": {"x": 1, "y": 1}, "p1": {"x": 1, "y": 1.0000001}},
                                           {"p0": {"x": -1, "y": 5}, "p1": {"x": -1, "y": 7}}])");
  ASSERT_EQ(r.plan.objects.size(), 2u);
  EXPECT_EQ(r.plan.objects[0].id, "wall-0");
  EXPECT_EQ(r.plan.objects[1].id, "wall-2");  // ids keep the file's index
  EXPECT_EQ(r.plan.objects[0].pose.x_m, 2.0);
  EXPECT_EQ(r.plan.objects[0].pose.y_m, 1.0);
  EXPECT_EQ(r.plan.objects[0].polylines[0][0], Eigen::Vector2d(-2, -1));
  EXPECT_EQ(r.report.skipped.at("shorter than min_length_m"), 1u);
  EXPECT_EQ(r.report.entity_counts.at("segments"), 3u);
  EXPECT_EQ(r.report.extent->min_m, Eigen::Vector2d(-1, 0));
}

TEST(AmrlImportTest, ReadsTheTextFormat) {
  const auto r = import_amrl_vectormap("# x0, y0, x1, y1\n0, 0, 1, 0\n\n2.5,1,2.5,3\r\n");
  ASSERT_EQ(r.plan.objects.size(), 2u);
  EXPECT_EQ(r.plan.objects[1].pose.y_m, 2.0);
}

TEST(AmrlImportTest, ErrorsNameTheBadValue) {
  EXPECT_EQ(error_path(R"([{"p0": {"x": 0, "y": 0}, "p1": {"x": 1, "y": "1"}}])"), "[0].p1.y");
  EXPECT_EQ(error_path(R"([{"p0": {"x": 0, "y": 0}, "p1": {"x": 1}}])"), "[0].p1.y");
  EXPECT_EQ(error_path(R"([{"p0": {"x": 0, "y": 0}, "p1": {"x": 1e9, "y": 0}}])"), "[0].p1");
  EXPECT_EQ(error_path(R"([1])"), "[0]");
  EXPECT_EQ(error_path(R"([)"), "");
  EXPECT_EQ(error_path("0, 0, 1\n"), "line 1");
  EXPECT_EQ(error_path("0, 0, 1, 1\n0, 0, x, 1\n"), "line 2");
}

TEST(AmrlImportTest, NegativeMinimumLengthIsAnInvalidArgument) {
  AmrlImportOptions o;
  o.min_length_m = -1.0;
  EXPECT_THROW(import_amrl_vectormap("[]", o), std::invalid_argument);
}

}  // namespace
}  // namespace wm::apriori
