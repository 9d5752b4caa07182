// Maps side by side in one registry, each with its own SQLite file and knowledge base, against real stores and the
// shipped rules: what one map takes in the other never sees, a restart opens them all again, and a removed map takes
// its files with it, also when a request still held it.
#include "server/service/map_registry.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "server/service/service_errors.h"
#include "server/service/service_test_helpers.h"
#include "support/temp_dir.h"

namespace wm::service {
namespace {

MapRegistryOptions registry_options(const std::filesystem::path& data_dir) {
  MapRegistryOptions options;
  options.data_dir = data_dir;
  options.store.synchronous_full = false;
  options.rules.rules_dir = WM_SOURCE_DIR "/rules/prolog";
  return options;
}

std::vector<std::string> files_in(const std::filesystem::path& dir) {
  std::vector<std::string> names;
  for (const auto& entry : std::filesystem::directory_iterator(dir)) names.push_back(entry.path().filename().string());
  std::sort(names.begin(), names.end());
  return names;
}

TEST(MapRegistryTest, MapIdsAreShortAndUrlSafe) {
  for (const char* good : {"a", "floor-1", "gdc_7", "0", "abcdefghijklmnopqrstuvwxyz012345"})
    EXPECT_TRUE(valid_map_id(good)) << good;
  for (const char* bad :
       {"", "-a", "_a", "A", "floor 1", "a/b", "..", "a.db", "é", "abcdefghijklmnopqrstuvwxyz0123456"})
    EXPECT_FALSE(valid_map_id(bad)) << bad;
}

TEST(MapRegistryTest, TwoMapsKeepTheirOwnElementsAndPlansAndARestartOpensBoth) {
  testing::TempDir dir;
  const auto data_dir = dir.path() / "maps";
  common::Diagnostics diagnostics{"", nullptr};
  {
    MapRegistry maps(registry_options(data_dir), diagnostics);
    EXPECT_TRUE(maps.ids().empty());
    auto floor1 = maps.create("floor-1");
    auto floor2 = maps.create("floor-2");
    EXPECT_THROW(maps.create("floor-1"), Conflict);
    EXPECT_THROW(maps.create("Floor 3"), std::invalid_argument);
    EXPECT_EQ(maps.ids(), (std::vector<std::string>{"floor-1", "floor-2"}));

    floor1->world.load_floor_plan(wall_plan());
    floor1->world.post_primitives(one_line({0, 3}, {4, 3}), "{}", std::nullopt);
    EXPECT_EQ(floor1->world.snapshot()->elements.size(), 1u);
    EXPECT_EQ(floor1->world.snapshot()->objects.size(), 1u);
    EXPECT_TRUE(floor2->world.snapshot()->elements.empty());
    EXPECT_TRUE(floor2->world.snapshot()->objects.empty());
    // Each map's rules see its own plan only.
    EXPECT_EQ(floor1->world.query("object(w, K)", 10).solutions.size(), 1u);
    EXPECT_TRUE(floor2->world.query("object(O, K)", 10).solutions.empty());
  }
  EXPECT_EQ(files_in(data_dir).size() >= 2, true);
  MapRegistry again(registry_options(data_dir), diagnostics);
  EXPECT_EQ(again.ids(), (std::vector<std::string>{"floor-1", "floor-2"}));
  EXPECT_EQ(again.find("floor-1")->world.snapshot()->elements.size(), 1u);
  EXPECT_EQ(again.find("floor-1")->world.query("object(w, K)", 10).solutions.size(), 1u);
  EXPECT_TRUE(again.find("floor-2")->world.snapshot()->elements.empty());
  EXPECT_EQ(again.find("floor-3"), nullptr);
}

TEST(MapRegistryTest, ARemovedMapTakesItsFilesAndLeavesTheOtherAsItWas) {
  testing::TempDir dir;
  const auto data_dir = dir.path() / "maps";
  common::Diagnostics diagnostics{"", nullptr};
  MapRegistry maps(registry_options(data_dir), diagnostics);
  maps.create("keep")->world.post_primitives(one_line({0, 3}, {4, 3}), "{}", std::nullopt);
  maps.create("gone")->world.post_primitives(one_line({0, 5}, {4, 5}), "{}", std::nullopt);
  EXPECT_THROW(maps.remove("nothing"), NotFound);

  maps.remove("gone");
  EXPECT_EQ(maps.find("gone"), nullptr);
  EXPECT_EQ(maps.ids(), std::vector<std::string>{"keep"});
  for (const auto& name : files_in(data_dir)) EXPECT_EQ(name.find("gone"), std::string::npos) << name;
  EXPECT_EQ(maps.find("keep")->world.snapshot()->elements.size(), 1u);
  // The id can be taken again: an empty map.
  EXPECT_TRUE(maps.create("gone")->world.snapshot()->elements.empty());
}

TEST(MapRegistryTest, ADamagedMapFileOrAStrangeNameInTheDirectoryLeavesTheOtherMapsServing) {
  testing::TempDir dir;
  const auto data_dir = dir.path() / "maps";
  common::Diagnostics diagnostics{"", nullptr};
  {
    MapRegistry maps(registry_options(data_dir), diagnostics);
    maps.create("good")->world.post_primitives(one_line({0, 3}, {4, 3}), "{}", std::nullopt);
  }
  { std::ofstream(data_dir / "broken.db") << "this is not an SQLite database, just text that is long enough to read"; }
  { std::ofstream(data_dir / "Not A Map.db") << "x"; }
  { std::ofstream(data_dir / "notes.txt") << "x"; }
  MapRegistry maps(registry_options(data_dir), diagnostics);
  EXPECT_EQ(maps.ids(), std::vector<std::string>{"good"});
  EXPECT_EQ(maps.find("good")->world.snapshot()->elements.size(), 1u);
  const auto summary = diagnostics.summary();
  EXPECT_EQ(summary.by_where.at("maps").errors, 1u);
  EXPECT_TRUE(std::filesystem::exists(data_dir / "broken.db"));  // left for a person to look at
}

TEST(MapRegistryTest, AMapRemovedWhileARequestHoldsItGoesWhenLetGo) {
  testing::TempDir dir;
  const auto data_dir = dir.path() / "maps";
  common::Diagnostics diagnostics{"", nullptr};
  MapRegistry maps(registry_options(data_dir), diagnostics);
  auto held = maps.create("busy");
  held->world.post_primitives(one_line({0, 3}, {4, 3}), "{}", std::nullopt);
  maps.remove("busy");
  EXPECT_EQ(maps.find("busy"), nullptr);
  // Its files are renamed aside, not yet removed: the request that holds it ends as it would have.
  auto names = files_in(data_dir);
  ASSERT_FALSE(names.empty());
  for (const auto& name : names) EXPECT_EQ(name.rfind(".removed-", 0), 0u) << name;
  held->world.post_primitives(one_line({0, 5}, {4, 5}), "{}", std::nullopt);
  EXPECT_EQ(held->world.snapshot()->elements.size(), 2u);
  held.reset();
  EXPECT_TRUE(files_in(data_dir).empty());
  // A start after a removal cut short removes what it left.
  { std::ofstream(data_dir / ".removed-7-old.db") << "x"; }
  MapRegistry again(registry_options(data_dir), diagnostics);
  EXPECT_TRUE(again.ids().empty());
  EXPECT_TRUE(files_in(data_dir).empty());
}

}  // namespace
}  // namespace wm::service
