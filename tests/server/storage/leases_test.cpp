// Map leases with fencing epochs in PostgreSQL, against a private server: taken, renewed, lost, taken over with the
// next epoch; a store whose node lost the lease commits nothing; a takeover waits for a commit under way.
#include "server/storage/leases.h"

#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <thread>

#include "server/storage/postgres.h"
#include "server/storage/store.h"
#include "support/postgres_server.h"

namespace wm::storage {
namespace {

using namespace std::chrono_literals;

// A map name of the running test's own: the lease table is shared by every test of the process.
std::string map_name() { return testing::schema_for(::testing::UnitTest::GetInstance()->current_test_info()->name()); }

world::UpdateResult add_element(const world::WorldState& state, std::int64_t seq, double y) {
  world::Observation obs;
  obs.observer = "robot-1";
  auto s = fusion::LineSegment::from_points({0, y}, {3, y}, Eigen::Matrix2d::Identity());
  s.line.cov = world::midpoint_line_cov(s, 0.01, 0.01);
  obs.segments.push_back({s});
  return world::apply_observation(state, obs, seq, world::WorldOptions{}, [](const rules::DecisionQuery&) {
    return rules::Decision{"add", "r", "why", false};
  });
}

StoreOptions fenced_store(const std::string& schema, const std::string& node, std::int64_t epoch) {
  StoreOptions options;
  options.path = testing::postgres().uri();
  options.postgres_schema = schema;
  options.fence = Fence{schema, node, epoch};
  return options;
}

TEST(LeaseTest, ALeaseIsTakenRenewedLostAndTakenOverWithTheNextEpoch) {
  LeaseTable leases(testing::postgres().uri());
  const auto map = map_name();
  EXPECT_EQ(leases.acquire(map, "a", 300ms), 1);
  EXPECT_EQ(leases.acquire(map, "b", 300ms), std::nullopt) << "held by a";
  EXPECT_TRUE(leases.renew(map, "a", 1, 300ms));
  EXPECT_FALSE(leases.renew(map, "b", 1, 300ms));
  EXPECT_FALSE(leases.renew(map, "a", 2, 300ms)) << "not at that epoch";
  std::this_thread::sleep_for(400ms);
  EXPECT_FALSE(leases.renew(map, "a", 1, 300ms)) << "an expired lease is lost, taken over or not";
  EXPECT_EQ(leases.acquire(map, "b", 60s), 2);
  bool listed = false;
  for (const auto& lease : leases.leases())
    if (lease.map == map) {
      listed = true;
      EXPECT_EQ(lease.node, "b");
      EXPECT_EQ(lease.epoch, 2);
      EXPECT_GT(lease.expires_in_s, 50);
    }
  EXPECT_TRUE(listed);
  leases.release(map, "b", 2);
  EXPECT_EQ(leases.acquire(map, "a", 60s), 3) << "a released lease is free at once";
  // A node taking its own lease again starts a new epoch: its store of the old epoch is fenced off.
  EXPECT_EQ(leases.acquire(map, "a", 60s), 4);
}

TEST(FenceTest, AStoreWhoseNodeLostTheLeaseCommitsNothingAndTheNewOwnerGoesOn) {
  LeaseTable leases(testing::postgres().uri());
  const auto map = map_name();
  const auto epoch_a = leases.acquire(map, "a", 60s);
  ASSERT_TRUE(epoch_a);
  Store a(fenced_store(map, "a", *epoch_a));
  const auto first = add_element(world::WorldState{}, 1, 0);
  a.commit_observation(first, world::Observation{"r", "client", "unknown", 0, 0, {}}, "{}");

  leases.release(map, "a", *epoch_a);  // as if a's lease ran out while it was stopped
  const auto epoch_b = leases.acquire(map, "b", 60s);
  ASSERT_EQ(epoch_b, *epoch_a + 1);
  const auto second = add_element(first.state, 2, 1);
  EXPECT_THROW(a.commit_observation(second, world::Observation{"r", "client", "unknown", 0, 0, {}}, "{}"), FencedError);
  const auto scan_less = a.load(world::WorldOptions{});
  EXPECT_EQ(scan_less.elements.size(), 1u) << "the fenced commit wrote nothing";

  Store b(fenced_store(map, "b", *epoch_b));
  const auto state = b.load(world::WorldOptions{});
  ASSERT_EQ(state.elements.size(), 1u);
  b.commit_observation(add_element(state, 2, 1), world::Observation{"r", "client", "unknown", 0, 0, {}}, "{}");
  EXPECT_EQ(b.load(world::WorldOptions{}).elements.size(), 2u);
  EXPECT_THROW(a.commit_observation(second, world::Observation{"r", "client", "unknown", 0, 0, {}}, "{}"), FencedError);
}

TEST(FenceTest, AnExpiredLeaseFencesItsOwnerEvenWhenNoOneTookItOver) {
  LeaseTable leases(testing::postgres().uri());
  const auto map = map_name();
  const auto epoch = leases.acquire(map, "a", 60s);
  ASSERT_TRUE(epoch);
  Store a(fenced_store(map, "a", *epoch));
  ASSERT_TRUE(leases.renew(map, "a", *epoch, 200ms));
  std::this_thread::sleep_for(300ms);
  try {
    a.commit_observation(add_element(world::WorldState{}, 1, 0), world::Observation{"r", "client", "unknown", 0, 0, {}},
                         "{}");
    FAIL() << "an expired lease must fence its owner";
  } catch (const FencedError& e) {
    EXPECT_NE(std::string(e.what()).find("fenced: map " + map), std::string::npos) << e.what();
  }
  EXPECT_TRUE(a.load(world::WorldOptions{}).elements.empty());
}

// The fence holds the lease row until its transaction ends: a node that takes the expired lease over waits for the
// commit its old owner began while the lease was good, so no commit of the old epoch lands after the new one began.
TEST(FenceTest, ATakeoverWaitsForACommitUnderWay) {
  LeaseTable leases(testing::postgres().uri());
  const auto map = map_name();
  const auto epoch = leases.acquire(map, "a", 300ms);
  ASSERT_TRUE(epoch);
  PostgresConnection a(testing::postgres().uri(), map, true);
  a.set_fence({map, "a", *epoch});
  a.exec("CREATE TABLE IF NOT EXISTS t(k BIGINT PRIMARY KEY)");
  // The commit's answer reaches both threads at once, so their clocks after it are not compared: the takeover must
  // have waited at least as long as the commit's transaction ran (0.6 s from its start).
  std::atomic<std::chrono::steady_clock::time_point> began{};
  std::chrono::steady_clock::time_point taken;
  std::thread owner([&] {
    began = std::chrono::steady_clock::now();
    Transaction tx(a);
    Statement(a, "SELECT pg_sleep(0.6)").run();  // a slow commit, begun while the lease is good
    Statement(a, "INSERT INTO t(k) VALUES (1)").run();
    tx.commit();
  });
  std::this_thread::sleep_for(400ms);  // past the lease, while the commit runs
  const auto taken_epoch = leases.acquire(map, "b", 60s);
  taken = std::chrono::steady_clock::now();
  owner.join();
  EXPECT_EQ(taken_epoch, *epoch + 1);
  EXPECT_GE(taken - began.load(), 590ms) << "the takeover did not wait for the commit under way";
  Statement count(a, "SELECT COUNT(*) FROM t");
  count.step();
  EXPECT_EQ(count.column_int(0), 1);
}

// A node paused inside a fenced transaction holds the lease row; once its lease ran out, a node taking it over (with a
// bounded wait) ends that session instead of waiting for it for as long as it is paused, and the stalled
// transaction commits nothing.
TEST(FenceTest, ATakeoverEndsTheStalledTransactionOfAnExpiredOwner) {
  LeaseTable leases(testing::postgres().uri());
  const auto map = map_name();
  const auto epoch = leases.acquire(map, "a", 300ms);
  ASSERT_TRUE(epoch);
  PostgresConnection stalled(testing::postgres().uri(), map, true);
  stalled.exec("CREATE TABLE IF NOT EXISTS t(k BIGINT PRIMARY KEY)");
  stalled.exec("SET application_name = '" + fence_session_name(map, *epoch) + "'");
  stalled.exec("BEGIN");
  stalled.exec("SELECT 1 FROM wm_cluster.leases WHERE map = '" + map + "' FOR SHARE");
  stalled.exec("INSERT INTO t(k) VALUES (1)");  // ... and then its node stops answering
  std::this_thread::sleep_for(400ms);           // past the lease
  LeaseTable taker(testing::postgres().uri(), 200ms);
  const auto started = std::chrono::steady_clock::now();
  const auto taken = taker.acquire(map, "b", 3s);
  EXPECT_EQ(taken, *epoch + 1);
  EXPECT_LT(std::chrono::steady_clock::now() - started, 3s);
  EXPECT_THROW(stalled.exec("COMMIT"), StorageError);  // its session was ended: the insert never commits
  PostgresConnection reader(testing::postgres().uri(), map, false);
  Statement count(reader, "SELECT COUNT(*) FROM t");
  count.step();
  EXPECT_EQ(count.column_int(0), 0);
  // A live lease's holder is never ended: the wait runs out and the lease stays b's.
  PostgresConnection holder(testing::postgres().uri(), map, false);
  holder.exec("SET application_name = '" + fence_session_name(map, *taken) + "'");
  holder.exec("BEGIN");
  holder.exec("SELECT 1 FROM wm_cluster.leases WHERE map = '" + map + "' FOR SHARE");
  EXPECT_THROW(taker.acquire(map, "c", 3s), StorageError);
  holder.exec("COMMIT");
}

}  // namespace
}  // namespace wm::storage
