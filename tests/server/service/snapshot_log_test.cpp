// SnapshotLog: the published map and the ids each version removed (GET /api/v1/map?since=).
#include "server/service/snapshot_log.h"

#include <gtest/gtest.h>

namespace wm::service {
namespace {

world::WorldState at_version(std::int64_t version) {
  world::WorldState state;
  state.version = version;
  return state;
}

TEST(SnapshotLogTest, AReaderKeepsTheMapItTookWhileANewOneIsPublished) {
  SnapshotLog log(at_version(3));
  const auto held = log.current();
  log.publish(at_version(4));
  EXPECT_EQ(held->version, 3);
  EXPECT_EQ(log.current()->version, 4);
}

TEST(SnapshotLogTest, RemovalsAreMergedOverTheVersionsAsked) {
  SnapshotLog log(at_version(10));
  log.publish(at_version(11), MapRemovals{{"e1"}, {}});
  log.publish(at_version(12));
  log.publish(at_version(13), MapRemovals{{"e2", "e3"}, {"table"}});
  log.publish(at_version(14), MapRemovals{{"e4"}, {}});
  auto removed = log.removed_since(10, 13);
  ASSERT_TRUE(removed);
  EXPECT_EQ(removed->elements, (std::set<std::string>{"e1", "e2", "e3"}));
  EXPECT_EQ(removed->objects, (std::set<std::string>{"table"}));
  removed = log.removed_since(13, 14);
  ASSERT_TRUE(removed);
  EXPECT_EQ(removed->elements, (std::set<std::string>{"e4"}));
  EXPECT_TRUE(log.removed_since(14, 14)->elements.empty());
  // Before the start nothing is known: the client must read the whole map.
  EXPECT_FALSE(log.removed_since(9, 14));
}

TEST(SnapshotLogTest, TheOldestRemovalsAreForgottenPastTheLimit) {
  SnapshotLog log(at_version(0), 3);
  log.publish(at_version(1), MapRemovals{{"e1", "e2"}, {}});
  log.publish(at_version(2), MapRemovals{{"e3"}, {}});
  EXPECT_TRUE(log.removed_since(0, 2));
  log.publish(at_version(3), MapRemovals{{"e4"}, {}});  // four ids: version 1's go
  EXPECT_FALSE(log.removed_since(0, 3));
  const auto removed = log.removed_since(1, 3);
  ASSERT_TRUE(removed);
  EXPECT_EQ(removed->elements, (std::set<std::string>{"e3", "e4"}));
  // One version larger than the limit is still kept whole.
  log.publish(at_version(4), MapRemovals{{"a", "b", "c", "d", "e"}, {}});
  ASSERT_TRUE(log.removed_since(3, 4));
  EXPECT_EQ(log.removed_since(3, 4)->elements.size(), 5u);
}

}  // namespace
}  // namespace wm::service
