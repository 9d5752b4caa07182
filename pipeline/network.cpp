#include "pipeline/network.h"

#include <cxxabi.h>
#include <pthread.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <future>
#include <set>
#include <sstream>

namespace wm::pipeline {

std::string type_name(const std::type_index& type) {
  int status = 0;
  std::unique_ptr<char, void (*)(void*)> demangled(abi::__cxa_demangle(type.name(), nullptr, nullptr, &status),
                                                   std::free);
  return status == 0 && demangled ? std::string(demangled.get()) : std::string(type.name());
}

double Params::number(const std::string& key, double fallback, double min, double max) const {
  const auto it = values_.find(key);
  if (it == values_.end()) return fallback;
  std::size_t used = 0;
  double value = 0;
  try {
    value = std::stod(it->second, &used);
  } catch (const std::exception&) {
    used = 0;
  }
  if (used != it->second.size() || !std::isfinite(value) || value < min || value > max) {
    std::ostringstream message;
    message << "parameter '" << key << "' must be a number in [" << min << ", " << max << "], not '" << it->second
            << "'";
    throw std::invalid_argument(message.str());
  }
  return value;
}

std::optional<std::string> Params::text(const std::string& key) const {
  const auto it = values_.find(key);
  if (it == values_.end()) return std::nullopt;
  return it->second;
}

const Registry::Factory* Registry::find(const std::string& kind) const {
  const auto it = factories_.find(kind);
  return it == factories_.end() ? nullptr : &it->second;
}

std::vector<std::string> Registry::kinds() const {
  std::vector<std::string> result;
  for (const auto& [kind, factory] : factories_) result.push_back(kind);
  return result;
}

namespace internal {

struct ExecutorState {
  std::string name;
  std::vector<Node*> nodes;
  std::mutex mutex;
  std::condition_variable cv;
  bool signalled = false;
  std::atomic<bool> idle{false};
  std::atomic<std::uint64_t> idle_at_pushes{0};
  std::atomic<std::uint64_t> cycles{0};
  std::atomic<std::int64_t> busy_ns{0};
  std::deque<std::shared_ptr<std::packaged_task<void()>>> controls;  // run between two activations (mutex)
  std::thread thread;
};

struct InputQueue {
  InputQueue(std::string component_name, const Component::Input& spec)
      : component(std::move(component_name)), name(spec.name), type(spec.type), options(spec.options) {}
  std::string component, name;
  std::type_index type;
  InputOptions options;
  ExecutorState* owner = nullptr;
  bool written = false;  // a connection ends here
  mutable std::mutex mutex;
  std::deque<std::any> values;
  std::uint64_t pushed = 0, dropped = 0, refused = 0, dropped_stopped = 0;
  std::size_t max_depth = 0;
  bool accepting = true;                  // false while its component's subtask is stopped
  std::atomic<std::uint64_t> version{0};  // values pushed so far: tells a peeking function a new value

  std::size_t depth() const {
    std::lock_guard lock(mutex);
    return values.size();
  }
  /// false when a FIFO is full and `force` is off. While its component is stopped the value is dropped (counted),
  /// and destroyed after the lock is let go (it may hold a request's answer).
  bool push(std::any value, bool force) {
    std::lock_guard lock(mutex);
    if (!accepting) {
      ++dropped_stopped;
      return true;
    }
    if (options.policy == PortPolicy::latest) {
      if (!values.empty()) {
        ++dropped;
        values.clear();
      }
    } else if (!force && values.size() >= options.capacity) {
      ++refused;
      return false;
    }
    values.push_back(std::move(value));
    ++pushed;
    ++version;
    max_depth = std::max(max_depth, values.size());
    return true;
  }
};

struct FunctionState {
  Component::Function spec;
  std::size_t priority = 0;
  std::vector<InputQueue*> consumed, peeked;
  std::vector<std::uint64_t> seen;      // per peeked port: its version at the last activation (executor thread)
  std::vector<InputQueue*> downstream;  // FIFO inputs fed by this component: the function waits for their room
  std::atomic<std::uint64_t> activations{0}, failures{0};
  std::atomic<std::int64_t> busy_ns{0}, max_ns{0};
};

struct Node {
  std::string name;
  std::string kind;
  std::unique_ptr<Component> component;
  std::vector<std::unique_ptr<InputQueue>> inputs;
  std::map<std::string, std::vector<InputQueue*>> targets;  // output → connected inputs
  std::vector<std::unique_ptr<FunctionState>> functions;    // in priority order
  ExecutorState* executor = nullptr;
  std::atomic<bool> running{true};  // false: its subtask is stopped (set on its executor's thread)
  std::string subtask;              // empty: in none
  mutable std::mutex params_mutex;
  std::map<std::string, std::string> params;  // the task file's, then the settable ones in force (params_mutex)

