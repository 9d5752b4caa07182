// A map's own rule files beside the shared rules directory (EngineOptions::map_rules_dir): two engines on one
// shared directory, one of them with files of its own.
#include <gtest/gtest.h>

#include <filesystem>
#include <string>

#include "rules/engine.h"
#include "tests/rules/rules_test_helpers.h"

namespace wm::rules {
namespace {

using testing::copy_shipped_rules;
using testing::demo_floor_plan;
using testing::matched;
using testing::read_text;
using testing::replace_once;
using testing::TempDir;
using testing::unmatched;
using testing::write_text;

// Every solid wall a glass wall on this map: matched walls are added, not confirmed.
constexpr const char* kFloorOverride =
    "override(observation(_, _, _, _), element(_, Object, _), add, floor2_no_walls, \"floor 2: no wall confirms\") "
    ":-\n    attribute(Object, solid).\n";

class MapRulesTest : public ::testing::Test {
 protected:
  MapRulesTest() { copy_shipped_rules(shared_); }

  EngineOptions options(const std::string& knowledge_base, const std::filesystem::path& own) const {
    EngineOptions o;
    o.rules_dir = shared_.path();
    o.knowledge_base = knowledge_base;
    o.map_rules_dir = own;
    return o;
  }

  TempDir shared_;
  TempDir maps_;
};

bool lists(const RulesStatus& status, const std::filesystem::path& path) {
  for (const auto& file : status.files)
    if (std::filesystem::path(file.path).lexically_normal() == path.lexically_normal()) return true;
  return false;
}

TEST_F(MapRulesTest, AMapsOwnFileDecidesOnThatMapOnly) {
  const auto floor2 = maps_ / "floor2";
  std::filesystem::create_directories(floor2);
  write_text(floor2 / "50_floor2.pl", kFloorOverride);
  Engine with_own(options("wm_kb_maprules_a", floor2));
  Engine shared_only(options("wm_kb_maprules_b", maps_ / "floor3"));  // no such directory: the shared files alone
  with_own.set_floor_plan(demo_floor_plan());
  shared_only.set_floor_plan(demo_floor_plan());

  EXPECT_EQ(with_own.decide(matched("e1", "w1")).rule, "floor2_no_walls");
  EXPECT_EQ(shared_only.decide(matched("e1", "w1")).rule, "solid_confirmed");
  // The rest of the shared rules still decide on the map.
  EXPECT_EQ(with_own.decide(unmatched()).rule, "unmatched_added");
  EXPECT_TRUE(lists(with_own.status(), floor2 / "50_floor2.pl"));
  EXPECT_TRUE(lists(with_own.status(), shared_.path() / "world_model.pl"));
  EXPECT_EQ(shared_only.status().files.size(), 1u);
  EXPECT_EQ(with_own.map_rules_dir(), floor2);
}

TEST_F(MapRulesTest, AFileNamedLikeASharedOneReplacesItOnThatMap) {
  const auto floor2 = maps_ / "floor2";
  std::filesystem::create_directories(floor2);
  const std::string shipped = read_text(shared_ / "world_model.pl");
  write_text(floor2 / "world_model.pl", replace_once(shipped, "delete, solid_confirmed,", "delete, floor2_confirmed,"));
  Engine engine(options("wm_kb_maprules_c", floor2));
  engine.set_floor_plan(demo_floor_plan());

  EXPECT_EQ(engine.decide(matched("e1", "w1")).rule, "floor2_confirmed");
  ASSERT_EQ(engine.status().files.size(), 1u);
  EXPECT_TRUE(lists(engine.status(), floor2 / "world_model.pl"));
}

TEST_F(MapRulesTest, FilesAddedLaterFollowOnReloadAndABrokenOneIsRefusedWithItsPath) {
  const auto floor2 = maps_ / "floor2";
  Engine engine(options("wm_kb_maprules_d", floor2));
  engine.set_floor_plan(demo_floor_plan());
  EXPECT_EQ(engine.decide(matched("e1", "w1")).rule, "solid_confirmed");

  std::filesystem::create_directories(floor2);
  write_text(floor2 / "50_floor2.pl",
             "override(observation(_, _, _, _), element(_, O, _), add, broken, \"x\") :-\n"
             "    attribute(O, solid\n");
  try {
    engine.reload();
    ADD_FAILURE() << "a broken map file was loaded";
  } catch (const RuleError& e) {
    EXPECT_NE(std::string(e.what()).find((floor2 / "50_floor2.pl").string()), std::string::npos) << e.what();
  }
  EXPECT_EQ(engine.decide(matched("e1", "w1")).rule, "solid_confirmed");  // the previous rules stay

  write_text(floor2 / "50_floor2.pl", kFloorOverride);
  const auto generation = engine.status().generation;
  engine.reload();
  EXPECT_EQ(engine.status().generation, generation + 1);
  EXPECT_EQ(engine.decide(matched("e1", "w1")).rule, "floor2_no_walls");

  std::filesystem::remove_all(floor2);  // the map's directory gone: the shared rules alone again
  engine.reload();
  EXPECT_EQ(engine.decide(matched("e1", "w1")).rule, "solid_confirmed");
}

TEST_F(MapRulesTest, ADryRunOfAMapFileReplacesThatFile) {
  const auto floor2 = maps_ / "floor2";
  std::filesystem::create_directories(floor2);
  write_text(floor2 / "50_floor2.pl", kFloorOverride);
  Engine engine(options("wm_kb_maprules_e", floor2));
  engine.set_floor_plan(demo_floor_plan());
  const auto answers = engine.dry_run({"50_floor2.pl", "% nothing on this map after all\n"}, {matched("e1", "w1")});
  ASSERT_EQ(answers.size(), 1u);
  EXPECT_EQ(answers[0].rule, "solid_confirmed");
  EXPECT_EQ(engine.decide(matched("e1", "w1")).rule, "floor2_no_walls");  // the active rules untouched
}

}  // namespace
}  // namespace wm::rules
