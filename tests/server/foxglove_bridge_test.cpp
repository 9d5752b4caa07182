#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <cstring>
#include <mutex>
#include <nlohmann/json.hpp>
#include <thread>

#include "server/foxglove/bridge.h"
#include "server/foxglove/messages.h"
#include "server/world/update.h"
#include "tests/server/api/fake_world_port.h"
#include "tests/support/lab_plan.h"

namespace wm::foxglove {
namespace {

using nlohmann::json;
using namespace std::chrono_literals;

// The fake port with what the bridge reads guarded by a lock, since the bridge reads it from its own thread while the
// test changes it: the snapshot, the decision log with its removals, the grid.
class LiveWorld : public testing::FakeWorldPort {
 public:
  LiveWorld() : current_(std::make_shared<const world::WorldState>()) {}

  std::shared_ptr<const world::WorldState> snapshot() const override {
    std::lock_guard lock(mutex_);
    return current_;
  }
  void set(world::WorldState state, std::set<std::string> removed_elements = {}) {
    std::lock_guard lock(mutex_);
    for (const auto& id : removed_elements) removals_.emplace_back(state.version, id);
    current_ = std::make_shared<const world::WorldState>(std::move(state));
  }
  std::optional<service::MapRemovals> removed_since(std::int64_t since, std::int64_t up_to) const override {
    std::lock_guard lock(mutex_);
    service::MapRemovals removed;
    for (const auto& [version, id] : removals_)
      if (version > since && version <= up_to) removed.elements.insert(id);
    return removed;
  }
  /// Logs a decision; the snapshot's last decision moves with it, as the service's does.
  void log(world::DecisionRecord decision) {
    std::lock_guard lock(mutex_);
    auto state = *current_;
    state.last_decision_seq = decision.seq;
    current_ = std::make_shared<const world::WorldState>(std::move(state));
    log_.push_back(std::move(decision));
  }
  std::vector<world::DecisionRecord> decisions(std::int64_t since_seq, std::size_t limit,
                                               const std::optional<std::string>&) override {
    std::lock_guard lock(mutex_);
    std::vector<world::DecisionRecord> rows;
    for (const auto& d : log_)
      if (d.seq > since_seq && rows.size() < limit) rows.push_back(d);
    return rows;
  }
  void insert(const fusion::LaserScan& scan) {
    std::lock_guard lock(mutex_);
    grid_.insert(scan);
    ++revision_;
  }
  std::vector<float> bayes() const {
    std::lock_guard lock(mutex_);
    return grid_.export_layer(fusion::OccupancyGrid::Layer::bayes_probability, *grid_.bounds());
  }
  std::optional<fusion::GridGeometry> grid_bounds() const override {
    std::lock_guard lock(mutex_);
    return grid_.bounds();
  }
  service::GridTiles grid_tiles() const override {
    std::lock_guard lock(mutex_);
    service::GridTiles result{grid_.tile_size_cells(), grid_.resolution_m(), revision_, {}};
    for (const auto& [index, revision] : grid_.tile_revisions()) result.tiles.push_back({index.x, index.y, revision});
    return result;
  }
  std::optional<service::GridTileValues> grid_tile(fusion::GridLayer layer, std::int64_t tx,
                                                   std::int64_t ty) const override {
    std::lock_guard lock(mutex_);
    const auto revision = grid_.tile_revision({tx, ty});
    if (revision == 0) return std::nullopt;
    ++tile_reads;
    return service::GridTileValues{
        grid_.export_layer(fusion::stored_layer(layer).value(), grid_.tiles_geometry({tx, ty}, {tx, ty})), revision};
  }
  std::optional<service::GridTileValues> grid_tile_layers(std::int64_t tx, std::int64_t ty) const override {
    std::lock_guard lock(mutex_);
    const auto revision = grid_.tile_revision({tx, ty});
    if (revision == 0) return std::nullopt;
    ++tile_reads;
    return service::GridTileValues{grid_.export_tile_layers({tx, ty}), revision};
  }

  mutable std::atomic<int> tile_reads{0};