  InputQueue* input(const std::string& port) const {
    for (const auto& q : inputs)
      if (q->name == port) return q.get();
    return nullptr;
  }
  const Component::Output* output(const std::string& port) const {
    for (const auto& o : component->outputs())
      if (o.name == port) return &o;
    return nullptr;
  }
};

}  // namespace internal

using internal::ExecutorState;
using internal::FunctionState;
using internal::InputQueue;
using internal::Node;

std::vector<std::any>& Activation::taken(const std::string& port) {
  for (auto& [name, values] : taken_)
    if (name == port) return values;
  throw std::logic_error("function takes no port '" + port + "'");
}

const std::any& Activation::peeked(const std::string& port) const {
  for (const auto& [name, value] : peeked_)
    if (name == port) return value;
  throw std::logic_error("function peeks no port '" + port + "'");
}

void Activation::emit_any(const std::string& port, std::type_index type, std::any value) {
  network_->deliver(*node_, port, type, std::move(value));
}

namespace {

std::string fail(const TaskSpec& spec, const std::string& reason) { return spec.source + ": " + reason; }

std::string port_list(const std::vector<std::string>& ports) {
  std::string text = "{";
  for (std::size_t i = 0; i < ports.size(); ++i) text += (i ? ", " : "") + ports[i];
  return text + "}";
}

}  // namespace

Network::Network(const TaskSpec& spec, const Registry& registry, FailureReport on_failure)
    : source_(spec.source), on_failure_(std::move(on_failure)) {
  std::map<std::string, Node*> by_name;
  for (const auto& c : spec.components) {
    if (by_name.count(c.name)) throw NetworkError(fail(spec, "component '" + c.name + "' is declared twice"));
    const auto* factory = registry.find(c.kind);
    if (!factory) {
      std::string known;
      for (const auto& k : registry.kinds()) known += (known.empty() ? "" : ", ") + k;
      throw NetworkError(
          fail(spec, "component '" + c.name + "': unknown kind '" + c.kind + "' (known: " + known + ")"));
    }
    auto node = std::make_unique<Node>();
    node->name = c.name;
    node->kind = c.kind;
    try {
      node->component = (*factory)(c.params);
    } catch (const std::exception& e) {
      throw NetworkError(fail(spec, "component '" + c.name + "' (" + c.kind + "): " + e.what()));
    }
    for (const auto& input : node->component->inputs()) {
      auto queue = std::make_unique<InputQueue>(c.name, input);
      if (const auto it = c.capacities.find(input.name); it != c.capacities.end()) queue->options.capacity = it->second;
      if (const auto it = c.policies.find(input.name); it != c.policies.end()) queue->options.policy = it->second;
      if (queue->options.capacity == 0)
        throw NetworkError(fail(spec, "component '" + c.name + "': port '" + input.name + "' has capacity 0"));
      node->inputs.push_back(std::move(queue));
    }
    for (const auto& [port, capacity] : c.capacities)
      if (!node->input(port))
        throw NetworkError(fail(spec, "component '" + c.name + "' (" + c.kind + ") has no input '" + port + "'"));
    for (const auto& [port, policy] : c.policies)
      if (!node->input(port))
        throw NetworkError(fail(spec, "component '" + c.name + "' (" + c.kind + ") has no input '" + port + "'"));

    // The functions to run, and their order: more ports first; ties that share a port need a relative priority.
    std::vector<const Component::Function*> chosen;
    for (const auto& f : node->component->functions())
      if (!c.functions || std::count(c.functions->begin(), c.functions->end(), f.name)) chosen.push_back(&f);
    if (c.functions)
      for (const auto& name : *c.functions)
        if (std::none_of(node->component->functions().begin(), node->component->functions().end(),
                         [&](const auto& f) { return f.name == name; }))
          throw NetworkError(fail(spec, "component '" + c.name + "' (" + c.kind + ") has no function '" + name + "'"));
    for (const auto& name : c.priorities)
      if (std::none_of(chosen.begin(), chosen.end(), [&](const auto* f) { return f->name == name; }))
        throw NetworkError(
            fail(spec, "component '" + c.name + "': priority names '" + name + "', which is not a running function"));
    const auto subset = [](const Component::Function& f) {
      std::vector<std::string> ports = f.ports;
      ports.insert(ports.end(), f.options.peeks.begin(), f.options.peeks.end());
      std::sort(ports.begin(), ports.end());
      return ports;
    };
    // Any two functions with as many ports are ordered: by the task file's priorities, else by the kind's default.
    const auto& order = c.priorities.empty() ? node->component->default_order() : c.priorities;
    const auto rank = [&](const Component::Function& f) -> std::ptrdiff_t {
      const auto it = std::find(order.begin(), order.end(), f.name);
      return it == order.end() ? -1 : it - order.begin();
    };
    for (const auto* f : chosen) {
      const auto ports = subset(*f);
      for (std::size_t i = 1; i < ports.size(); ++i)
        if (ports[i] == ports[i - 1])
          throw NetworkError(
              fail(spec, "component '" + c.name + "': function '" + f->name + "' names port '" + ports[i] + "' twice"));
      for (const auto& port : ports)
        if (!node->input(port))
          throw NetworkError(fail(spec, "component '" + c.name + "': function '" + f->name + "' depends on '" + port +
                                            "', which is no input of " + c.kind));
      for (const auto* g : chosen) {
        if (g <= f) continue;
        const auto other = subset(*g);
        if (other == ports)
          throw NetworkError(fail(spec, "component '" + c.name + "': functions '" + f->name + "' and '" + g->name +
                                            "' both depend on " + port_list(ports)));
        std::vector<std::string> shared;
        std::set_intersection(ports.begin(), ports.end(), other.begin(), other.end(), std::back_inserter(shared));
        if (ports.size() == other.size() && (rank(*f) < 0 || rank(*g) < 0))
          throw NetworkError(fail(spec, "component '" + c.name + "': functions '" + f->name + "' and '" + g->name +
                                            "' both depend on " + std::to_string(ports.size()) + " ports" +
                                            (shared.empty() ? std::string() : " and share " + port_list(shared)) +
                                            ": give them a relative priority (priorities: [" + f->name + ", " +
                                            g->name + "] or the reverse" +
                                            (c.priorities.empty() ? "; kind " + c.kind + " has no default order" : "") +
                                            ")"));
      }
    }
    std::stable_sort(chosen.begin(), chosen.end(), [&](const auto* a, const auto* b) {
      if (a->port_count() != b->port_count()) return a->port_count() > b->port_count();
      const auto ra = rank(*a), rb = rank(*b);
      if (ra >= 0 && rb >= 0) return ra < rb;
      return false;
    });
    for (std::size_t i = 0; i < chosen.size(); ++i) {
      auto state = std::make_unique<FunctionState>();
      state->spec = *chosen[i];
      state->priority = i;
      for (const auto& port : state->spec.ports) state->consumed.push_back(node->input(port));
      for (const auto& port : state->spec.options.peeks) state->peeked.push_back(node->input(port));
      state->seen.assign(state->peeked.size(), 0);
      node->functions.push_back(std::move(state));
    }
    node->params = c.params.values();
    for (const auto& [key, value] : node->component->settable_params()) node->params.emplace(key, value);
    by_name[c.name] = node.get();
    nodes_.push_back(std::move(node));
  }

  const auto find_node = [&](const std::string& name, const std::string& where) {
    const auto it = by_name.find(name);
    if (it == by_name.end()) throw NetworkError(fail(spec, where + ": no component '" + name + "'"));
    return it->second;
  };
  for (const auto& link : spec.connections) {
    const std::string where =
        "connection " + link.from_component + "." + link.from_port + " -> " + link.to_component + "." + link.to_port;
    Node* from = find_node(link.from_component, where);
    Node* to = find_node(link.to_component, where);
    const auto* out = from->output(link.from_port);
    if (!out) throw NetworkError(fail(spec, where + ": " + from->kind + " has no output '" + link.from_port + "'"));
    InputQueue* in = to->input(link.to_port);
    if (!in) throw NetworkError(fail(spec, where + ": " + to->kind + " has no input '" + link.to_port + "'"));
    if (out->type != in->type)
      throw NetworkError(fail(spec, where + ": port type mismatch: " + link.from_component + "." + link.from_port +
                                        " carries " + type_name(out->type) + " but " + link.to_component + "." +
                                        link.to_port + " takes " + type_name(in->type)));
    auto& targets = from->targets[link.from_port];
    if (std::count(targets.begin(), targets.end(), in)) throw NetworkError(fail(spec, where + " is given twice"));
    targets.push_back(in);
    in->written = true;
  }
  for (const auto& node : nodes_) {
    for (const auto& f : node->functions) {
      for (const auto* q : f->consumed)
        if (!q->written && !q->options.external)
          throw NetworkError(fail(spec, "component '" + node->name + "': port '" + q->name + "' of function '" +
                                            f->spec.name + "' is written by nobody (connect an output to it)"));
      for (const auto* q : f->peeked)
        if (!q->written && !q->options.external)
          throw NetworkError(fail(spec, "component '" + node->name + "': port '" + q->name + "' of function '" +
                                            f->spec.name + "' is written by nobody (connect an output to it)"));
      for (const auto& [port, targets] : node->targets) {
        const auto& emits = f->spec.options.emits;
        if (emits && !std::count(emits->begin(), emits->end(), port)) continue;
        for (auto* q : targets)
          if (q->options.policy == PortPolicy::fifo) f->downstream.push_back(q);
      }
    }
    for (const auto& f : node->component->functions())
      if (f.options.emits)
        for (const auto& port : *f.options.emits)
          if (!node->output(port))
            throw NetworkError(fail(spec, "component '" + node->name + "': function '" + f.name + "' emits on '" +
                                              port + "', which is no output of " + node->kind));
    // A FIFO that receives values nobody takes would fill and stall its producers for good.
    for (const auto& q : node->inputs) {
      if (!q->written || q->options.policy != PortPolicy::fifo) continue;
      const bool taken = std::any_of(node->functions.begin(), node->functions.end(), [&](const auto& f) {
        return std::count(f->consumed.begin(), f->consumed.end(), q.get()) > 0;
      });
      if (!taken)
        throw NetworkError(fail(spec, "component '" + node->name + "': port '" + q->name +
                                          "' is connected but no running function takes its values"));
    }
  }

  if (spec.executors.size() > kMaxExecutors)
    throw NetworkError(fail(spec, "more than " + std::to_string(kMaxExecutors) + " executors (each is a thread)"));
  for (const auto& e : spec.executors) {
    if (e.components.empty()) throw NetworkError(fail(spec, "executor '" + e.name + "' runs no component"));
    auto executor = std::make_unique<ExecutorState>();
    executor->name = e.name;
    for (const auto& name : e.components) {
      Node* node = find_node(name, "executor '" + e.name + "'");
      if (node->executor)
        throw NetworkError(fail(spec, "component '" + name + "' is on two executors ('" + node->executor->name +
                                          "' and '" + e.name + "')"));
      node->executor = executor.get();
      for (auto& q : node->inputs) q->owner = executor.get();
      executor->nodes.push_back(node);
    }
    executors_.push_back(std::move(executor));
  }
  for (const auto& node : nodes_)
    if (!node->executor) throw NetworkError(fail(spec, "component '" + node->name + "' is on no executor"));

  // Subtasks: only components whose values may be lost, so a stopped one never keeps a request from its answer.
  for (const auto& t : spec.subtasks) {
    const std::string where = "subtask '" + t.name + "'";
    if (std::any_of(subtasks_.begin(), subtasks_.end(), [&](const auto& s) { return s->name == t.name; }))
      throw NetworkError(fail(spec, where + " is declared twice"));
    if (t.components.empty()) throw NetworkError(fail(spec, where + " names no component"));
    auto subtask = std::make_unique<Subtask>();
    subtask->name = t.name;
    subtask->running = t.running;
    for (const auto& name : t.components) {
      Node* node = find_node(name, where);
      if (!node->subtask.empty())
        throw NetworkError(
            fail(spec, "component '" + name + "' is in two subtasks ('" + node->subtask + "' and '" + t.name + "')"));
      for (const auto& q : node->inputs) {
        if (q->options.external)
          throw NetworkError(fail(spec, where + ": component '" + name +
                                            "' takes values from outside the network on '" + q->name +
                                            "' (the HTTP writes): it cannot be stopped"));
        if (q->written && q->options.policy == PortPolicy::fifo)
          throw NetworkError(fail(spec, where + ": component '" + name + "' takes every value on '" + q->name +
                                            "' (a fifo: requests wait for them): only components whose inputs keep "
                                            "the latest value can be stopped"));
      }
      node->subtask = t.name;
      node->running = t.running;
      for (auto& q : node->inputs) q->accepting = t.running;
      subtask->nodes.push_back(node);
    }
    subtasks_.push_back(std::move(subtask));
  }
}

Network::~Network() {
  if (started_ && !stop_now_) stop(false);
}

void Network::start() {
  if (started_) return;
  started_ = true;
  started_at_ = std::chrono::steady_clock::now();
  for (auto& executor : executors_) {
    auto* state = executor.get();
    state->thread = std::thread([this, state] { run_executor(*state); });
  }
}

StopReport Network::stop(bool drain, std::chrono::milliseconds timeout) {
  StopReport report;
  if (started_ && !stop_now_) {
    if (drain) {
      // Quiet when every executor found nothing to run since the last value moved anywhere.
      const auto deadline = std::chrono::steady_clock::now() + timeout;
      report.drained = false;
      while (std::chrono::steady_clock::now() < deadline) {
        const auto pushes = pushes_.load();
        const bool quiet = std::all_of(executors_.begin(), executors_.end(), [&](const auto& e) {
          return e->idle.load() && e->idle_at_pushes.load() == pushes;
        });
        if (quiet && pushes_.load() == pushes) {  // and nothing moved while we looked
          report.drained = true;
          break;
        }
        notify();
        std::this_thread::sleep_for(std::chrono::milliseconds(2));
      }
    } else {
      report.drained = false;
    }
    stop_now_ = true;
    notify();
    for (auto& executor : executors_)
      if (executor->thread.joinable()) executor->thread.join();
  }
  // Destroyed here, on the caller's thread: completion handles in them fire now.
  for (auto& node : nodes_)
    for (auto& q : node->inputs) {
      std::deque<std::any> left;
      {
        std::lock_guard lock(q->mutex);
        left.swap(q->values);
        q->dropped += left.size();
      }
      if (!left.empty()) report.dropped[node->name + "." + q->name] = left.size();
    }
  if (!report.dropped.empty()) report.drained = false;
  return report;
}

void Network::inject_any(const std::string& component, const std::string& port, std::type_index type, std::any value) {
  for (const auto& node : nodes_) {
    if (node->name != component) continue;
    InputQueue* q = node->input(port);
    if (!q || !q->options.external) throw std::logic_error(component + "." + port + " is no external input");
    if (q->type != type)
      throw std::logic_error(component + "." + port + " takes " + type_name(q->type) + ", not " + type_name(type));
    if (stop_now_) throw QueueFull("the processing network is stopping");
    if (!q->push(std::move(value), false))
      throw QueueFull(component + "." + port + " is full (" + std::to_string(q->options.capacity) + " waiting)");
    ++pushes_;
    wake(*q->owner);
    return;
  }
  throw std::logic_error("no component '" + component + "'");
}

void Network::deliver(Node& from, const std::string& port, std::type_index type, std::any value) {
  const auto* out = from.output(port);
  if (!out) throw std::logic_error(from.name + " has no output '" + port + "'");
  if (out->type != type)
    throw std::logic_error(from.name + "." + port + " carries " + type_name(out->type) + ", not " + type_name(type));
  const auto it = from.targets.find(port);
  if (it == from.targets.end() || it->second.empty()) {
    ++discarded_;
    return;
  }
  // Room was checked before the activation; an activation that emits several values may pass the capacity by as
  // many, which stays bounded.
  for (std::size_t i = 0; i < it->second.size(); ++i) {
    InputQueue* q = it->second[i];
    q->push(i + 1 == it->second.size() ? std::move(value) : value, true);
    ++pushes_;
    if (q->owner != from.executor) wake(*q->owner);
  }
}

bool Network::consumes(const std::string& component, const std::string& port) const {
  for (const auto& node : nodes_)
    if (node->name == component)
      for (const auto& f : node->functions)
        if (std::count(f->spec.ports.begin(), f->spec.ports.end(), port) ||
            std::count(f->spec.options.peeks.begin(), f->spec.options.peeks.end(), port))
          return true;
  return false;
}

std::size_t Network::depth(const std::string& component, const std::string& port) const {
  for (const auto& node : nodes_)
    if (node->name == component)
      if (const auto* q = node->input(port)) return q->depth();
  return 0;
}

bool Network::has_component(const std::string& component) const {
  return std::any_of(nodes_.begin(), nodes_.end(), [&](const auto& n) { return n->name == component; });
}

void Network::wake(ExecutorState& executor) {
  {
    std::lock_guard lock(executor.mutex);
    executor.signalled = true;
  }
  executor.cv.notify_one();
}

void Network::notify() {
  for (auto& executor : executors_) wake(*executor);
}

bool Network::ready(const Node& node, std::size_t function) const {
  if (!node.running) return false;
  const auto& f = *node.functions[function];
  for (const auto* q : f.consumed)
    if (q->depth() == 0) return false;
  bool unseen = false;  // a peeked value this function has not run on
  for (std::size_t i = 0; i < f.peeked.size(); ++i) {
    if (f.peeked[i]->depth() == 0) return false;
    unseen = unseen || f.peeked[i]->version != f.seen[i];
  }
  if (!f.peeked.empty() && !unseen) {
    const auto mode = f.spec.options.peek_new;
    if (mode == PeekNew::always || (mode == PeekNew::when_only_peeks && f.consumed.empty())) return false;
  }
  for (const auto* q : f.downstream)
    if (q->depth() >= q->options.capacity) return false;
  return !f.spec.options.guard || f.spec.options.guard();
}

void Network::activate(Node& node, std::size_t function) {
  auto& f = *node.functions[function];
  Activation activation;
  activation.network_ = this;
  activation.node_ = &node;
  bool made_room = false;  // producers that wait for room in a full FIFO may run now
  for (auto* q : f.consumed) {
    std::vector<std::any> values;
    {
      std::lock_guard lock(q->mutex);
      made_room = made_room || q->values.size() >= q->options.capacity;
      const std::size_t n = std::min(q->values.size(), std::max<std::size_t>(1, q->options.batch));
      for (std::size_t i = 0; i < n; ++i) {
        values.push_back(std::move(q->values.front()));
        q->values.pop_front();
      }
    }
    activation.taken_.emplace_back(q->name, std::move(values));
  }
  for (std::size_t i = 0; i < f.peeked.size(); ++i) {
    auto* q = f.peeked[i];
    std::lock_guard lock(q->mutex);
    activation.peeked_.emplace_back(q->name, q->values.front());
    f.seen[i] = q->version;
  }
  ++pushes_;  // a value moved: a stop that drains must look again
  if (made_room) notify();
  const auto begin = std::chrono::steady_clock::now();
  try {
    f.spec.body(activation);
  } catch (const std::exception& e) {
    // A function reports failures through its values (e.g. a request's answer); what escapes is a bug, logged.
    ++f.failures;
    if (on_failure_) on_failure_(node.name, f.spec.name, e.what());
  } catch (...) {
    ++f.failures;
    if (on_failure_) on_failure_(node.name, f.spec.name, "an exception that is not a std::exception");
  }
  const auto ns =
      std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::steady_clock::now() - begin).count();
  ++f.activations;
  f.busy_ns += ns;
  if (ns > f.max_ns) f.max_ns = ns;
}

