#include "pipeline/network.h"

#include <gtest/gtest.h>

#include <future>
#include <stdexcept>
#include <string>
#include <vector>

namespace wm::pipeline {
namespace {

// What every activation did, in order, from any thread.
struct Trace {
  std::mutex mutex;
  std::vector<std::string> events;
  void add(std::string event) {
    std::lock_guard lock(mutex);
    events.push_back(std::move(event));
  }
  std::vector<std::string> copy() {
    std::lock_guard lock(mutex);
    return events;
  }
};

bool wait_for(const std::function<bool()>& done) {
  for (int i = 0; i < 2000; ++i) {
    if (done()) return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  return done();
}

// A sink with three functions on ports a and b: both, a alone, b alone (DisCODe's laser+sonar, laser, sonar).
std::unique_ptr<Component> sink(Trace& trace) {
  auto c = std::make_unique<Component>();
  c->input<int>("a", {PortPolicy::fifo, 16, true}).input<int>("b", {PortPolicy::fifo, 16, true});
  c->function("a_only", {"a"}, [&trace](Activation& x) { trace.add("a_only:" + std::to_string(x.take<int>("a"))); });
  c->function("both", {"a", "b"}, [&trace](Activation& x) {
    const int a = x.take<int>("a"), b = x.take<int>("b");
    trace.add("both:" + std::to_string(a) + "+" + std::to_string(b));
  });
  c->function("b_only", {"b"}, [&trace](Activation& x) { trace.add("b_only:" + std::to_string(x.take<int>("b"))); });
  c->order({"a_only", "b_only"});
  return c;
}

TaskSpec one(const std::string& kind, std::vector<std::string> priorities = {}) {
  TaskSpec spec;
  spec.source = "test.yaml";
  spec.components.push_back({"s", kind, {}, std::nullopt, std::move(priorities), {}, {}});
  spec.executors.push_back({"main", {"s"}});
  return spec;
}

TEST(NetworkTest, FunctionsThatDependOnMorePortsGoFirst) {
  Trace trace;
  Registry registry;
  registry.add("sink", [&](const Params&) { return sink(trace); });
  Network network(one("sink"), registry);
  const auto stats = network.stats();
  ASSERT_EQ(stats.functions.size(), 3u);
  EXPECT_EQ(stats.functions[0].function, "both");  // two ports
  EXPECT_EQ(stats.functions[0].priority, 0u);
  // Data on both ports before the executor starts: the two-port function takes them together.
  network.inject("s", "a", 1);
  network.inject("s", "b", 2);
  network.inject("s", "a", 3);
  network.start();
  ASSERT_TRUE(wait_for([&] { return trace.copy().size() == 2; }));
  network.stop();
  EXPECT_EQ(trace.copy(), (std::vector<std::string>{"both:1+2", "a_only:3"}));
}

// An exception that escapes a function is counted and told to the failure report with where it came from; the
// network goes on with the next value.
TEST(NetworkTest, AFunctionThatThrowsIsCountedAndReportedAndTheNetworkGoesOn) {
  Trace trace;
  Registry registry;
  registry.add("fragile", [&](const Params&) {
    auto c = std::make_unique<Component>();
    c->input<int>("a", {PortPolicy::fifo, 16, true});
    c->function("check", {"a"}, [&trace](Activation& x) {
      const int a = x.take<int>("a");
      if (a < 0) throw std::runtime_error("negative: " + std::to_string(a));
      trace.add("ok:" + std::to_string(a));
    });
    return c;
  });
  std::mutex mutex;
  std::vector<std::string> reports;
  Network network(one("fragile"), registry,
                  [&](std::string_view component, std::string_view function, std::string_view what) {
                    std::lock_guard lock(mutex);
                    reports.push_back(std::string(component) + "." + std::string(function) + ": " + std::string(what));
                  });
  for (const int a : {1, -2, 3}) network.inject("s", "a", a);
  network.start();
  ASSERT_TRUE(wait_for([&] { return trace.copy().size() == 2; }));
  network.stop();
  EXPECT_EQ(trace.copy(), (std::vector<std::string>{"ok:1", "ok:3"}));
  EXPECT_EQ(network.stats().functions.at(0).failures, 1u);
  std::lock_guard lock(mutex);
  EXPECT_EQ(reports, (std::vector<std::string>{"s.check: negative: -2"}));
}

TEST(NetworkTest, EachFunctionRunsOncePerCycle) {
  // A fast stream on `a` cannot starve `b`: every cycle tries each function once, so they alternate.
  Trace trace;
  Registry registry;
  registry.add("split", [&](const Params&) {
    auto c = std::make_unique<Component>();
    c->input<int>("a", {PortPolicy::fifo, 16, true}).input<int>("b", {PortPolicy::fifo, 16, true});
    c->function("fa", {"a"}, [&](Activation& x) { trace.add("a" + std::to_string(x.take<int>("a"))); });
    c->function("fb", {"b"}, [&](Activation& x) { trace.add("b" + std::to_string(x.take<int>("b"))); });
    c->order({"fa", "fb"});
    return c;
  });
  Network network(one("split"), registry);
  for (int i = 0; i < 4; ++i) network.inject("s", "a", i);
  for (int i = 0; i < 2; ++i) network.inject("s", "b", i);
  network.start();
  ASSERT_TRUE(wait_for([&] { return trace.copy().size() == 6; }));
  network.stop();
  EXPECT_EQ(trace.copy(), (std::vector<std::string>{"a0", "b0", "a1", "b1", "a2", "a3"}));
  const auto stats = network.stats();
  EXPECT_EQ(stats.functions[0].activations + stats.functions[1].activations, 6u);
  EXPECT_GE(stats.executors.at(0).cycles, 4u);
}

TEST(NetworkTest, PeekReadsWithoutConsuming) {
  Trace trace;
  Registry registry;
  registry.add("peeker", [&](const Params&) {
    auto c = std::make_unique<Component>();
    c->input<int>("data", {PortPolicy::fifo, 16, true}).input<std::string>("mode", {PortPolicy::latest, 1, true});
    c->function("process", {"data"},
                [&](Activation& x) { trace.add(x.peek<std::string>("mode") + std::to_string(x.take<int>("data"))); },
                {{"mode"}, {}, std::nullopt});
    return c;
  });
  Network network(one("peeker"), registry);
  network.inject("s", "data", 1);
  network.start();
  std::this_thread::sleep_for(std::chrono::milliseconds(50));
  EXPECT_TRUE(trace.copy().empty()) << "ran without the peeked port";
  network.inject<std::string>("s", "mode", "x");
  network.inject("s", "data", 2);
  ASSERT_TRUE(wait_for([&] { return trace.copy().size() == 2; }));
  network.inject<std::string>("s", "mode", "y");  // keep-latest: replaces x
  network.inject("s", "data", 3);
  ASSERT_TRUE(wait_for([&] { return trace.copy().size() == 3; }));
  for (const auto& p : network.stats().ports) {
    if (p.port == "mode") {
      EXPECT_EQ(p.depth, 1u);  // still there: never consumed
    }
  }
  network.stop();
  EXPECT_EQ(trace.copy(), (std::vector<std::string>{"x1", "x2", "y3"}));
}

TEST(NetworkTest, KeepLatestDropsOlderValues) {
  Trace trace;
  Registry registry;
  registry.add("sink", [&](const Params&) { return sink(trace); });
  auto spec = one("sink");
  spec.components[0].policies["a"] = PortPolicy::latest;
  spec.components[0].functions = std::vector<std::string>{"a_only"};
  Network network(spec, registry);
  for (int i = 0; i < 5; ++i) network.inject("s", "a", i);
  network.start();
  ASSERT_TRUE(wait_for([&] { return trace.copy().size() == 1; }));
  network.stop();
  EXPECT_EQ(trace.copy(), (std::vector<std::string>{"a_only:4"}));
  EXPECT_EQ(network.stats().ports.at(0).dropped, 4u);
}

TEST(NetworkTest, FullFifoRefusesFromOutsideAndHoldsBackItsProducer) {
  Registry registry;
  std::promise<void> release;
  auto released = release.get_future().share();
  registry.add("source", [&](const Params&) {
    auto c = std::make_unique<Component>();
    c->input<int>("in", {PortPolicy::fifo, 100, true}).output<int>("out");
    c->function("forward", {"in"}, [](Activation& x) { x.emit("out", x.take<int>("in")); });
    return c;
  });
  registry.add("slow", [&](const Params&) {
    auto c = std::make_unique<Component>();
    c->input<int>("in", {PortPolicy::fifo, 2, false});
    c->function("work", {"in"}, [released](Activation& x) {
      x.take<int>("in");
      released.wait();
    });
    return c;
  });
  TaskSpec spec;
  spec.source = "test.yaml";
  spec.components.push_back({"src", "source", {}, std::nullopt, {}, {}, {}});
  spec.components.push_back({"dst", "slow", {}, std::nullopt, {}, {}, {}});
  spec.connections.push_back({"src", "out", "dst", "in"});
  spec.executors.push_back({"one", {"src"}});
  spec.executors.push_back({"two", {"dst"}});
  Network network(spec, registry);
  network.start();
  for (int i = 0; i < 10; ++i) network.inject("src", "in", i);
  // dst holds one in its function and 2 queued; the source waits for room with the other 7.
  ASSERT_TRUE(wait_for([&] {
    for (const auto& p : network.stats().ports)
      if (p.component == "src" && p.depth == 7) return true;
    return false;
  }));
  std::this_thread::sleep_for(std::chrono::milliseconds(30));
  for (const auto& p : network.stats().ports) {
    if (p.component == "dst") {
      EXPECT_LE(p.depth, 2u);
    }
  }
  release.set_value();
  const auto report = network.stop(true);
  EXPECT_TRUE(report.drained);
  EXPECT_TRUE(report.dropped.empty());
}

TEST(NetworkTest, ExternalFifoRefusesWhenFull) {
  Trace trace;
  Registry registry;
  registry.add("sink", [&](const Params&) { return sink(trace); });
  auto spec = one("sink");
  spec.components[0].capacities["a"] = 2;
  Network network(spec, registry);  // not started: nothing consumes
  network.inject("s", "a", 1);
  network.inject("s", "a", 2);
  EXPECT_THROW(network.inject("s", "a", 3), QueueFull);
  EXPECT_EQ(network.stats().ports.at(0).refused, 1u);
  EXPECT_THROW(network.inject<std::string>("s", "a", "x"), std::logic_error);  // wrong type
}

TEST(NetworkTest, StopDrainsAcrossExecutorsOrReportsWhatIsLeft) {
  Trace trace;
  Registry registry;
  registry.add("relay", [&](const Params&) {
    auto c = std::make_unique<Component>();
    c->input<int>("in", {PortPolicy::fifo, 1000, true}).output<int>("out");
    c->function("relay", {"in"}, [](Activation& x) { x.emit("out", x.take<int>("in") + 1); });
    return c;
  });
  registry.add("sink", [&](const Params&) { return sink(trace); });
  TaskSpec spec;
  spec.source = "test.yaml";
  spec.components.push_back({"r", "relay", {}, std::nullopt, {}, {}, {}});
  spec.components.push_back({"s", "sink", {}, std::vector<std::string>{"a_only"}, {}, {{"a", 1000}}, {}});
  spec.connections.push_back({"r", "out", "s", "a"});
  spec.executors.push_back({"first", {"r"}});
  spec.executors.push_back({"second", {"s"}});
  {
    Network network(spec, registry);
    network.start();
    for (int i = 0; i < 200; ++i) network.inject("r", "in", i);
    const auto report = network.stop(true);
    EXPECT_TRUE(report.drained);
    EXPECT_EQ(trace.copy().size(), 200u);  // every value went through both executors
  }
  {
    // b has no running function: what waits there is reported, and the threads still end.
    Network network(spec, registry);
    network.start();
    network.inject("s", "b", 7);
    network.inject("s", "b", 8);
    const auto report = network.stop(true);
    EXPECT_FALSE(report.drained);
    EXPECT_EQ(report.dropped.at("s.b"), 2u);
  }
}

TEST(NetworkTest, GuardsHoldAFunctionBack) {
  Trace trace;
  std::atomic<bool> open{false};
  Registry registry;
  registry.add("gated", [&](const Params&) {
    auto c = std::make_unique<Component>();
    c->input<int>("in", {PortPolicy::fifo, 8, true});
    c->function("run", {"in"}, [&](Activation& x) { trace.add(std::to_string(x.take<int>("in"))); },
                {{}, [&] { return open.load(); }, std::nullopt});
    return c;
  });
  Network network(one("gated"), registry);
  network.start();
  network.inject("s", "in", 1);
  std::this_thread::sleep_for(std::chrono::milliseconds(40));
  EXPECT_TRUE(trace.copy().empty());
  open = true;
  network.notify();
  ASSERT_TRUE(wait_for([&] { return trace.copy().size() == 1; }));
  network.stop();
}

TEST(NetworkTest, ThreadStartRunsOnTheExecutorThread) {
  std::promise<std::thread::id> started;
  std::promise<std::thread::id> ran;
  Registry registry;
  registry.add("k", [&](const Params&) {
    auto c = std::make_unique<Component>();
    c->input<int>("in", {PortPolicy::fifo, 8, true});
    c->function("f", {"in"}, [&](Activation& x) {
      x.take<int>("in");
      ran.set_value(std::this_thread::get_id());
    });
    c->on_thread_start([&] {
      started.set_value(std::this_thread::get_id());
      return std::shared_ptr<void>();
    });
    return c;
  });
  Network network(one("k"), registry);
  network.start();
  network.inject("s", "in", 1);
  const auto a = started.get_future().get(), b = ran.get_future().get();
  EXPECT_EQ(a, b);
  EXPECT_NE(a, std::this_thread::get_id());
  network.stop();
}

// --- errors in a task file, each refused with the file and its reason ---

std::string build_error(const TaskSpec& spec, const Registry& registry) {
  try {
    Network network(spec, registry);
  } catch (const NetworkError& e) {
    return e.what();
  }
  return "";
}

TEST(NetworkErrorsTest, UnknownComponentKind) {
  Registry registry;
  registry.add("sink", [](const Params&) { return std::make_unique<Component>(); });
  const auto error = build_error(one("sonar_grid"), registry);
  EXPECT_NE(error.find("test.yaml: component 's': unknown kind 'sonar_grid' (known: sink)"), std::string::npos)
      << error;
}

TEST(NetworkErrorsTest, PortTypeMismatch) {
  Registry registry;
  registry.add("ints", [](const Params&) {
    auto c = std::make_unique<Component>();
    c->output<int>("out");
    return c;
  });
  registry.add("texts", [](const Params&) {
    auto c = std::make_unique<Component>();
    c->input<std::string>("in");
    c->function("f", {"in"}, [](Activation&) {});
    return c;
  });
  TaskSpec spec;
  spec.source = "net.yaml";
  spec.components.push_back({"x", "ints", {}, std::nullopt, {}, {}, {}});
  spec.components.push_back({"y", "texts", {}, std::nullopt, {}, {}, {}});
  spec.connections.push_back({"x", "out", "y", "in"});
  spec.executors.push_back({"e", {"x", "y"}});
  const auto error = build_error(spec, registry);
  EXPECT_NE(error.find("net.yaml: connection x.out -> y.in: port type mismatch: x.out carries int but y.in takes "
                       "std::__cxx11::basic_string"),
            std::string::npos)
      << error;
}

TEST(NetworkErrorsTest, TwoFunctionsOnOneSubset) {
  Registry registry;
  registry.add("twice", [](const Params&) {
    auto c = std::make_unique<Component>();
    c->input<int>("a", {PortPolicy::fifo, 8, true}).input<int>("b", {PortPolicy::fifo, 8, true});
    c->function("f", {"a", "b"}, [](Activation&) {});
    c->function("g", {"b"}, [](Activation&) {}, {{"a"}, {}, std::nullopt});  // peeking a counts: the same subset {a, b}
    return c;
  });
  const auto error = build_error(one("twice"), registry);
  EXPECT_NE(error.find("test.yaml: component 's': functions 'f' and 'g' both depend on {a, b}"), std::string::npos)
      << error;
}

std::unique_ptr<Component> tied() {
  auto c = std::make_unique<Component>();
  c->input<int>("a", {PortPolicy::fifo, 8, true})
      .input<int>("b", {PortPolicy::fifo, 8, true})
      .input<int>("c", {PortPolicy::fifo, 8, true});
  c->function("ab", {"a", "b"}, [](Activation&) {});
  c->function("bc", {"b", "c"}, [](Activation&) {});
  return c;
}

TEST(NetworkErrorsTest, TieRefusedWithoutARelativePriorityAndResolvedWithOne) {
  Registry registry;
  registry.add("tied", [](const Params&) { return tied(); });
  const auto error = build_error(one("tied"), registry);
  EXPECT_NE(error.find("test.yaml: component 's': functions 'ab' and 'bc' both depend on 2 ports and share {b}: give "
                       "them a relative priority"),
            std::string::npos)
      << error;
  Network resolved(one("tied", {"bc", "ab"}), registry);
  const auto stats = resolved.stats();
  EXPECT_EQ(stats.functions.at(0).function, "bc");
  EXPECT_EQ(stats.functions.at(1).function, "ab");
  // With the priority, b's one value goes to bc when both could run.
  TaskSpec spec = one("tied", {"ab", "bc"});
  Network other(spec, registry);
  EXPECT_EQ(other.stats().functions.at(0).function, "ab");
}

TEST(NetworkErrorsTest, PortNobodyWrites) {
  Registry registry;
  registry.add("reader", [](const Params&) {
    auto c = std::make_unique<Component>();
    c->input<int>("in");  // not external
    c->function("read", {"in"}, [](Activation&) {});
    return c;
  });
  const auto error = build_error(one("reader"), registry);
  EXPECT_NE(error.find("test.yaml: component 's': port 'in' of function 'read' is written by nobody"),
            std::string::npos)
      << error;
}

TEST(NetworkErrorsTest, ExecutorsAndNames) {
  Registry registry;
  registry.add("tied", [](const Params&) { return tied(); });
  auto spec = one("tied", {"ab", "bc"});
  spec.executors.push_back({"again", {"s"}});
  EXPECT_NE(build_error(spec, registry).find("component 's' is on two executors ('main' and 'again')"),
            std::string::npos);
  spec = one("tied", {"ab", "bc"});
  spec.executors.clear();
  EXPECT_NE(build_error(spec, registry).find("component 's' is on no executor"), std::string::npos);
  spec = one("tied", {"ab", "bc"});
  spec.components[0].functions = std::vector<std::string>{"ab", "zz"};
  EXPECT_NE(build_error(spec, registry).find("has no function 'zz'"), std::string::npos);
  spec = one("tied", {"ab", "bc"});
  spec.connections.push_back({"s", "out", "t", "in"});
  EXPECT_NE(build_error(spec, registry).find("connection s.out -> t.in: no component 't'"), std::string::npos);
}

TEST(NetworkErrorsTest, AnExecutorWithoutComponentsOrTooManyExecutorsAreRefused) {
  Registry registry;
  registry.add("tied", [](const Params&) { return tied(); });
  auto spec = one("tied", {"ab", "bc"});
  spec.executors.push_back({"idle", {}});
  EXPECT_NE(build_error(spec, registry).find("test.yaml: executor 'idle' runs no component"), std::string::npos);
  spec = one("tied", {"ab", "bc"});
  for (std::size_t i = 0; i < kMaxExecutors; ++i) spec.executors.push_back({"e" + std::to_string(i), {"s"}});
  EXPECT_NE(build_error(spec, registry).find("more than 64 executors"), std::string::npos);
}

TEST(NetworkErrorsTest, DisablingAFunctionRemovesItsTie) {
  Registry registry;
  registry.add("tied", [](const Params&) { return tied(); });
  auto spec = one("tied");
  spec.components[0].functions = std::vector<std::string>{"ab"};
  Network network(spec, registry);
  EXPECT_TRUE(network.consumes("s", "a"));
  EXPECT_FALSE(network.consumes("s", "c"));
}

// --- the paper's tie rule: any two functions with as many ports are ordered ---

std::unique_ptr<Component> apart(bool with_default) {
  auto c = std::make_unique<Component>();
  c->input<int>("a", {PortPolicy::fifo, 8, true}).input<int>("b", {PortPolicy::fifo, 8, true});
  c->function("fa", {"a"}, [](Activation& x) { x.take<int>("a"); });
  c->function("fb", {"b"}, [](Activation& x) { x.take<int>("b"); });
  if (with_default) c->order({"fb", "fa"});
  return c;
}

TEST(NetworkErrorsTest, TiesWithoutASharedPortNeedAnOrderToo) {
  Registry registry;
  registry.add("bare", [](const Params&) { return apart(false); });
  registry.add("ordered", [](const Params&) { return apart(true); });
  const auto error = build_error(one("bare"), registry);
  EXPECT_NE(error.find("test.yaml: component 's': functions 'fa' and 'fb' both depend on 1 ports: give them a "
                       "relative priority (priorities: [fa, fb] or the reverse; kind bare has no default order)"),
            std::string::npos)
      << error;
  // The kind's default order settles it; the task file's priorities replace it.
  Network by_default(one("ordered"), registry);
  EXPECT_EQ(by_default.stats().functions.at(0).function, "fb");
  Network by_task(one("ordered", {"fa", "fb"}), registry);
  EXPECT_EQ(by_task.stats().functions.at(0).function, "fa");
  // A task file's priorities that leave a tie out are refused even when the kind has a default.
  registry.add("three", [](const Params&) {
    auto c = apart(true);
    c->input<int>("c", {PortPolicy::fifo, 8, true});
    c->function("fc", {"c"}, [](Activation& x) { x.take<int>("c"); });
    c->order({"fc", "fb", "fa"});
    return c;
  });
  EXPECT_NE(build_error(one("three", {"fa", "fb"}), registry)
                .find("functions 'fa' and 'fc' both depend on 1 ports: give them a relative priority"),
            std::string::npos);
}

// --- peeking: a value is new data once ---

TEST(NetworkTest, AFunctionThatOnlyPeeksRunsOncePerNewValue) {
  Trace trace;
  std::atomic<int> polls{0};
  Registry registry;
  registry.add("watch", [&](const Params&) {
    auto c = std::make_unique<Component>();
    c->input<int>("setting", {PortPolicy::latest, 1, true}).input<int>("other", {PortPolicy::latest, 1, true});
    c->function("watch", {}, [&](Activation& x) { trace.add("saw " + std::to_string(x.peek<int>("setting"))); },
                {{"setting"}, {}, std::nullopt});
    c->function("poll", {}, [&](Activation&) { ++polls; }, {{"other"}, {}, std::nullopt, PeekNew::never});
    c->order({"watch", "poll"});
    return c;
  });
  Network network(one("watch"), registry);
  network.start();
  network.inject("s", "setting", 1);
  ASSERT_TRUE(wait_for([&] { return trace.copy().size() == 1; }));
  std::this_thread::sleep_for(std::chrono::milliseconds(60));  // many cycles: the old value does not count again
  EXPECT_EQ(trace.copy().size(), 1u);
  network.inject("s", "setting", 2);
  ASSERT_TRUE(wait_for([&] { return trace.copy().size() == 2; }));
  network.inject("s", "setting", 2);  // the same value pushed again is a new value
  ASSERT_TRUE(wait_for([&] { return trace.copy().size() == 3; }));
  // PeekNew::never: a poll, every cycle while its port holds a value.
  network.inject("s", "other", 0);
  ASSERT_TRUE(wait_for([&] { return polls.load() > 20; }));
  network.stop(false);
  EXPECT_EQ(trace.copy(), (std::vector<std::string>{"saw 1", "saw 2", "saw 2"}));
  for (const auto& f : network.stats().functions)
    if (f.function == "watch") {
      EXPECT_EQ(f.activations, 3u);
    }
}

TEST(NetworkTest, PeekNewAlwaysHoldsAConsumerBackUntilThePeekedValueIsNew) {
  Trace trace;
  Registry registry;
  registry.add("gate", [&](const Params&) {
    auto c = std::make_unique<Component>();
    c->input<int>("data", {PortPolicy::fifo, 16, true}).input<int>("key", {PortPolicy::latest, 1, true});
    c->function("pair", {"data"},
                [&](Activation& x) {
                  trace.add(std::to_string(x.peek<int>("key")) + ":" + std::to_string(x.take<int>("data")));
                },
                {{"key"}, {}, std::nullopt, PeekNew::always});
    return c;
  });
  Network network(one("gate"), registry);
  network.inject("s", "data", 1);
  network.inject("s", "data", 2);
  network.inject("s", "key", 10);
  network.start();
  ASSERT_TRUE(wait_for([&] { return trace.copy().size() == 1; }));
  std::this_thread::sleep_for(std::chrono::milliseconds(50));
  EXPECT_EQ(trace.copy().size(), 1u) << "ran again on a key it had seen";
  network.inject("s", "key", 11);
  ASSERT_TRUE(wait_for([&] { return trace.copy().size() == 2; }));
  network.stop(false);
  EXPECT_EQ(trace.copy(), (std::vector<std::string>{"10:1", "11:2"}));
}

// --- subtasks and parameters while the network runs ---

// A source that forwards every value to a ticked worker (keep-latest input) in a subtask; the worker's `scale`
// parameter may change at run time.
Registry subtask_registry(Trace& trace, std::atomic<std::thread::id>& applied_on) {
  Registry registry;
  registry.add("source", [](const Params&) {
    auto c = std::make_unique<Component>();
    c->input<int>("in", {PortPolicy::fifo, 1000, true}).output<int>("out");
    c->function("forward", {"in"}, [](Activation& x) { x.emit("out", x.take<int>("in")); });
    return c;
  });
  registry.add("worker", [&trace, &applied_on](const Params& params) {
    const auto read = [](const Params& p) { return static_cast<int>(p.number("scale", 1, 1, 100)); };
    auto scale = std::make_shared<int>(read(params));
    auto c = std::make_unique<Component>();
    c->input<int>("tick", {PortPolicy::latest, 1, false});
    c->function("work", {"tick"},
                [&trace, scale](Activation& x) { trace.add(std::to_string(x.take<int>("tick") * *scale)); });
    c->settable({{"scale", std::to_string(*scale)}}, [read, scale, &applied_on](const Params& p) {
      const int value = read(p);
      return std::function<void()>([scale, value, &applied_on] {
        *scale = value;
        applied_on = std::this_thread::get_id();
      });
    });
    return c;
  });
  return registry;
}

TaskSpec subtask_spec(bool running) {
  TaskSpec spec;
  spec.source = "sub.yaml";
  spec.components.push_back({"src", "source", {}, std::nullopt, {}, {}, {}});
  spec.components.push_back({"w", "worker", {}, std::nullopt, {}, {}, {}});
  spec.connections.push_back({"src", "out", "w", "tick"});
  spec.executors.push_back({"one", {"src"}});
  spec.executors.push_back({"two", {"w"}});
  spec.subtasks.push_back({"work", {"w"}, running});
  return spec;
}

int port_count(const Network& network, const std::string& port, std::uint64_t PortStats::*field) {
  for (const auto& p : network.stats().ports)
    if (p.port == port) return static_cast<int>(p.*field);
  return -1;
}

TEST(NetworkTest, AStoppedSubtaskRunsNothingAndDropsWhatArrivesWithoutHoldingItsProducers) {
  Trace trace;
  std::atomic<std::thread::id> applied_on;
  const auto registry = subtask_registry(trace, applied_on);
  Network network(subtask_spec(false), registry);
  auto stats = network.stats();
  ASSERT_EQ(stats.subtasks.size(), 1u);
  EXPECT_FALSE(stats.subtasks[0].running);
  EXPECT_EQ(stats.subtasks[0].components, std::vector<std::string>{"w"});
  network.start();
  for (int i = 1; i <= 50; ++i) network.inject("src", "in", i);
  ASSERT_TRUE(wait_for([&] { return port_count(network, "tick", &PortStats::dropped_stopped) == 50; }));
  EXPECT_EQ(network.depth("src", "in"), 0u) << "the producer went on";
  EXPECT_TRUE(trace.copy().empty());

  network.set_subtask("work", true);
  network.inject("src", "in", 7);
  ASSERT_TRUE(wait_for([&] { return trace.copy().size() == 1; }));
  EXPECT_EQ(trace.copy().back(), "7");
  network.set_subtask("work", false);
  for (int i = 0; i < 5; ++i) network.inject("src", "in", 8);
  ASSERT_TRUE(wait_for([&] { return port_count(network, "tick", &PortStats::dropped_stopped) == 55; }));
  EXPECT_EQ(trace.copy().size(), 1u);
  stats = network.stats();
  EXPECT_FALSE(stats.components.at(1).running);
  EXPECT_EQ(stats.components.at(1).subtask, std::optional<std::string>("work"));
  EXPECT_THROW(network.set_subtask("nothing", true), std::out_of_range);
  EXPECT_TRUE(network.stop().drained);
}

TEST(NetworkTest, ParametersChangeOnTheComponentsThreadAfterTheSameCheckAsAtStart) {
  Trace trace;
  std::atomic<std::thread::id> applied_on;
  const auto registry = subtask_registry(trace, applied_on);
  Network network(subtask_spec(true), registry);
  network.start();
  EXPECT_EQ(network.stats().components.at(1).params.at("scale"), "1");
  network.set_params("w", {{"scale", "3"}});
  EXPECT_NE(applied_on.load(), std::this_thread::get_id());
  EXPECT_NE(applied_on.load(), std::thread::id());
  network.inject("src", "in", 5);
  ASSERT_TRUE(wait_for([&] { return trace.copy().size() == 1; }));
  EXPECT_EQ(trace.copy().back(), "15");
  // The factory's own message; nothing changes.
  for (const std::string bad : {"0", "nan", "3x", "", "1e999"}) {
    try {
      network.set_params("w", {{"scale", bad}});
      ADD_FAILURE() << "accepted '" << bad << "'";
    } catch (const std::invalid_argument& e) {
      EXPECT_EQ(std::string(e.what()),
                "component 'w' (worker): parameter 'scale' must be a number in [1, 100], not '" + bad + "'");
    }
  }
  EXPECT_EQ(network.stats().components.at(1).params.at("scale"), "3");
  try {
    network.set_params("w", {{"speed", "2"}});
    ADD_FAILURE();
  } catch (const std::invalid_argument& e) {
    EXPECT_EQ(std::string(e.what()),
              "component 'w' (worker): parameter 'speed' cannot change while the network runs (these can: scale)");
  }
  EXPECT_THROW(network.set_params("src", {{"scale", "2"}}), std::invalid_argument);  // none of its can
  EXPECT_THROW(network.set_params("nobody", {{"scale", "2"}}), std::out_of_range);
  network.inject("src", "in", 2);
  ASSERT_TRUE(wait_for([&] { return trace.copy().size() == 2; }));
  EXPECT_EQ(trace.copy().back(), "6");
  network.stop();
}

TEST(NetworkErrorsTest, ASubtaskMayHoldOnlyComponentsWhoseValuesMayBeLost) {
  Trace trace;
  std::atomic<std::thread::id> applied_on;
  const auto registry = subtask_registry(trace, applied_on);
  auto spec = subtask_spec(true);
  spec.subtasks[0].components = {"src"};
  EXPECT_NE(build_error(spec, registry)
                .find("sub.yaml: subtask 'work': component 'src' takes values from outside the network on 'in' (the "
                      "HTTP writes): it cannot be stopped"),
            std::string::npos)
      << build_error(spec, registry);
  spec = subtask_spec(true);
  spec.components[1].policies["tick"] = PortPolicy::fifo;
  EXPECT_NE(build_error(spec, registry)
                .find("subtask 'work': component 'w' takes every value on 'tick' (a fifo: requests wait for them)"),
            std::string::npos)
      << build_error(spec, registry);
  spec = subtask_spec(true);
  spec.subtasks.push_back({"again", {"w"}, true});
  EXPECT_NE(build_error(spec, registry).find("component 'w' is in two subtasks ('work' and 'again')"),
            std::string::npos);
  spec = subtask_spec(true);
  spec.subtasks[0].components = {"nobody"};
  EXPECT_NE(build_error(spec, registry).find("subtask 'work': no component 'nobody'"), std::string::npos);
}

}  // namespace
}  // namespace wm::pipeline