 private:
  mutable std::mutex mutex_;
  std::shared_ptr<const world::WorldState> current_;
  std::vector<std::pair<std::int64_t, std::string>> removals_;
  std::vector<world::DecisionRecord> log_;
  fusion::OccupancyGrid grid_{fusion::GridOptions{}};
  std::int64_t revision_ = 0;
};

// What the transport does with an endpoint: opens it, and takes its frames.
struct Frame {
  bool binary = false;
  json text;                       // a text frame
  std::uint32_t subscription = 0;  // a data frame's header
  std::uint64_t stamp_ns = 0;
  json payload;
  std::size_t payload_bytes = 0;
};

class Connection {
 public:
  explicit Connection(std::shared_ptr<http::WebSocketEndpoint> endpoint) : endpoint_(std::move(endpoint)) {
    endpoint_->open([this] { ++wakes; });
  }
  ~Connection() { endpoint_->close(); }

  std::vector<Frame> take() {
    std::vector<Frame> frames;
    for (auto& f : endpoint_->take()) {
      Frame frame;
      frame.binary = f.binary;
      if (!f.binary) {
        frame.text = json::parse(f.head);
      } else {
        EXPECT_EQ(f.head.size(), kMessageDataHeaderBytes);
        EXPECT_EQ(f.head[0], '\x01');
        std::memcpy(&frame.subscription, f.head.data() + 1, 4);  // the tests run on little-endian hosts
        std::memcpy(&frame.stamp_ns, f.head.data() + 5, 8);
        frame.payload = json::parse(*f.body);
        frame.payload_bytes = f.body->size();
      }
      frames.push_back(std::move(frame));
    }
    return frames;
  }
  /// Takes frames until `done` holds for all taken so far (or 5 s pass); returns them all.
  std::vector<Frame> take_until(const std::function<bool(const std::vector<Frame>&)>& done) {
    std::vector<Frame> all;
    const auto deadline = std::chrono::steady_clock::now() + 5s;
    while (!done(all) && std::chrono::steady_clock::now() < deadline) {
      for (auto& f : take()) all.push_back(std::move(f));
      std::this_thread::sleep_for(2ms);
    }
    return all;
  }
  void send(const json& message) { endpoint_->receive(message.dump(), false); }
  void subscribe(std::uint32_t id, std::uint32_t channel) {
    send({{"op", "subscribe"}, {"subscriptions", {{{"id", id}, {"channelId", channel}}}}});
  }

  std::atomic<int> wakes{0};

 private:
  std::shared_ptr<http::WebSocketEndpoint> endpoint_;
};

std::size_t count_for(const std::vector<Frame>& frames, std::uint32_t subscription) {
  return static_cast<std::size_t>(std::count_if(
      frames.begin(), frames.end(), [&](const Frame& f) { return f.binary && f.subscription == subscription; }));
}
const Frame* last_for(const std::vector<Frame>& frames, std::uint32_t subscription) {
  for (auto it = frames.rbegin(); it != frames.rend(); ++it)
    if (it->binary && it->subscription == subscription) return &*it;
  return nullptr;
}

world::Element element(std::int64_t number, double y, std::int64_t version) {
  world::Element e;
  e.number = number;
  e.segment = fusion::LineSegment::from_points({0, y}, {2, y}, Eigen::Matrix2d::Identity() * 1e-4);
  e.origin = "scan";
  e.created_version = e.updated_version = version;
  return e;
}

world::DecisionRecord decision(std::int64_t seq) {
  world::DecisionRecord d;
  d.seq = seq;
  d.action = rules::Action::add;
  d.rule = "unmatched_added";
  d.element = "e" + std::to_string(seq);
  return d;
}

fusion::LaserScan scan_at(double x) {
  fusion::LaserScan s;
  s.sensor_pose = {x, 0, 0};
  s.angle_min_rad = -M_PI / 2;
  s.angle_increment_rad = M_PI / 180;
  s.ranges_m.assign(181, 3.0);
  s.range_max_m = 10;
  return s;
}

class FoxgloveBridgeTest : public ::testing::Test {
 protected:
  FoxgloveBridgeTest() {
    options_.update_period = 1ms;
    options_.grid_period = 1ms;
  }
  std::unique_ptr<Bridge> start() {
    return std::make_unique<Bridge>(options_, world_, hub_, diagnostics_,
                                    ServerInfo{"wmd test", "run-1", {{"api", "/api/v1"}}});
  }
  void publish(events::EventKind kind) { hub_.publish(kind, "{}"); }