void Network::run_executor(ExecutorState& executor) {
  // Named after its executor (15 characters at most), so top -H and perf show which stage is busy.
  pthread_setname_np(pthread_self(), executor.name.substr(0, 15).c_str());
  std::vector<std::shared_ptr<void>> attached;
  for (auto* node : executor.nodes)
    if (const auto& start = node->component->thread_start()) attached.push_back(start());
  const auto run_controls = [&executor] {
    std::deque<std::shared_ptr<std::packaged_task<void()>>> controls;
    {
      std::lock_guard lock(executor.mutex);
      controls.swap(executor.controls);
    }
    for (auto& control : controls) (*control)();
  };
  while (!stop_now_) {
    run_controls();
    const auto pushes_before = pushes_.load();
    bool ran = false;
    const auto begin = std::chrono::steady_clock::now();
    for (auto* node : executor.nodes)
      for (std::size_t i = 0; i < node->functions.size() && !stop_now_; ++i)
        if (ready(*node, i)) {
          activate(*node, i);
          ran = true;
        }
    ++executor.cycles;
    if (ran) {
      executor.busy_ns +=
          std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::steady_clock::now() - begin).count();
      continue;
    }
    std::unique_lock lock(executor.mutex);
    executor.idle_at_pushes = pushes_before;
    executor.idle = true;
    // Guards read state outside the ports: look again now and then even without a signal.
    executor.cv.wait_for(lock, std::chrono::milliseconds(20), [&] { return executor.signalled || stop_now_; });
    executor.signalled = false;
    executor.idle = false;
  }
  run_controls();  // none comes after this: run_on_thread looks at stop_now_ under the same mutex
  attached.clear();
}

