#pragma once

// A processing network with DisCODe's conditional activation (Stefańczyk, Kornuta, Kasprzak: "DisCODe: a component
// framework for perception"): components with typed input and output ports; each component holds partial transition
// functions, each depending on a subset of its input ports and activated only when all of them hold data; functions
// that depend on more ports go first, and any two with as many ports are ordered by a relative priority (the task
// file's, else the component kind's default); a function may read a port without consuming it (peek), and runs on
// a peeked value once; every cycle of an executor tries each function of each of its components once, in that
// order, so no function starves another. Subtasks are groups of components started and stopped while the network
// runs; a component's parameters may change while it runs, applied on its own thread.
#include <any>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstddef>
#include <cstdint>
#include <deque>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>
#include <thread>
#include <typeindex>
#include <vector>

namespace wm::pipeline {

/// A network that cannot be built as described; the message names the task file and the reason.
class NetworkError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// A value offered to a full FIFO input from outside the network: the caller should retry later.
class QueueFull : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// What an input does when a value arrives: FIFO keeps every value (bounded: a full FIFO refuses values from outside
/// and holds back the functions that feed it); keep-latest keeps only the newest (a sensor stream), counting the
/// values it replaced as dropped.
enum class PortPolicy { fifo, latest };

/// The readable name of a C++ type, for error messages and the observability endpoint.
std::string type_name(const std::type_index& type);

struct InputOptions {
  PortPolicy policy = PortPolicy::fifo;
  std::size_t capacity = 64;
  /// Written from outside the network (Network::inject), e.g. by the HTTP handlers; such a port needs no connection.
  bool external = false;
  /// A function that consumes this port takes up to this many queued values in one activation (group work, e.g. one
  /// transaction for every observation waiting); 1: one value per activation.
  std::size_t batch = 1;
};

/// When a function that peeks runs again on a value it has already seen (each input counts the values pushed into it,
/// and each function remembers the count it last saw on each port it peeks).
enum class PeekNew {
  /// A function that only peeks runs when a peeked port holds a value it has not seen; one that also consumes is
  /// triggered by its consumed values (the peeked ports need only hold a value).
  when_only_peeks,
  /// Also a function that consumes waits for a value it has not seen on one of its peeked ports.
  always,
  /// A peeked value is always new: a function that only peeks runs every cycle while its ports hold values.
  never,
};

struct FunctionOptions {
  /// Ports the function reads without consuming: they must hold data too, and count for its priority.
  std::vector<std::string> peeks;
  /// An extra condition on state outside the ports (e.g. "nothing in flight"); the function waits while it is false.
  std::function<bool()> guard;
  /// The outputs it emits on: it waits for room in the FIFO inputs they feed (nullopt: every output of its
  /// component). Naming them keeps a feedback loop (a result coming back to the component) from blocking itself.
  std::optional<std::vector<std::string>> emits;
  PeekNew peek_new = PeekNew::when_only_peeks;
};

class Activation;
class Params;
using FunctionBody = std::function<void(Activation&)>;

/// Ports and partial functions. A component kind's factory builds one and fills it in; the network wires it.
class Component {
 public:
  struct Input {
    std::string name;
    std::type_index type;
    InputOptions options;
  };
  struct Output {
    std::string name;
    std::type_index type;
  };
  struct Function {
    std::string name;
    std::vector<std::string> ports;  // consumed
    FunctionOptions options;
    FunctionBody body;
    std::size_t port_count() const { return ports.size() + options.peeks.size(); }
  };

  virtual ~Component() = default;