  FoxgloveOptions options_;
  LiveWorld world_;
  events::EventHub hub_;
  common::Diagnostics diagnostics_;
};

TEST_F(FoxgloveBridgeTest, AClientIsGreetedWithServerInfoThenTheChannels) {
  const auto bridge = start();
  Connection client(bridge->connect());
  const auto frames = client.take_until([](const auto& f) { return f.size() >= 2; });
  ASSERT_EQ(frames.size(), 2u);
  EXPECT_EQ(frames[0].text["op"], "serverInfo");
  EXPECT_EQ(frames[0].text["sessionId"], "run-1");
  EXPECT_EQ(frames[1].text["op"], "advertise");
  std::map<int, std::pair<std::string, std::string>> channels;
  for (const auto& c : frames[1].text["channels"]) channels[c["id"]] = {c["topic"], c["schemaName"]};
  EXPECT_EQ(channels, (std::map<int, std::pair<std::string, std::string>>{
                          {kGridChannel, {"/grid", "foxglove.Grid"}},
                          {kGridDsChannel, {"/grid/ds", "foxglove.Grid"}},
                          {kElementsChannel, {"/map/elements", "foxglove.SceneUpdate"}},
                          {kPlanChannel, {"/map/plan", "foxglove.SceneUpdate"}},
                          {kTfChannel, {"/tf", "foxglove.FrameTransforms"}},
                          {kDecisionsChannel, {"/decisions", "foxglove.Log"}}}));
  EXPECT_GT(client.wakes.load(), 0);
  EXPECT_EQ(bridge->stats().clients, 1u);
}

TEST_F(FoxgloveBridgeTest, ASubscriberGetsTheWholeSceneAtOnceThenOnlyWhatChanged) {
  auto state = world::apply_floor_plan(world::WorldState{}, testing::lab_plan(), world_.world_options()).state;
  state.elements.put(element(1, 1.0, state.version));
  state.elements.put(element(2, 2.0, state.version));
  world_.set(state);
  const auto bridge = start();
  Connection client(bridge->connect());
  client.subscribe(10, kElementsChannel);
  client.subscribe(11, kPlanChannel);
  auto frames = client.take_until([](const auto& f) { return count_for(f, 10) >= 1 && count_for(f, 11) >= 1; });
  const auto* scene = last_for(frames, 10);
  ASSERT_NE(scene, nullptr);
  ASSERT_EQ(scene->payload["deletions"].size(), 1u);
  EXPECT_EQ(scene->payload["deletions"][0]["type"], 1);  // everything on the topic goes first
  ASSERT_EQ(scene->payload["entities"].size(), 2u);
  for (const auto& entity : scene->payload["entities"]) {
    const auto* e = state.find_element(entity["id"]);
    ASSERT_NE(e, nullptr) << entity["id"];
    const auto& points = entity["lines"][0]["points"];
    EXPECT_EQ(points[0]["x"], e->segment.p0().x());
    EXPECT_EQ(points[0]["y"], e->segment.p0().y());
    EXPECT_EQ(points[1]["x"], e->segment.p1().x());
    EXPECT_EQ(points[1]["y"], e->segment.p1().y());
  }
  const auto* plan = last_for(frames, 11);
  ASSERT_NE(plan, nullptr);
  ASSERT_EQ(plan->payload["entities"].size(), 2u);
  EXPECT_EQ(plan->payload["entities"][0]["id"], "wall-n");
  EXPECT_EQ(plan->payload["entities"][1]["id"], "table-1");
  EXPECT_EQ(plan->payload["entities"][1]["lines"][0]["points"].size(), 8u);

  // One element added, one removed: a change of those two, not the whole scene; the plan did not change.
  auto next = state;
  next.version = state.version + 1;
  next.elements.erase(1);
  next.elements.put(element(3, 3.0, next.version));
  world_.set(next, {"e1"});
  publish(events::EventKind::update);
  frames = client.take_until([](const auto& f) { return count_for(f, 10) >= 1; });
  ASSERT_EQ(count_for(frames, 10), 1u);
  const auto* change = last_for(frames, 10);
  EXPECT_EQ(change->payload["deletions"],
            json::parse(R"([{"id":"e1","timestamp":)" + change->payload["deletions"][0]["timestamp"].dump() +
                        R"(,"type":0}])"));
  ASSERT_EQ(change->payload["entities"].size(), 1u);
  EXPECT_EQ(change->payload["entities"][0]["id"], "e3");
  std::this_thread::sleep_for(50ms);
  EXPECT_EQ(count_for(client.take(), 11), 0u) << "the plan did not change";
}

TEST_F(FoxgloveBridgeTest, TheGridIsItsCellsAndALaterGridReplacesOneStillQueued) {
  world_.insert(scan_at(0));
  const auto bridge = start();
  Connection client(bridge->connect());
  client.subscribe(1, kGridChannel);
  auto frames = client.take_until([](const auto& f) { return count_for(f, 1) >= 1; });
  const auto* grid = last_for(frames, 1);
  ASSERT_NE(grid, nullptr);
  const auto bounds = *world_.grid_bounds();
  EXPECT_EQ(grid->payload["column_count"], bounds.width());
  EXPECT_EQ(grid->payload["pose"]["position"]["x"], bounds.origin_m().x());
  EXPECT_EQ(grid->payload["pose"]["position"]["y"], bounds.origin_m().y());
  const auto bytes = grid->payload["data"].get<std::string>();
  const auto expected = world_.bayes();
  std::vector<float> want(expected.begin(), expected.end());
  const fusion::GridGeometry region(bounds.origin_m(), bounds.resolution_m(), bounds.width(), bounds.height());
  EXPECT_EQ(bytes, json::parse(grid_message(region, {{"probability", want}}, 0))["data"].get<std::string>())
      << "the cells are the grid's";

  // Three changes of the grid while the client does not read: one grid message waits for it, the newest.
  const auto built = bridge->stats().grid_messages;
  for (int i = 1; i <= 3; ++i) {
    world_.insert(scan_at(0.5 * i));
    publish(events::EventKind::scan);
    const auto deadline = std::chrono::steady_clock::now() + 5s;
    while (bridge->stats().grid_messages < built + static_cast<std::uint64_t>(i) &&
           std::chrono::steady_clock::now() < deadline)
      std::this_thread::sleep_for(1ms);
  }
  frames = client.take();
  ASSERT_EQ(count_for(frames, 1), 1u);
  EXPECT_GE(bridge->stats().superseded, 2u);
  const auto newest = world_.bayes();
  const auto newest_bounds = *world_.grid_bounds();
  EXPECT_EQ(last_for(frames, 1)->payload["data"].get<std::string>(),
            json::parse(grid_message(newest_bounds, {{"probability", newest}}, 0))["data"].get<std::string>());
}

TEST_F(FoxgloveBridgeTest, OnlyTheTilesThatChangedAreReadAgain) {
  world_.insert(scan_at(0));
  world_.insert(scan_at(40));  // far away: tiles of their own
  const auto bridge = start();
  Connection client(bridge->connect());
  client.subscribe(1, kGridChannel);
  client.take_until([](const auto& f) { return count_for(f, 1) >= 1; });
  const auto revisions = [&] {
    std::map<std::pair<std::int64_t, std::int64_t>, std::uint64_t> r;
    for (const auto& t : world_.grid_tiles().tiles) r[{t.tx, t.ty}] = t.revision;
    return r;
  };
  const auto before = revisions();
  EXPECT_EQ(static_cast<std::size_t>(world_.tile_reads.load()), before.size()) << "each tile read once";
  const int first = world_.tile_reads.load();
  world_.insert(scan_at(40));
  publish(events::EventKind::scan);
  client.take_until([](const auto& f) { return count_for(f, 1) >= 1; });
  const auto after = revisions();
  std::size_t changed = 0;
  for (const auto& [index, revision] : after)
    if (!before.contains(index) || before.at(index) != revision) ++changed;
  EXPECT_GT(changed, 0u);
  EXPECT_LT(changed, after.size());
  EXPECT_EQ(static_cast<std::size_t>(world_.tile_reads.load() - first), changed)
      << "only the tiles the scan at x = 40 changed";
}

TEST_F(FoxgloveBridgeTest, AClientThatFallsBehindLosesItsQueueAndGetsTheCurrentStateWhenItReadsAgain) {
  options_.max_queued_messages = 5;
  for (int seq = 1; seq <= 3; ++seq) world_.log(decision(seq));
  const auto bridge = start();
  Connection client(bridge->connect());
  client.subscribe(4, kDecisionsChannel);
  auto frames = client.take_until([](const auto& f) { return count_for(f, 4) >= 3; });
  EXPECT_EQ(count_for(frames, 4), 3u) << "the decisions so far";

  // Twenty decisions, one event each, while the client reads nothing: more than five changes queued.
  for (int seq = 4; seq <= 23; ++seq) {
    world_.log(decision(seq));
    publish(events::EventKind::update);
    std::this_thread::sleep_for(2ms);
  }
  const auto deadline = std::chrono::steady_clock::now() + 5s;
  while (bridge->stats().dropped == 0 && std::chrono::steady_clock::now() < deadline) std::this_thread::sleep_for(1ms);
  EXPECT_GT(bridge->stats().dropped, 0u);

  frames = client.take_until([](const auto& f) { return count_for(f, 4) >= 20; });
  ASSERT_FALSE(frames.empty());
  ASSERT_FALSE(frames[0].binary) << "first the warning";
  EXPECT_EQ(frames[0].text["op"], "status");
  EXPECT_EQ(frames[0].text["level"], 1);
  EXPECT_NE(frames[0].text["message"].get<std::string>().find("fell behind"), std::string::npos);
  // Then the current state: the log up to the last decision, in order.
  std::vector<std::int64_t> seqs;
  for (const auto& f : frames)
    if (f.binary && f.subscription == 4) {
      const auto message = f.payload["message"].get<std::string>();
      seqs.push_back(std::stoll(message.substr(std::string("decision ").size())));
    }
  ASSERT_FALSE(seqs.empty());
  EXPECT_EQ(seqs.back(), 23);
  EXPECT_TRUE(std::is_sorted(seqs.begin(), seqs.end()));
  EXPECT_EQ(bridge->stats().resyncs, 1u);
}

TEST_F(FoxgloveBridgeTest, EachRobotGetsAPoseChannelAndATransform) {
  const auto bridge = start();
  Connection client(bridge->connect());
  client.take_until([](const auto& f) { return f.size() >= 2; });
  world_.registry.on_pose("r1", {1.5, -2.0, 0.75, std::nullopt, 10.0, 1'700'000'000.25, "reported"}, false);
  publish(events::EventKind::robot);
  auto frames = client.take_until([](const auto& f) { return !f.empty(); });
  ASSERT_EQ(frames.size(), 1u);
  EXPECT_EQ(frames[0].text["op"], "advertise");
  const auto channel = frames[0].text["channels"][0];
  EXPECT_EQ(channel["topic"], "/robots/r1/pose");
  EXPECT_EQ(channel["schemaName"], "foxglove.PoseInFrame");
  EXPECT_EQ(channel["id"], kFirstRobotChannel);

  client.subscribe(1, kFirstRobotChannel);
  client.subscribe(2, kTfChannel);
  frames = client.take_until([](const auto& f) { return count_for(f, 1) >= 1 && count_for(f, 2) >= 1; });
  const auto& pose = last_for(frames, 1)->payload;
  EXPECT_EQ(pose["frame_id"], "map");
  EXPECT_EQ(pose["pose"]["position"]["x"], 1.5);
  EXPECT_EQ(pose["pose"]["position"]["y"], -2.0);
  EXPECT_NEAR(
      2 * std::atan2(pose["pose"]["orientation"]["z"].get<double>(), pose["pose"]["orientation"]["w"].get<double>()),
      0.75, 1e-12);
  EXPECT_EQ(pose["timestamp"]["sec"], 1'700'000'000);  // when the server received it
  EXPECT_EQ(pose["timestamp"]["nsec"], 250'000'000);
  const auto& tf = last_for(frames, 2)->payload["transforms"];
  ASSERT_EQ(tf.size(), 1u);
  EXPECT_EQ(tf[0]["child_frame_id"], "r1/base_link");
  EXPECT_EQ(tf[0]["translation"]["x"], 1.5);

  // It moves: a new pose, a new tree of transforms.
  world_.registry.on_pose("r1", {2.5, -2.0, 0.75, std::nullopt, 11.0, 1'700'000'001.0, "reported"}, false);
  publish(events::EventKind::robot);
  frames = client.take_until([](const auto& f) { return count_for(f, 1) >= 1 && count_for(f, 2) >= 1; });
  EXPECT_EQ(last_for(frames, 1)->payload["pose"]["position"]["x"], 2.5);
  EXPECT_EQ(last_for(frames, 2)->payload["transforms"][0]["translation"]["x"], 2.5);
}

TEST_F(FoxgloveBridgeTest, UnsubscribingStopsTheMessagesAndBadRequestsAreAnsweredWithStatuses) {
  world_.log(decision(1));
  const auto bridge = start();
  Connection client(bridge->connect());
  client.subscribe(4, kDecisionsChannel);
  client.take_until([](const auto& f) { return count_for(f, 4) >= 1; });
  client.send({{"op", "unsubscribe"}, {"subscriptionIds", {4, 99}}});
  world_.log(decision(2));
  publish(events::EventKind::update);
  std::this_thread::sleep_for(50ms);
  auto frames = client.take();
  EXPECT_EQ(count_for(frames, 4), 0u);
  ASSERT_EQ(frames.size(), 1u);
  EXPECT_EQ(frames[0].text["level"], 1);
  EXPECT_EQ(frames[0].text["message"], "unsubscribe: no subscription 99");

  client.subscribe(5, 1234);
  client.send({{"op", "subscribeParameterUpdates"}, {"parameterNames", json::array()}});
  client.send({{"op", "subscribe"}, {"subscriptions", "all"}});
  frames = client.take();
  ASSERT_EQ(frames.size(), 3u);
  EXPECT_EQ(frames[0].text["message"], "subscribe: no channel 1234");
  EXPECT_NE(frames[1].text["message"].get<std::string>().find("'subscribeParameterUpdates' is not supported"),
            std::string::npos);
  EXPECT_EQ(frames[2].text["message"], "bad message: subscriptions: not an array");
  for (const auto& f : frames) EXPECT_EQ(f.text["level"], 2);
}

TEST_F(FoxgloveBridgeTest, TheEventHubIsHeardOnlyWhileAClientIsConnected) {
  const auto bridge = start();
  const auto wait_for = [&](std::size_t subscribers) {
    const auto deadline = std::chrono::steady_clock::now() + 5s;
    while (hub_.subscriber_count() != subscribers && std::chrono::steady_clock::now() < deadline)
      std::this_thread::sleep_for(1ms);
    return hub_.subscriber_count();
  };
  EXPECT_EQ(wait_for(0), 0u);
  {
    Connection client(bridge->connect());
    EXPECT_EQ(wait_for(1), 1u);
  }
  EXPECT_EQ(wait_for(0), 0u) << "with nobody connected the world service builds no events for the bridge";
  EXPECT_EQ(bridge->stats().clients, 0u);
}

}  // namespace
}  // namespace wm::foxglove

namespace wm::foxglove {
namespace {

// A sparse grid (two scans 60 m apart) over the cell limit is pooled tile by tile: the same cells as pooling the
// whole bounding box, at a cost that follows the tiles (two scans kilometres apart made a bounding box of 10^12).
TEST_F(FoxgloveBridgeTest, ACoarsenedGridIsTheBlockMaximumOfTheDenseGrid) {
  world_.insert(scan_at(0));
  world_.insert(scan_at(60));
  options_.max_grid_cells = 20000;
  const auto bridge = start();
  Connection client(bridge->connect());
  client.subscribe(1, kGridChannel);
  const auto frames = client.take_until([](const auto& f) { return count_for(f, 1) >= 1; });
  const auto* grid = last_for(frames, 1);
  ASSERT_NE(grid, nullptr);
  const auto bounds = *world_.grid_bounds();
  const fusion::GridGeometry region(bounds.origin_m(), bounds.resolution_m(), bounds.width(), bounds.height());
  const auto k = coarsening_factor(region.width(), region.height(), options_.max_grid_cells);
  ASSERT_GT(k, 1);
  const auto dense = world_.bayes();
  const auto [coarse, fields] = coarsened(region, {{"probability", std::vector<float>(dense.begin(), dense.end())}}, k);
  EXPECT_EQ(grid->payload["column_count"], coarse.width());
  EXPECT_EQ(grid->payload["cell_size"]["x"], coarse.resolution_m());
  EXPECT_EQ(grid->payload["data"].get<std::string>(),
            json::parse(grid_message(coarse, fields, 0))["data"].get<std::string>());
}

TEST_F(FoxgloveBridgeTest, OneClientMoreThanTheLimitIsToldSoAndClosed) {
  options_.max_clients = 2;
  const auto bridge = start();
  auto first = std::make_unique<Connection>(bridge->connect());
  Connection second(bridge->connect());
  auto endpoint = bridge->connect();
  endpoint->open([] {});
  const auto refused = endpoint->take();
  ASSERT_EQ(refused.size(), 1u);
  EXPECT_TRUE(refused[0].close_after);
  EXPECT_EQ(json::parse(refused[0].head)["message"],
            "too many Foxglove clients: this server serves 2 at once; try again later");
  endpoint->close();
  EXPECT_EQ(bridge->stats().clients, 2u);
  first.reset();  // a place is free again
  Connection third(bridge->connect());
  const auto greeting = third.take();
  ASSERT_EQ(greeting.size(), 2u);
  EXPECT_EQ(greeting[0].text["op"], "serverInfo");
}

// What a hostile client could do with one connection (found by a review): a megabyte of unknown ids or of
// subscriptions to one channel, sent without reading, must not make megabytes of replies or copies of the state.
TEST_F(FoxgloveBridgeTest, AClientThatSendsWithoutReadingGetsOneStatusPerMessageAndOneSubscriptionPerChannel) {
  world_.log(decision(1));
  const auto bridge = start();
  Connection client(bridge->connect());
  client.take_until([](const auto& f) { return f.size() >= 2; });  // serverInfo, advertise

  json ids = json::array();
  for (int i = 0; i < 50000; ++i) ids.push_back(0);
  client.send({{"op", "unsubscribe"}, {"subscriptionIds", ids}});
  auto frames = client.take();
  ASSERT_EQ(frames.size(), 1u);
  EXPECT_EQ(frames[0].text["message"],
            "unsubscribe: no subscription 0; no subscription 0; no subscription 0; and 49997 more");

  json subscriptions = json::array();
  for (std::uint32_t i = 0; i < 5000; ++i) subscriptions.push_back({{"id", i}, {"channelId", kDecisionsChannel}});
  client.send({{"op", "subscribe"}, {"subscriptions", subscriptions}});
  frames = client.take_until([](const auto& f) { return count_for(f, 0) >= 1; });
  std::this_thread::sleep_for(50ms);
  for (auto& f : client.take()) frames.push_back(std::move(f));
  EXPECT_EQ(count_for(frames, 0), 1u);  // the first subscription's current state: the one decision
  for (std::uint32_t i = 1; i < 5000; ++i) ASSERT_EQ(count_for(frames, i), 0u) << i;
  const auto statuses = std::count_if(frames.begin(), frames.end(), [](const Frame& f) { return !f.binary; });
  EXPECT_EQ(statuses, 1);
  for (const auto& f : frames) {
    if (f.binary) continue;
    EXPECT_EQ(f.text["message"], "subscribe: channel " + std::to_string(kDecisionsChannel) +
                                     " is subscribed already; channel " + std::to_string(kDecisionsChannel) +
                                     " is subscribed already; channel " + std::to_string(kDecisionsChannel) +
                                     " is subscribed already; and 4996 more");
  }

  // An unknown operation is quoted back only in part, and statuses stop queueing at a bound.
  client.send({{"op", std::string(100000, 'x')}});
  frames = client.take();
  ASSERT_EQ(frames.size(), 1u);
  EXPECT_LT(frames[0].text["message"].get<std::string>().size(), 200u);
  for (int i = 0; i < 20000; ++i) client.send({{"op", "nothing"}});
  std::size_t queued_bytes = 0;
  for (const auto& f : client.take()) queued_bytes += f.text.dump().size();
  EXPECT_GT(queued_bytes, 100000u);
  EXPECT_LE(queued_bytes, 256u << 10);
}

}  // namespace
}  // namespace wm::foxglove