void Network::run_on_thread(Node& node, std::function<void()> control) {
  if (!started_) {
    control();
    return;
  }
  auto task = std::make_shared<std::packaged_task<void()>>(std::move(control));
  auto done = task->get_future();
  auto& executor = *node.executor;
  {
    std::lock_guard lock(executor.mutex);
    if (stop_now_) throw QueueFull("the processing network is stopping");
    executor.controls.push_back(std::move(task));
    executor.signalled = true;
  }
  executor.cv.notify_one();
  done.get();
}

void Network::set_subtask(const std::string& name, bool running) {
  const auto it = std::find_if(subtasks_.begin(), subtasks_.end(), [&](const auto& t) { return t->name == name; });
  if (it == subtasks_.end()) throw std::out_of_range("no subtask '" + name + "' in " + source_);
  std::lock_guard control(control_mutex_);
  for (Node* node : (*it)->nodes)
    run_on_thread(*node, [node, running] {
      node->running = running;
      for (auto& q : node->inputs) {
        std::deque<std::any> left;  // destroyed after the lock: a value may hold a request's answer
        std::lock_guard lock(q->mutex);
        q->accepting = running;
        if (!running) {
          left.swap(q->values);
          q->dropped_stopped += left.size();
        }
      }
    });
  (*it)->running = running;
  notify();  // producers that waited for room in its inputs
}

