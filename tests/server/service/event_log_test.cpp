// The event log on its own: commits go out in the order they began, each commit's events together and from one
// thread, whatever order their stages finish in; inert without subscribers; JSON made only for those who read it.
#include "server/service/event_log.h"

#include <gtest/gtest.h>

#include <map>
#include <mutex>
#include <thread>
#include <vector>

namespace wm::service {
namespace {

nlohmann::json body(const events::Event& event) { return nlohmann::json::parse(event.json); }

TEST(EventLogTest, ACommitClosedEarlyWaitsForTheOnesBeforeIt) {
  events::EventHub hub;
  common::Diagnostics diagnostics("", nullptr);
  EventLog log(&hub, diagnostics);
  const auto subscriber = hub.subscribe([] {});
  auto scan = log.begin();    // a scan: its grid region comes later, from the grid thread
  auto update = log.begin();  // the next commit, finished at once
  update.add(events::EventKind::update, [] { return nlohmann::json{{"version", 2}}; });
  update.close();
  EXPECT_TRUE(subscriber->take().empty());
  EXPECT_EQ(log.waiting(), 2u);
  scan.add(events::EventKind::update, [] { return nlohmann::json{{"version", 1}}; });
  scan.add(events::EventKind::scan, [] { return nlohmann::json{{"seq_of_scan", 7}}; });
  scan.close();
  const auto events = subscriber->take();
  ASSERT_EQ(events.size(), 3u);
  EXPECT_EQ(events[0].kind, events::EventKind::update);
  EXPECT_EQ(body(events[0]).at("version"), 1);
  EXPECT_EQ(events[1].kind, events::EventKind::scan);
  EXPECT_EQ(events[2].kind, events::EventKind::update);
  EXPECT_EQ(body(events[2]).at("version"), 2);
  EXPECT_EQ(log.waiting(), 0u);
}

TEST(EventLogTest, ACommitDroppedUnclosedLetsTheOnesBehindItGo) {
  events::EventHub hub;
  common::Diagnostics diagnostics("", nullptr);
  EventLog log(&hub, diagnostics);
  const auto subscriber = hub.subscribe([] {});
  auto later = [&] {
    auto dropped = log.begin();
    dropped.add(events::EventKind::update, [] { return nlohmann::json{{"version", 1}}; });
    auto next = log.begin();
    next.add(events::EventKind::update, [] { return nlohmann::json{{"version", 2}}; });
    next.close();
    EXPECT_TRUE(subscriber->take().empty());
    return 0;  // `dropped` dies here, as a value the network drops when the server stops
  };
  later();
  const auto events = subscriber->take();
  ASSERT_EQ(events.size(), 2u);
  EXPECT_EQ(body(events[0]).at("version"), 1);
  EXPECT_EQ(body(events[1]).at("version"), 2);
}

TEST(EventLogTest, EachCommitsEventsComeTogetherFromOneThreadInTheOrderTheCommitsBegan) {
  events::EventHub hub(1 << 16);
  common::Diagnostics diagnostics("", nullptr);
  EventLog log(&hub, diagnostics);
  std::mutex seen_mutex;
  std::vector<std::thread::id> publisher_of;  // by hub seq − 1
  const auto subscriber = hub.subscribe([&] {
    std::lock_guard lock(seen_mutex);
    publisher_of.push_back(std::this_thread::get_id());
  });
  // Four "writers" begin commits under one lock (the writer's order); each commit's three events are added and it is
  // closed later, on the thread that began it, so stages finish out of order.
  std::mutex writer;
  int next_commit = 0;
  constexpr int kPerThread = 300;
  std::vector<std::thread> threads;
  for (int t = 0; t < 4; ++t) {
    threads.emplace_back([&] {
      for (int i = 0; i < kPerThread; ++i) {
        EventLog::Commit commit;
        int n = 0;
        {
          std::lock_guard lock(writer);
          n = next_commit++;
          commit = log.begin();
        }
        for (int k = 0; k < 3; ++k)
          commit.add(events::EventKind::update, [&] { return nlohmann::json{{"commit", n}, {"part", k}}; });
        if (i % 7 == 0) std::this_thread::yield();
        commit.close();
      }
    });
  }
  for (auto& thread : threads) thread.join();
  const auto events = subscriber->take();
  ASSERT_EQ(events.size(), 4u * kPerThread * 3);
  ASSERT_EQ(publisher_of.size(), events.size());
  for (std::size_t i = 0; i < events.size(); ++i) {
    const auto e = body(events[i]);
    ASSERT_EQ(e.at("commit").get<std::size_t>(), i / 3) << "event " << i;
    ASSERT_EQ(e.at("part").get<std::size_t>(), i % 3) << "event " << i;
    ASSERT_EQ(publisher_of[i], publisher_of[i - i % 3]) << "commit " << i / 3 << " published from two threads";
  }
  EXPECT_EQ(log.waiting(), 0u);
}

TEST(EventLogTest, WithoutSubscribersNothingIsMadeOrHeld) {
  events::EventHub hub;
  common::Diagnostics diagnostics("", nullptr);
  EventLog log(&hub, diagnostics);
  int made = 0;
  auto commit = log.begin();
  commit.add(events::EventKind::update, [&] {
    ++made;
    return nlohmann::json::object();
  });
  EXPECT_EQ(log.waiting(), 0u);
  commit.close();
  EventLog without_hub(nullptr, diagnostics);
  without_hub.publish(events::EventKind::scan, [&] {
    ++made;
    return nlohmann::json::object();
  });
  EXPECT_EQ(made, 0);
}

TEST(EventLogTest, TheJsonIsMadeOnlyWhenASubscriberReadsIt) {
  events::EventHub hub;
  common::Diagnostics diagnostics("", nullptr);
  EventLog log(&hub, diagnostics);
  const auto bridge = hub.subscribe([] {}, false);
  int made = 0;
  const auto make = [&] {
    ++made;
    return nlohmann::json{{"type", "scan"}};
  };
  log.publish(events::EventKind::scan, make);
  EXPECT_EQ(made, 0);
  const auto page = hub.subscribe([] {});
  log.publish(events::EventKind::scan, make);
  EXPECT_EQ(made, 1);
  const auto seen = bridge->take();
  ASSERT_EQ(seen.size(), 2u);
  EXPECT_EQ(seen[0].json, R"({"seq":1})");
  EXPECT_EQ(body(seen[1]).at("type"), "scan");
}

TEST(EventLogTest, AnEventWhoseJsonCannotBeMadeIsReportedAndTheRestOfItsCommitGoes) {
  events::EventHub hub;
  common::Diagnostics diagnostics("", nullptr);
  EventLog log(&hub, diagnostics);
  const auto subscriber = hub.subscribe([] {});
  auto commit = log.begin();
  commit.add(events::EventKind::update, []() -> nlohmann::json { throw std::runtime_error("no state"); });
  commit.add(events::EventKind::robot, [] { return nlohmann::json{{"type", "robot"}}; });
  commit.close();
  const auto events = subscriber->take();
  ASSERT_EQ(events.size(), 1u);
  EXPECT_EQ(events[0].kind, events::EventKind::robot);
  EXPECT_EQ(diagnostics.summary().by_where.at("events").warnings, 1u);
}

}  // namespace
}  // namespace wm::service
