// The map writer without sockets or threads: a real SQLite store for the map it starts from, the shipped rules, and
// an observation taken through its three steps (prepare, commit, finish), or stopped by a store write that throws.
#include "server/service/map_writer.h"

#include <gtest/gtest.h>

#include <stdexcept>

#include "server/service/service_test_helpers.h"
#include "server/storage/store.h"
#include "support/temp_dir.h"

namespace wm::service {
namespace {

std::int64_t element_facts(rules::Engine& engine) {
  const auto result = engine.query("aggregate_all(count, element(_, _, _, _, _, _, _, _), N)", 1);
  EXPECT_EQ(result.solutions.size(), 1u);
  return result.solutions.empty() ? -1 : result.solutions[0][0].integer;
}

struct MapWriterTest : ::testing::Test, WriterParts {};

TEST_F(MapWriterTest, APreparedObservationIsInTheRulesFactsAndReachesReadersOnlyWhenFinished) {
  const auto before = writer.snapshot();
  auto prepared = writer.prepare(before, one_line({0, 0}, {4, 0}));
  EXPECT_EQ(prepared.seq, before->last_observation_seq + 1);
  ASSERT_EQ(prepared.update.decisions.size(), 1u);
  EXPECT_EQ(prepared.update.decisions[0].action, rules::Action::add);
  // The rules decide the next segment against the decided map, readers still see the committed one.
  EXPECT_EQ(element_facts(engine), 1);
  EXPECT_EQ(writer.snapshot(), before);

  bool written = false;
  writer.commit(prepared, [&] { written = true; });
  EXPECT_TRUE(written);
  auto live = events.begin();
  const auto outcome = writer.finish(std::move(prepared), live);
  EXPECT_EQ(outcome.version, before->version + 1);
  EXPECT_EQ(writer.snapshot()->version, before->version + 1);
  EXPECT_EQ(writer.snapshot()->elements.size(), 1u);
  // The decision is a fact now (decision/7), for rules that look at the log.
  const auto logged = engine.query("aggregate_all(count, decision(_, _, _, _, _, _, _), N)", 1);
  ASSERT_EQ(logged.solutions.size(), 1u);
  EXPECT_EQ(logged.solutions[0][0].integer, 1);
}

TEST_F(MapWriterTest, AStoreWriteThatThrowsPutsTheRulesFactsBackToTheMapItWasDecidedAgainst) {
  {
    auto first = writer.prepare(writer.snapshot(), one_line({0, 0}, {4, 0}));
    writer.commit(first, [] {});
    auto live = events.begin();
    writer.finish(std::move(first), live);
  }
  const auto committed = writer.snapshot();
  auto second = writer.prepare(committed, one_line({0, 3}, {4, 3}));
  EXPECT_EQ(element_facts(engine), 2);
  EXPECT_THROW(writer.commit(second, [] { throw std::runtime_error("disk full"); }), std::runtime_error);
  EXPECT_EQ(element_facts(engine), 1);
  EXPECT_EQ(writer.snapshot(), committed);
  // Decided again, it is numbered as if the failed one never came.
  const auto again = writer.prepare(committed, one_line({0, 3}, {4, 3}));
  ASSERT_EQ(again.update.decisions.size(), 1u);
  EXPECT_EQ(again.update.decisions[0].element, std::optional<std::string>("e2"));
}

TEST_F(MapWriterTest, AnOwnObservationIsNumberedNextAndStampedButDecidesNothingByItself) {
  const auto base = writer.snapshot();
  const auto p = MapWriter::own_observation(base, "grid-trim", "grid", "grid");
  EXPECT_EQ(p.seq, base->last_observation_seq + 1);
  EXPECT_EQ(p.observation.observer, "grid-trim");
  EXPECT_EQ(p.observation.origin, "grid");
  EXPECT_GT(p.observation.received_at_unix_s, 1.7e9);
  EXPECT_TRUE(p.update.decisions.empty());
}

}  // namespace
}  // namespace wm::service