void Network::set_params(const std::string& component, const std::map<std::string, std::string>& changes) {
  const auto it = std::find_if(nodes_.begin(), nodes_.end(), [&](const auto& n) { return n->name == component; });
  if (it == nodes_.end()) throw std::out_of_range("no component '" + component + "' in " + source_);
  Node& node = **it;
  const std::string who = "component '" + node.name + "' (" + node.kind + ")";
  const auto& settable = node.component->settable_params();
  std::string known;
  for (const auto& [key, value] : settable) known += (known.empty() ? "" : ", ") + key;
  if (changes.empty()) throw std::invalid_argument(who + ": no parameter given");
  for (const auto& [key, value] : changes)
    if (!settable.count(key))
      throw std::invalid_argument(
          who + ": parameter '" + key + "' cannot change while the network runs" +
          (known.empty() ? std::string(" (none of " + node.kind + "'s can)") : " (these can: " + known + ")"));
  std::lock_guard control(control_mutex_);
  std::map<std::string, std::string> merged;
  {
    std::lock_guard lock(node.params_mutex);
    merged = node.params;
  }
  for (const auto& [key, value] : changes) merged[key] = value;
  std::function<void()> apply;
  try {
    apply = node.component->prepare()(Params(merged));
  } catch (const std::invalid_argument& e) {
    throw std::invalid_argument(who + ": " + e.what());  // as the task file's error says it, without the file
  }
  run_on_thread(node, std::move(apply));
  std::lock_guard lock(node.params_mutex);
  node.params = std::move(merged);
}

