#include "server/service/world_service.h"

namespace wm::service {

WorldService::WorldService(const ServiceOptions& options, storage::Store& store, rules::Engine& engine)
    : options_(options), store_(store), engine_(engine) {
  snapshot_ = std::make_shared<const world::WorldState>(store_.load(options_.world));
  writer_ = std::thread([this] { writer_loop(); });
  // The knowledge base mirrors the committed plan; fill it before the first request is taken.
  run_on_writer([this] {
    engine_.set_floor_plan(facts(*snapshot()));
    return 0;
  });
}

WorldService::~WorldService() {
  {
    std::lock_guard lock(queue_mutex_);
    stopping_ = true;
  }
  queue_cv_.notify_all();
  writer_.join();
}

std::shared_ptr<const world::WorldState> WorldService::snapshot() const {
  std::lock_guard lock(snapshot_mutex_);
  return snapshot_;
}

void WorldService::publish(world::WorldState state) {
  auto next = std::make_shared<const world::WorldState>(std::move(state));
  std::lock_guard lock(snapshot_mutex_);
  snapshot_ = std::move(next);
}

template <typename F>
auto WorldService::run_on_writer(F&& work) -> decltype(work()) {
  using Result = decltype(work());
  auto task = std::make_shared<std::packaged_task<Result()>>(std::forward<F>(work));
  auto future = task->get_future();
  {
    std::lock_guard lock(queue_mutex_);
    if (queue_.size() >= options_.max_queued_requests) throw Busy("the world model's write queue is full; retry later");
    queue_.emplace_back([task] { (*task)(); });
  }
  queue_cv_.notify_one();
  return future.get();
}

void WorldService::writer_loop() {
  rules::ThreadAttachment prolog(engine_);
  for (;;) {
    std::function<void()> job;
    {
      std::unique_lock lock(queue_mutex_);
      queue_cv_.wait(lock, [this] { return stopping_ || !queue_.empty(); });
      if (queue_.empty()) return;  // stopping, and everything queued has run
      job = std::move(queue_.front());
      queue_.pop_front();
    }
    job();  // packaged_task keeps any exception for the waiting caller
  }
}

std::vector<rules::ObjectFacts> WorldService::facts(const world::WorldState& state) const {
  std::vector<rules::ObjectFacts> result;
  result.reserve(state.objects.size());
  for (const auto& object : state.objects) {
    rules::ObjectFacts f;
    f.id = object.plan->id;
    f.kind = object.plan->kind;
    f.attributes = object.plan->attributes;
    for (std::size_t k = 0; k < object.body.edges().size(); ++k) {
      const auto edge = world::apriori_edge(object, k, options_.world);
      f.edges.push_back({world::edge_id(f.id, k), edge.line.rho_m, edge.line.phi_rad, edge.length_m()});
    }
    result.push_back(std::move(f));
  }
  return result;
}

WorldService::PrimitivesOutcome WorldService::post_primitives(world::Observation observation, std::string payload_json) {
  return run_on_writer([this, observation = std::move(observation), payload = std::move(payload_json)] {
    const auto current = snapshot();
    const std::int64_t seq = current->last_observation_seq + 1;
    auto update = world::apply_observation(*current, observation, seq, options_.world,
                                           [this](const rules::DecisionQuery& q) { return engine_.decide(q); });
    store_.commit_observation(update, observation, payload);
    const bool moved = std::any_of(update.decisions.begin(), update.decisions.end(),
                                   [](const auto& d) { return d.action == "rigid_adjust"; });
    PrimitivesOutcome outcome{seq, update.state.version, update.decisions};
    publish(std::move(update.state));
    // Edge facts are in the world frame: a moved object must be seen where it is now by the next rule call.
    if (moved) engine_.set_floor_plan(facts(*snapshot()));
    return outcome;
  });
}

std::int64_t WorldService::load_floor_plan(apriori::FloorPlan plan) {
  return run_on_writer([this, plan = std::move(plan)] {
    const auto current = snapshot();
    auto update = world::apply_floor_plan(*current, plan, options_.world);
    auto new_facts = facts(update.state);
    store_.commit_floor_plan(update, plan);
    const auto version = update.state.version;
    publish(std::move(update.state));
    engine_.set_floor_plan(new_facts);
    return version;
  });
}

rules::RulesStatus WorldService::rules_status() {
  return run_on_writer([this] { return engine_.status(); });
}

}  // namespace wm::service
