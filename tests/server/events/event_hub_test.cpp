// The event hub on its own: seq stamping and order, kinds kept, a subscriber that falls behind gets one resync,
// bad texts refused, many publishers at once.
#include "server/events/event_hub.h"

#include <gtest/gtest.h>

#include <atomic>
#include <nlohmann/json.hpp>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

namespace wm::events {
namespace {

std::uint64_t seq_of(const Event& event) { return nlohmann::json::parse(event.json).at("seq").get<std::uint64_t>(); }

TEST(EventHubTest, EveryEventIsStampedInOrderAndKeepsItsKind) {
  EventHub hub;
  int wakes = 0;
  const auto subscriber = hub.subscribe([&wakes] { ++wakes; });
  hub.publish(EventKind::update, R"({"type":"update","version":3})");
  hub.publish(EventKind::scan, "{}");
  const auto events = subscriber->take();
  ASSERT_EQ(events.size(), 2u);
  EXPECT_EQ(events[0].kind, EventKind::update);
  EXPECT_EQ(events[0].json, R"({"seq":1,"type":"update","version":3})");
  EXPECT_EQ(events[1].kind, EventKind::scan);
  EXPECT_EQ(events[1].json, R"({"seq":2})");
  EXPECT_EQ(wakes, 2);
  EXPECT_TRUE(subscriber->take().empty());
  EXPECT_EQ(hub.last_seq(), 2u);
}

TEST(EventHubTest, ASubscriberThatFallsBehindGetsOneResyncAndCountsWhatItLost) {
  EventHub hub(4);
  const auto slow = hub.subscribe([] {});
  const auto quick = hub.subscribe([] {});
  for (int i = 0; i < 10; ++i) {
    hub.publish(EventKind::update, "{}");
    quick->take();
  }
  const auto events = slow->take();
  ASSERT_EQ(events.size(), 1u);
  EXPECT_EQ(events[0].kind, EventKind::resync);
  EXPECT_EQ(nlohmann::json::parse(events[0].json).at("type"), "resync");
  EXPECT_EQ(slow->dropped(), 10u);
  EXPECT_EQ(quick->dropped(), 0u);
  hub.publish(EventKind::robot, "{}");  // after the resync was read, events flow again
  const auto after = slow->take();
  ASSERT_EQ(after.size(), 1u);
  EXPECT_EQ(after[0].kind, EventKind::robot);
  EXPECT_EQ(seq_of(after[0]), 11u);
}

TEST(EventHubTest, BadTextsAreRefusedAndAnUnsubscribedSubscriberHearsNothing) {
  EventHub hub;
  const auto subscriber = hub.subscribe([] {});
  EXPECT_THROW(hub.publish(EventKind::update, ""), std::invalid_argument);
  EXPECT_THROW(hub.publish(EventKind::update, "[1]"), std::invalid_argument);
  EXPECT_THROW(hub.publish(EventKind::update, "{\"a\":1"), std::invalid_argument);
  EXPECT_EQ(hub.last_seq(), 0u) << "a refused event takes no number";
  hub.unsubscribe(subscriber);
  hub.publish(EventKind::update, "{}");
  EXPECT_TRUE(subscriber->take().empty());
  EXPECT_EQ(hub.subscriber_count(), 0u);
}

TEST(EventHubTest, ManyPublishersAtOnceStillGiveEverySubscriberOneIncreasingSequence) {
  EventHub hub(100'000);
  const auto a = hub.subscribe([] {});
  const auto b = hub.subscribe([] {});
  std::vector<std::thread> publishers;
  for (int t = 0; t < 4; ++t)
    publishers.emplace_back([&hub] {
      for (int i = 0; i < 2000; ++i) hub.publish(EventKind::scan, "{}");
    });
  for (auto& p : publishers) p.join();
  for (const auto& subscriber : {a, b}) {
    const auto events = subscriber->take();
    ASSERT_EQ(events.size(), 8000u);
    for (std::size_t i = 0; i < events.size(); ++i) ASSERT_EQ(seq_of(events[i]), i + 1);
  }
}

}  // namespace
}  // namespace wm::events