NetworkStats Network::stats() const {
  NetworkStats s;
  s.source = source_;
  s.discarded = discarded_;
  for (const auto& node : nodes_) {
    ComponentStats cs;
    cs.name = node->name;
    cs.kind = node->kind;
    {
      std::lock_guard lock(node->params_mutex);
      cs.params = node->params;
    }
    for (const auto& [key, value] : node->component->settable_params()) cs.settable.push_back(key);
    if (!node->subtask.empty()) cs.subtask = node->subtask;
    cs.running = node->running;
    s.components.push_back(std::move(cs));
    for (const auto& q : node->inputs) {
      std::lock_guard lock(q->mutex);
      s.ports.push_back({node->name, q->name, type_name(q->type), q->options.policy, q->options.capacity,
                         q->values.size(), q->max_depth, q->pushed, q->dropped, q->refused, q->dropped_stopped});
    }
    for (const auto& f : node->functions)
      s.functions.push_back({node->name, f->spec.name, f->spec.ports, f->spec.options.peeks, f->priority,
                             f->activations, f->failures, f->busy_ns * 1e-9, f->max_ns * 1e-9});
    for (const auto& [port, targets] : node->targets)
      for (const auto* q : targets)
        s.connections.push_back(node->name + "." + port + " -> " + q->component + "." + q->name);
  }
  const double wall =
      started_ ? std::chrono::duration<double>(std::chrono::steady_clock::now() - started_at_).count() : 0;
  for (const auto& t : subtasks_) {
    SubtaskStats ts{t->name, t->running, {}};
    for (const auto* node : t->nodes) ts.components.push_back(node->name);
    s.subtasks.push_back(std::move(ts));
  }
  for (const auto& e : executors_) {
    ExecutorStats es{e->name, {}, e->cycles, e->busy_ns * 1e-9, wall};
    for (const auto* node : e->nodes) es.components.push_back(node->name);
    s.executors.push_back(std::move(es));
  }
  return s;
}

}  // namespace wm::pipeline