  template <typename T>
  Component& input(std::string name, InputOptions options = {}) {
    inputs_.push_back({std::move(name), std::type_index(typeid(T)), options});
    return *this;
  }
  template <typename T>
  Component& output(std::string name) {
    outputs_.push_back({std::move(name), std::type_index(typeid(T))});
    return *this;
  }
  Component& function(std::string name, std::vector<std::string> ports, FunctionBody body,
                      FunctionOptions options = {}) {
    functions_.push_back({std::move(name), std::move(ports), std::move(options), std::move(body)});
    return *this;
  }
  /// The kind's default relative priority of its functions, first = first: orders any two with as many ports (the
  /// task file's `priorities:` replace it).
  Component& order(std::vector<std::string> functions) {
    order_ = std::move(functions);
    return *this;
  }
  /// Parameters that may change while the network runs. `current`: their values at start, as text. `prepare`, on
  /// the caller's thread, checks the parameters as the factory did at start (the task file's with the changes on
  /// top; @throw std::invalid_argument with the factory's message) and returns what puts them in force, which runs
  /// on the component's own executor thread between two activations.
  using Prepare = std::function<std::function<void()>(const Params&)>;
  Component& settable(std::map<std::string, std::string> current, Prepare prepare) {
    settable_ = std::move(current);
    prepare_ = std::move(prepare);
    return *this;
  }
  /// Runs on each executor thread that hosts this component, before its first activation; what it returns is kept
  /// until the thread ends (e.g. a Prolog engine attached to the thread).
  Component& on_thread_start(std::function<std::shared_ptr<void>()> start) {
    thread_start_ = std::move(start);
    return *this;
  }

  const std::vector<Input>& inputs() const { return inputs_; }
  const std::vector<Output>& outputs() const { return outputs_; }
  const std::vector<Function>& functions() const { return functions_; }
  const std::function<std::shared_ptr<void>()>& thread_start() const { return thread_start_; }
  const std::vector<std::string>& default_order() const { return order_; }
  const std::map<std::string, std::string>& settable_params() const { return settable_; }
  const Prepare& prepare() const { return prepare_; }

 private:
  std::vector<Input> inputs_;
  std::vector<Output> outputs_;
  std::vector<Function> functions_;
  std::function<std::shared_ptr<void>()> thread_start_;
  std::vector<std::string> order_;
  std::map<std::string, std::string> settable_;
  Prepare prepare_;
};

/// Parameters of one component from the task file, as text.
class Params {
 public:
  Params() = default;
  explicit Params(std::map<std::string, std::string> values) : values_(std::move(values)) {}
  /// @throw std::invalid_argument when the value is not a number in [min, max].
  double number(const std::string& key, double fallback, double min, double max) const;
  std::optional<std::string> text(const std::string& key) const;
  const std::map<std::string, std::string>& values() const { return values_; }

 private:
  std::map<std::string, std::string> values_;
};

/// Component kinds by name. A factory may throw std::invalid_argument for bad parameters.
class Registry {
 public:
  using Factory = std::function<std::unique_ptr<Component>(const Params&)>;
  void add(std::string kind, Factory factory) { factories_[std::move(kind)] = std::move(factory); }
  const Factory* find(const std::string& kind) const;
  std::vector<std::string> kinds() const;

