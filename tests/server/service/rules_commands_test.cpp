// The rules commands through the service that runs them, with a real store and a copy of the shipped rules: a reload
// takes a good edit and refuses a bad one whole, a query sees the active rules, and a dry run asks the logged
// decisions again with a candidate file without changing what is active.
#include "server/service/rules_commands.h"

#include <gtest/gtest.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <thread>

#include "server/service/service_test_helpers.h"
#include "server/service/world_service.h"
#include "support/temp_dir.h"

namespace wm::service {
namespace {

std::string read_file(const std::filesystem::path& path) {
  std::ifstream in(path);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

struct Served {
  testing::TempDir dir;
  std::filesystem::path rules_dir = [this] {
    auto path = dir.path() / "rules";
    std::filesystem::create_directories(path);
    std::filesystem::copy_file(WM_SOURCE_DIR "/rules/prolog/world_model.pl", path / "world_model.pl");
    return path;
  }();
  storage::Store store{{(dir.path() / "world.db").string(), false}};
  rules::Engine engine{rules::EngineOptions{rules_dir}};
  common::Diagnostics diagnostics{"", nullptr};
  WorldService world{ServiceOptions{}, store, engine, diagnostics};
};

std::size_t answers(WorldService& world, const std::string& goal) { return world.query(goal, 10).solutions.size(); }

TEST(RulesCommandsTest, AReloadTakesAGoodEditAndRefusesABadOneWholeWhileTheActiveRulesKeepAnswering) {
  Served s;
  const auto first = s.world.rules_status();
  EXPECT_EQ(first.files.size(), 1u);
  EXPECT_THROW(s.world.query("site(X)", 10), rules::QueryError);  // no such predicate yet

  std::ofstream(s.rules_dir / "site.pl") << "site(hq).\n";
  const auto reloaded = s.world.reload_rules();
  EXPECT_EQ(reloaded.generation, first.generation + 1);
  EXPECT_EQ(reloaded.files.size(), 2u);
  EXPECT_EQ(answers(s.world, "site(hq)"), 1u);

  // A second file with a syntax error: nothing of the edit is taken, the first edit stays active.
  std::ofstream(s.rules_dir / "zz_broken.pl") << "site(annex).\nthis is not ( prolog.\n";
  EXPECT_THROW(s.world.reload_rules(), rules::RuleError);
  const auto after = s.world.rules_status();
  EXPECT_EQ(after.generation, reloaded.generation);
  EXPECT_EQ(after.files.size(), 2u);
  EXPECT_FALSE(after.last_error.empty());
  EXPECT_EQ(answers(s.world, "site(X)"), 1u);
  EXPECT_EQ(answers(s.world, "site(annex)"), 0u);
}

TEST(RulesCommandsTest, ADryRunAsksTheLoggedDecisionsAgainWithTheCandidateAndChangesNothing) {
  Served s;
  s.world.load_floor_plan(wall_plan());
  for (int views = 0; views < 3; ++views) s.world.post_primitives(one_line({2, -1}, {2, 1}), "{}", std::nullopt);
  const auto logged = s.world.decisions(0, 100, std::nullopt);
  std::size_t confirmed = 0;
  for (const auto& d : logged) confirmed += d.rule == "solid_confirmed" ? 1 : 0;
  ASSERT_EQ(confirmed, 3u);  // each view of the wall confirmed it

  const auto text = read_file(s.rules_dir / "world_model.pl");
  const auto same = s.world.dry_run({"world_model.pl", text}, 100);
  EXPECT_EQ(same.redecided, logged.size());
  EXPECT_TRUE(same.changes.empty());

  // The same rules with the confirmation renamed: every confirmation would be decided by another rule.
  auto renamed = text;
  const std::string old_name = "solid_confirmed", new_name = "wall_confirmed_by_a_view";
  for (auto at = renamed.find(old_name); at != std::string::npos; at = renamed.find(old_name, at + new_name.size()))
    renamed.replace(at, old_name.size(), new_name);
  const auto differing = s.world.dry_run({"world_model.pl", renamed}, 100);
  ASSERT_EQ(differing.changes.size(), confirmed);
  EXPECT_EQ(differing.changes[0].candidate.rule, "wall_confirmed_by_a_view");
  // Nothing of the candidate is active.
  EXPECT_EQ(s.world.rules_status().generation, 1);
  EXPECT_EQ(answers(s.world, "clause(decide(_, _, _, R, _), _), R == solid_confirmed"), 1u);
  EXPECT_EQ(answers(s.world, "clause(decide(_, _, _, R, _), _), R == wall_confirmed_by_a_view"), 0u);
  const auto next = s.world.post_primitives(one_line({2, -1}, {2, 1}), "{}", std::nullopt);
  ASSERT_EQ(next.decisions.size(), 1u);
  EXPECT_EQ(next.decisions[0].rule, "solid_confirmed");
}

// Waits up to 10 s for the rules' generation to pass `generation`; the status then.
rules::RulesStatus next_generation(WorldService& world, std::int64_t generation) {
  for (int i = 0; i < 200 && world.rules_status().generation <= generation; ++i)
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  return world.rules_status();
}

TEST(RulesCommandsTest, TheWatcherFollowsAMapsOwnRulesDirectoryFromWhenItIsMadeUntilItGoes) {
  testing::TempDir dir;
  const auto shared = dir.path() / "rules";
  std::filesystem::create_directories(shared);
  std::filesystem::copy_file(WM_SOURCE_DIR "/rules/prolog/world_model.pl", shared / "world_model.pl");
  rules::EngineOptions engine_options{shared};
  engine_options.map_rules_dir = shared / "maps" / "floor2";  // not there yet
  storage::Store store{{(dir.path() / "world.db").string(), false}};
  rules::Engine engine{engine_options};
  common::Diagnostics diagnostics{"", nullptr};
  ServiceOptions options;
  options.watch_rules_dir = shared;
  WorldService world{options, store, engine, diagnostics};
  world.load_floor_plan(wall_plan());
  ASSERT_EQ(world.post_primitives(one_line({2, -1}, {2, 1}), "{}", std::nullopt).decisions.at(0).rule,
            "solid_confirmed");

  // As a person would: make the directories and save a file at once.
  std::filesystem::create_directories(engine_options.map_rules_dir);
  std::ofstream(engine_options.map_rules_dir / "50_floor2.pl")
      << "override(observation(_, _, _, _), element(_, O, _), add, floor2_no_walls, \"floor 2\") :-\n"
         "    attribute(O, solid).\n";
  const auto taken = next_generation(world, 1);
  ASSERT_EQ(taken.generation, 2) << taken.last_error;
  EXPECT_EQ(taken.files.size(), 2u);
  EXPECT_EQ(world.post_primitives(one_line({2, -1}, {2, 1}), "{}", std::nullopt).decisions.at(0).rule,
            "floor2_no_walls");

  // A file of the map edited: followed as the shared ones are.
  std::ofstream(engine_options.map_rules_dir / "50_floor2.pl")
      << "override(observation(_, _, _, _), element(_, O, _), add, floor2_edited, \"floor 2\") :-\n"
         "    attribute(O, solid).\n";
  ASSERT_EQ(next_generation(world, 2).generation, 3);
  EXPECT_EQ(world.post_primitives(one_line({2, -1}, {2, 1}), "{}", std::nullopt).decisions.at(0).rule, "floor2_edited");

  // The map's directory removed: the shared rules alone again.
  std::filesystem::remove_all(shared / "maps");
  const auto gone = next_generation(world, 3);
  ASSERT_EQ(gone.generation, 4) << gone.last_error;
  EXPECT_EQ(gone.files.size(), 1u);
  EXPECT_EQ(world.post_primitives(one_line({2, -1}, {2, 1}), "{}", std::nullopt).decisions.at(0).rule,
            "solid_confirmed");
}

}  // namespace
}  // namespace wm::service
