#include <algorithm>
#include <cmath>
#include <string>

#include "server/foxglove/bridge_internal.h"
#include "server/foxglove/messages.h"

// The scene, pose, transform and decision messages, and the current state a new subscription gets first.
namespace wm::foxglove {
namespace {

// Decisions read from the log per page, and pages per turn (the rest follows on the next turn).
constexpr std::size_t kDecisionPage = 1000;
constexpr int kDecisionPagesPerTurn = 10;

// Whole seconds and the fraction apart: a double of Unix seconds holds the fraction to the nanosecond, its product with
// 1e9 (about 1.7e18) only to 256 ns.
std::uint64_t unix_ns(double unix_s) {
  if (!(unix_s > 0)) return 0;
  const double whole = std::floor(unix_s);
  return static_cast<std::uint64_t>(whole) * 1'000'000'000u +
         static_cast<std::uint64_t>(std::llround((unix_s - whole) * 1e9));
}

// Frames and topics of robots: the ROS multi-robot convention (a prefix per robot), so a robot named "map" cannot
// take the map frame's name.
std::string robot_frame(const std::string& id) { return id + "/base_link"; }

}  // namespace

using internal::Payload;
using internal::share;
using internal::unix_ns_now;

void Bridge::Core::produce_scene(std::uint32_t channel) {
  const bool elements = channel == kElementsChannel;
  (elements ? elements_dirty_ : plan_dirty_) = false;
  auto& sent = elements ? elements_sent_ : plan_sent_;
  if (!has_subscribers(channel)) {
    sent.reset();  // a new subscriber starts from the whole scene anyway
    return;
  }
  const auto now = world.map.snapshot();
  if (!sent) {
    sent = now;
    return;
  }
  if (now->version == sent->version) return;
  const auto removed = world.map.removed_since(sent->version, now->version);
  const auto stamp = unix_ns_now();
  if (!removed) {  // the service no longer knows what went: the whole scene again
    sent = now;
    publish(channel, full_scene(channel), stamp);
    return;
  }
  std::vector<LineEntity> upserts;
  std::vector<std::string> deleted;
  if (elements) {
    for (const auto& [number, element] : now->elements)
      if (element.updated_version > sent->version) upserts.push_back(element_entity(element));
    deleted.assign(removed->elements.begin(), removed->elements.end());
  } else {
    for (const auto& object : now->objects)
      if (object.updated_version > sent->version) upserts.push_back(object_entity(object, world.map.world_options()));
    deleted.assign(removed->objects.begin(), removed->objects.end());
  }
  sent = now;
  if (!upserts.empty() || !deleted.empty())
    publish(channel, share(scene_update_message(upserts, deleted, false, stamp)), stamp);
}

// The whole scene of the snapshot the topic's updates go from, made once per version.
Payload Bridge::Core::full_scene(std::uint32_t channel) {
  const bool elements = channel == kElementsChannel;
  const auto& state = elements ? elements_sent_ : plan_sent_;
  auto& cache = elements ? elements_full_ : plan_full_;
  if (cache.second && cache.first == state->version) return cache.second;
  std::vector<LineEntity> entities;
  if (elements) {
    entities.reserve(state->elements.size());
    for (const auto& [number, element] : state->elements) entities.push_back(element_entity(element));
  } else {
    for (const auto& object : state->objects) entities.push_back(object_entity(object, world.map.world_options()));
  }
  cache = {state->version, share(scene_update_message(entities, {}, true, unix_ns_now()))};
  return cache.second;
}

std::uint32_t Bridge::Core::robot_channel(const std::string& id) {
  if (const auto it = robot_channels_.find(id); it != robot_channels_.end()) return it->second;
  std::lock_guard lock(clients_mutex);
  const auto channel_id = static_cast<std::uint32_t>(kFirstRobotChannel + robot_channels_.size());
  Channel channel{channel_id, "/robots/" + id + "/pose", "foxglove.PoseInFrame", schemas::pose_in_frame()};
  channels.push_back(channel);
  const auto advertise = advertise_json({channel});
  for (const auto& c : clients)
    if (auto client = c.lock()) client->push_text(advertise);
  robot_channels_.emplace(id, channel_id);
  return channel_id;
}

void Bridge::Core::produce_robots() {
  robots_dirty_ = false;
  std::vector<PlanarTransform> transforms;
  bool moved = false;
  for (const auto& robot : world.robots.robots()) {
    if (!robot.pose) continue;
    const auto& pose = *robot.pose;
    const auto channel = robot_channel(robot.id);  // advertised even before anyone subscribes to it
    const auto stamp = unix_ns(pose.received_at_unix_s);
    transforms.push_back({std::string(kMapFrame), robot_frame(robot.id), pose.x, pose.y, pose.theta, stamp});
    const SentPose now{pose.x, pose.y, pose.theta, pose.received_at_unix_s};
    auto& last = robots_sent_[robot.id];
    if (last.received_at == now.received_at && last.x == now.x && last.y == now.y && last.theta == now.theta) continue;
    last = now;
    moved = true;
    publish(channel, share(pose_in_frame_message(pose.x, pose.y, pose.theta, stamp)), stamp);
  }
  // Every robot's transform in each message: a message is the whole tree, so a newer one may replace a queued one.
  if (moved) publish(kTfChannel, share(frame_transforms_message(transforms)), unix_ns_now());
}

void Bridge::Core::produce_decisions() {
  decisions_dirty_ = false;
  if (!has_subscribers(kDecisionsChannel)) {
    decision_cursor_ = world.map.snapshot()->last_decision_seq;
    return;
  }
  for (int page = 0; page < kDecisionPagesPerTurn; ++page) {
    const auto rows = world.map.decisions(decision_cursor_, kDecisionPage, std::nullopt);
    for (const auto& d : rows) {
      const auto stamp = unix_ns_now();
      publish(kDecisionsChannel, share(log_message(d, stamp)), stamp);
      decision_cursor_ = d.seq;
    }
    if (rows.size() < kDecisionPage) return;
  }
  decisions_dirty_ = true;  // more than a turn's worth: the rest next period
}

void Bridge::Core::serve(const InitialRequest& request) {
  const auto client = request.client.lock();
  if (!client) return;
  std::vector<Payload> payloads;
  const auto stamp = unix_ns_now();
  switch (request.channel) {
    case kGridChannel:
    case kGridDsChannel: {
      auto& cache = request.channel == kGridChannel ? grid_cache_ : ds_cache_;
      // The cache is current unless a scan came since it was made: then the grid is read afresh, once per pass of
      // the bridge's loop whatever the number of new subscriptions (each build can take tens of milliseconds).
      auto& built_pass = request.channel == kGridChannel ? grid_built_pass_ : ds_built_pass_;
      if (!cache.payload || (grid_dirty_ && built_pass != pass_)) {
        if (auto built = build_grid(request.channel)) cache = std::move(*built);
        built_pass = pass_;
      }
      if (cache.payload) payloads.push_back(cache.payload);
      break;
    }
    case kElementsChannel:
    case kPlanChannel: {
      // Bring the topic's other subscribers to now first, so that this one's whole scene and their changes start
      // from the same snapshot.
      auto& sent = request.channel == kElementsChannel ? elements_sent_ : plan_sent_;
      if (sent) produce_scene(request.channel);
      if (!sent) sent = world.map.snapshot();
      payloads.push_back(full_scene(request.channel));
      break;
    }
    case kTfChannel: {
      std::vector<PlanarTransform> all;
      for (const auto& robot : world.robots.robots())
        if (robot.pose)
          all.push_back({std::string(kMapFrame), robot_frame(robot.id), robot.pose->x, robot.pose->y, robot.pose->theta,
                         unix_ns(robot.pose->received_at_unix_s)});
      if (!all.empty()) payloads.push_back(share(frame_transforms_message(all)));
      break;
    }
    case kDecisionsChannel: {
      if (has_subscribers(kDecisionsChannel))
        produce_decisions();  // the others first, as for the scenes
      else
        decision_cursor_ = world.map.snapshot()->last_decision_seq;
      const auto since =
          std::max<std::int64_t>(0, decision_cursor_ - static_cast<std::int64_t>(options.initial_decisions));
      for (const auto& d : world.map.decisions(since, options.initial_decisions, std::nullopt))
        if (d.seq <= decision_cursor_) payloads.push_back(share(log_message(d, stamp)));
      break;
    }
    default: {
      for (const auto& [id, channel] : robot_channels_)
        if (channel == request.channel)
          if (const auto robot = world.robots.robot(id); robot && robot->pose)
            payloads.push_back(share(pose_in_frame_message(robot->pose->x, robot->pose->y, robot->pose->theta,
                                                           unix_ns(robot->pose->received_at_unix_s))));
      break;
    }
  }
  client->push_initial(request.subscription, request.channel, payloads, stamp);
}

}  // namespace wm::foxglove