 private:
  std::map<std::string, Factory> factories_;
};

/// A network as a task file describes it.
struct TaskSpec {
  struct ComponentSpec {
    std::string name;
    std::string kind;
    Params params;
    std::optional<std::vector<std::string>> functions;  // the functions to run (nullopt: all)
    std::vector<std::string> priorities;            // relative priority among ties, first = first (empty: the kind's)
    std::map<std::string, std::size_t> capacities;  // input port → capacity
    std::map<std::string, PortPolicy> policies;     // input port → policy
  };
  struct Connection {
    std::string from_component, from_port, to_component, to_port;
  };
  struct ExecutorSpec {
    std::string name;
    std::vector<std::string> components;  // tried in this order every cycle
  };
  /// Components started and stopped together while the network runs. Only components whose inputs all keep the
  /// latest value may be in one (what a FIFO or an external input holds, a request waits for).
  struct SubtaskSpec {
    std::string name;
    std::vector<std::string> components;
    bool running = true;  // at start
  };
  std::string source = "<task>";  // the file, for error messages
  std::vector<ComponentSpec> components;
  std::vector<Connection> connections;
  std::vector<ExecutorSpec> executors;
  std::vector<SubtaskSpec> subtasks;
};

/// Bounds on a task file: what a network of a few stages needs, many times over. A larger one is a mistake or an
/// attack, and would cost a thread per executor before anything runs.
inline constexpr std::size_t kMaxTaskFileBytes = std::size_t{1} << 20;
inline constexpr std::size_t kMaxComponents = 256;
inline constexpr std::size_t kMaxExecutors = 64;

/// Reads a YAML task file: a regular file of at most kMaxTaskFileBytes (a FIFO, a device or a directory is refused
/// without waiting on it). @throw NetworkError naming the file and what is wrong.
TaskSpec read_task_file(const std::string& path);
/// The same from YAML text; `source` names it in errors. Refuses more than kMaxComponents components or
/// kMaxExecutors executors, and an executor that runs no component.
TaskSpec parse_task(const std::string& yaml, const std::string& source);

struct PortStats {
  std::string component, port, type;
  PortPolicy policy = PortPolicy::fifo;
  std::size_t capacity = 0, depth = 0, max_depth = 0;
  std::uint64_t pushed = 0, dropped = 0, refused = 0;
  std::uint64_t dropped_stopped = 0;  // arrived while its component's subtask was stopped (not in `pushed`)
};
struct FunctionStats {
  std::string component, function;
  std::vector<std::string> ports, peeks;
  std::size_t priority = 0;  // 0 = tried first in its component
  std::uint64_t activations = 0, failures = 0;
  double busy_s = 0, max_s = 0;
};
struct ExecutorStats {
  std::string name;
  std::vector<std::string> components;
  std::uint64_t cycles = 0;
  double busy_s = 0, wall_s = 0;  // load = busy_s / wall_s
};
struct ComponentStats {
  std::string name, kind;
  std::map<std::string, std::string> params;  // the task file's, then the settable ones in force
  std::vector<std::string> settable;          // what PUT .../params may change
  std::optional<std::string> subtask;
  bool running = true;
};
struct SubtaskStats {
  std::string name;
  bool running = true;
  std::vector<std::string> components;
};
struct NetworkStats {
  std::string source;
  std::vector<ComponentStats> components;
  std::vector<SubtaskStats> subtasks;
  std::vector<PortStats> ports;
  std::vector<FunctionStats> functions;
  std::vector<ExecutorStats> executors;
  std::vector<std::string> connections;  // "a.out -> b.in"
  std::uint64_t discarded = 0;           // values emitted on outputs nobody reads
};

/// What stop() left behind.
struct StopReport {
  bool drained = true;                         // every function that could run did before the threads ended
  std::map<std::string, std::size_t> dropped;  // "component.port" → values left in it
};

namespace internal {
struct InputQueue;
struct Node;
struct ExecutorState;
}  // namespace internal

/// The values of one activation: taken from the function's ports, peeked, and emitted.
class Activation {
 public:
  template <typename T>
  T take(const std::string& port) {
    return std::any_cast<T>(std::move(taken(port).front()));
  }
  template <typename T>
  std::vector<T> take_all(const std::string& port) {
    std::vector<T> result;
    for (auto& value : taken(port)) result.push_back(std::any_cast<T>(std::move(value)));
    return result;
  }
  template <typename T>
  const T& peek(const std::string& port) const {
    return *std::any_cast<T>(&peeked(port));
  }
  /// Sends a copy to every input connected to `port`. @throw std::logic_error for an unknown port or a wrong type.
  template <typename T>
  void emit(const std::string& port, T value) {
    emit_any(port, std::type_index(typeid(T)), std::any(std::move(value)));
  }

 private:
  friend class Network;
  std::vector<std::any>& taken(const std::string& port);
  const std::any& peeked(const std::string& port) const;
  void emit_any(const std::string& port, std::type_index type, std::any value);

