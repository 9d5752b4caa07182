#include "server/storage/store.h"

#include <sqlite3.h>

#include <gtest/gtest.h>

#include "support/temp_dir.h"

namespace wm::storage {
namespace {

apriori::FloorPlan plan() {
  return apriori::parse_floor_plan_json(R"({"name": "p", "objects": [
      {"id": "w", "kind": "wall", "attributes": ["solid"], "segments": [[[0, 10], [20, 10]]]},
      {"id": "t", "kind": "table", "attributes": ["not_deformable"], "pose": {"x": 5, "y": 5, "theta": 0.3},
       "polygon": [[-0.6, -0.4], [0.6, -0.4], [0.6, 0.4], [-0.6, 0.4]]}]})");
}

world::UpdateResult add_element(const world::WorldState& state, std::int64_t seq) {
  world::Observation obs;
  obs.observer = "robot-1";
  obs.stamp_s = 3.25;
  auto s = fusion::LineSegment::from_points({1.0 / 3.0, 2}, {4, 2.1}, Eigen::Matrix2d::Identity());
  s.line.cov = world::midpoint_line_cov(s, 0.01, 0.01);
  obs.segments.push_back({s});
  return world::apply_observation(state, obs, seq, world::WorldOptions{},
                                  [](const rules::DecisionQuery&) { return rules::Decision{"add", "r", "why", false}; });
}

TEST(StoreTest, NewFileHasCurrentSchemaAndEmptyWorld) {
  testing::TempDir dir;
  Store store({(dir.path() / "a.db").string(), true});
  EXPECT_EQ(store.schema_version(), Store::kSchemaVersion);
  const auto state = store.load(world::WorldOptions{});
  EXPECT_EQ(state.version, 0);
  EXPECT_TRUE(state.objects.empty());
  EXPECT_TRUE(state.elements.empty());
}

TEST(StoreTest, WorldSurvivesReopenBitForBit) {
  testing::TempDir dir;
  const auto path = (dir.path() / "a.db").string();
  world::WorldOptions options;
  world::WorldState saved;
  {
    Store store({path, true});
    auto loaded = world::apply_floor_plan(world::WorldState{}, plan(), options);
    // Move the table as a rigid update would, so the stored pose differs from the drawn one.
    loaded.state.objects[1].body = fusion::RigidObject({5.0 + 1e-3 / 7.0, 5.0, 0.3 + 1e-4}, Eigen::Matrix3d::Identity() * 1e-3,
                                                       loaded.state.objects[1].body.edges());
    store.commit_floor_plan(loaded, plan());
    auto update = add_element(loaded.state, 1);
    store.commit_observation(update, world::Observation{"robot-1", "client", "unknown", 3.25, 0.0, {}}, R"({"segments": []})");
    saved = update.state;
  }
  Store store({path, true});
  const auto state = store.load(options);
  EXPECT_EQ(state.version, saved.version);
  EXPECT_EQ(state.next_element_number, 2);
  EXPECT_EQ(state.last_decision_seq, 1);
  ASSERT_EQ(state.objects.size(), 2u);
  EXPECT_EQ(state.objects[1].body.pose().x_m, saved.objects[1].body.pose().x_m);
  EXPECT_EQ(state.objects[1].body.pose().theta_rad, saved.objects[1].body.pose().theta_rad);
  ASSERT_EQ(state.elements.size(), 1u);
  const auto& a = state.elements.at(1).segment;
  const auto& b = saved.elements.at(1).segment;
  EXPECT_EQ(a.line.rho_m, b.line.rho_m);
  EXPECT_EQ(a.line.phi_rad, b.line.phi_rad);
  EXPECT_EQ(a.line.cov, b.line.cov);
  EXPECT_EQ(a.t0_m, b.t0_m);
  EXPECT_EQ(a.t1_m, b.t1_m);
  const auto log = store.decisions(0, 10);
  ASSERT_EQ(log.size(), 1u);
  EXPECT_EQ(log[0].action, "add");
  EXPECT_EQ(log[0].element, "e1");
  EXPECT_EQ(log[0].observer, "robot-1");
  EXPECT_EQ(store.decisions(0, 10, std::string("e1")).size(), 1u);
  EXPECT_TRUE(store.decisions(0, 10, std::string("e2")).empty());
  EXPECT_TRUE(store.decisions(1, 10).empty());
}

TEST(StoreTest, FailedCommitLeavesNothingBehind) {
  testing::TempDir dir;
  Store store({(dir.path() / "a.db").string(), true});
  auto update = add_element(world::WorldState{}, 1);
  store.commit_observation(update, world::Observation{"r", "client", "unknown", 0, 0, {}}, "{}");
  // The same observation sequence again violates the journal's primary key: the transaction rolls back.
  auto again = add_element(update.state, 1);
  EXPECT_THROW(store.commit_observation(again, world::Observation{"r", "client", "unknown", 0, 0, {}}, "{}"), StorageError);
  const auto state = store.load(world::WorldOptions{});
  EXPECT_EQ(state.elements.size(), 1u);
  EXPECT_EQ(state.version, update.state.version);
  EXPECT_EQ(store.decisions(0, 10).size(), 1u);
}

TEST(StoreTest, RefusesADatabaseFromANewerVersion) {
  testing::TempDir dir;
  const auto path = (dir.path() / "a.db").string();
  { Store store({path, true}); }
  sqlite3* db = nullptr;
  ASSERT_EQ(sqlite3_open(path.c_str(), &db), SQLITE_OK);
  ASSERT_EQ(sqlite3_exec(db, "PRAGMA user_version = 99", nullptr, nullptr, nullptr), SQLITE_OK);
  sqlite3_close(db);
  try {
    Store store({path, true});
    FAIL() << "a newer schema must be refused";
  } catch (const StorageError& e) {
    EXPECT_NE(std::string(e.what()).find("newer"), std::string::npos);
  }
}

}  // namespace
}  // namespace wm::storage