  class Network* network_ = nullptr;
  internal::Node* node_ = nullptr;
  std::vector<std::pair<std::string, std::vector<std::any>>> taken_;
  std::vector<std::pair<std::string, std::any>> peeked_;
};

/// Told of each exception that escaped a function (a bug: functions report failures through their values): the
/// component, the function and what the exception said. Called on the executor's thread; must not throw.
using FailureReport = std::function<void(std::string_view component, std::string_view function, std::string_view what)>;

/// A built network: its executors run from start() until stop(). Thread-safe.
class Network {
 public:
  /// Builds and checks the network. @throw NetworkError ("<source>: <reason>") for an unknown component kind, a
  /// port type mismatch, two functions on one subset of ports, a tie without a relative priority, a port nobody
  /// writes, a component on no executor or on two, unknown names.
  /// `on_failure` (optional) hears of each failure that FunctionStats::failures counts.
  Network(const TaskSpec& spec, const Registry& registry, FailureReport on_failure = {});
  ~Network();
  Network(const Network&) = delete;
  Network& operator=(const Network&) = delete;

  void start();
  /// Stops the executors. `drain`: first runs until no function can run anywhere (at most `timeout`); what is left
  /// in the queues is reported as dropped (and destroyed, so completion handles in it fire).
  StopReport stop(bool drain = true, std::chrono::milliseconds timeout = std::chrono::seconds(10));

  /// Offers a value to an external input. @throw QueueFull when a FIFO input is full; std::logic_error for an
  /// unknown or non-external port or a wrong type.
  template <typename T>
  void inject(const std::string& component, const std::string& port, T value) {
    inject_any(component, port, std::type_index(typeid(T)), std::any(std::move(value)));
  }
  /// Whether the component exists and one of its running functions consumes or peeks `port`.
  bool consumes(const std::string& component, const std::string& port) const;
  bool has_component(const std::string& component) const;
  /// Values waiting in an input (0 for an unknown one).
  std::size_t depth(const std::string& component, const std::string& port) const;
  /// Wakes every executor (after state that guards read changed outside the network).
  void notify();

  /// Starts or stops a subtask, on each of its components' executor threads between two activations (this call
  /// waits for them). A stopped component runs no function; what waits in its inputs is dropped, and so is what
  /// arrives there until it starts again (PortStats::dropped_stopped), so no producer waits on it.
  /// @throw std::out_of_range for an unknown subtask; QueueFull while the network stops.
  void set_subtask(const std::string& name, bool running);
  /// Changes parameters of a running component: checked on this thread as at start (@throw std::invalid_argument,
  /// nothing changed: a parameter that cannot change at run time, a bad value), put in force on its executor's
  /// thread between two activations; returns when they are. @throw std::out_of_range for an unknown component;
  /// QueueFull while the network stops.
  void set_params(const std::string& component, const std::map<std::string, std::string>& changes);

  NetworkStats stats() const;
  const std::string& source() const { return source_; }

 private:
  friend class Activation;
  void inject_any(const std::string& component, const std::string& port, std::type_index type, std::any value);
  void deliver(internal::Node& from, const std::string& port, std::type_index type, std::any value);
  void run_executor(internal::ExecutorState& executor);
  bool ready(const internal::Node& node, std::size_t function) const;
  void activate(internal::Node& node, std::size_t function);
  void wake(internal::ExecutorState& executor);
  /// Runs `control` on `node`'s executor thread between two activations (here when no thread runs) and waits.
  void run_on_thread(internal::Node& node, std::function<void()> control);

  std::string source_;
  FailureReport on_failure_;
  std::vector<std::unique_ptr<internal::Node>> nodes_;
  std::vector<std::unique_ptr<internal::ExecutorState>> executors_;
  struct Subtask {
    std::string name;
    std::vector<internal::Node*> nodes;
    std::atomic<bool> running{true};
  };
  std::vector<std::unique_ptr<Subtask>> subtasks_;
  std::mutex control_mutex_;              // one start/stop or parameter change at a time
  std::atomic<std::uint64_t> pushes_{0};  // values pushed or taken anywhere
  std::atomic<std::uint64_t> discarded_{0};
  std::atomic<bool> stop_now_{false};
  bool started_ = false;
  std::chrono::steady_clock::time_point started_at_;
};

}  // namespace wm::pipeline
