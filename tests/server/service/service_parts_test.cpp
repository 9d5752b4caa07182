// The service's small parts without the service: the writer-preferring lock the grid readers share with the grid
// writer, and the Prolog worker that runs knowledge-base queries and dry runs on a thread of its own.
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <future>
#include <mutex>
#include <shared_mutex>
#include <stdexcept>
#include <thread>
#include <vector>

#include "server/service/prolog_worker.h"
#include "server/service/writer_preferring_mutex.h"

namespace wm::service {
namespace {

using namespace std::chrono_literals;

// With a reader in and a writer waiting, a new reader waits too (a reader-preferring lock would let it in, and
// readers in a loop would keep the writer out for as long as they overlap).
TEST(WriterPreferringMutexTest, AWaitingWriterGoesBeforeNewReaders) {
  WriterPreferringMutex mutex;
  std::shared_lock first(mutex);
  std::atomic<bool> writer_in{false};
  std::thread writer([&] {
    std::unique_lock lock(mutex);
    writer_in = true;
  });
  // Once the writer waits for `first`, a new reader is refused (until then one may still get in, and is let go).
  bool refused = false;
  for (const auto deadline = std::chrono::steady_clock::now() + 10s;
       !refused && std::chrono::steady_clock::now() < deadline;) {
    refused = !mutex.try_lock_shared();
    if (!refused) {
      mutex.unlock_shared();
      std::this_thread::sleep_for(1ms);
    }
  }
  EXPECT_TRUE(refused) << "a new reader must not pass a waiting writer";
  EXPECT_FALSE(writer_in);
  first.unlock();
  writer.join();
  EXPECT_TRUE(writer_in);
  EXPECT_TRUE(mutex.try_lock_shared());
  EXPECT_TRUE(mutex.try_lock_shared()) << "readers share it when no writer waits";
  mutex.unlock_shared();
  mutex.unlock_shared();
  EXPECT_TRUE(mutex.try_lock());
  EXPECT_FALSE(mutex.try_lock_shared());
  mutex.unlock();
}

TEST(PrologWorkerTest, JobsRunInOrderOnOneThreadAndTheirErrorsComeBack) {
  rules::Engine engine(rules::EngineOptions{WM_SOURCE_DIR "/rules/prolog"});
  PrologWorker worker(engine, 16, "test");
  std::vector<int> order;
  std::vector<std::thread::id> threads;
  std::vector<std::future<void>> done;
  for (int i = 0; i < 5; ++i)
    done.push_back(worker.submit([&, i] {
      order.push_back(i);
      threads.push_back(std::this_thread::get_id());
    }));
  for (auto& d : done) d.get();
  EXPECT_EQ(order, (std::vector<int>{0, 1, 2, 3, 4}));
  for (const auto& t : threads) EXPECT_EQ(t, threads[0]);
  EXPECT_NE(threads[0], std::this_thread::get_id());
  EXPECT_EQ(worker.run([] { return 41 + 1; }), 42);
  EXPECT_THROW(worker.run([]() -> int { throw std::invalid_argument("bad goal"); }), std::invalid_argument);
  // The worker's thread has the engine attached: a query runs there.
  const auto result = worker.run([&] { return engine.query("X = 1", 1); });
  ASSERT_EQ(result.solutions.size(), 1u);
}

TEST(PrologWorkerTest, AFullQueueIsBusyAndTakesJobsAgainOnceItDrains) {
  rules::Engine engine(rules::EngineOptions{WM_SOURCE_DIR "/rules/prolog"});
  PrologWorker worker(engine, 2, "test");
  std::promise<void> release, started;
  auto gate = release.get_future().share();
  auto running = worker.submit([gate, &started] {  // holds the thread, out of the queue
    started.set_value();
    gate.wait();
  });
  started.get_future().wait();
  auto a = worker.submit([] {});
  auto b = worker.submit([] {});
  try {
    worker.submit([] {});
    FAIL() << "a third queued job must be refused";
  } catch (const Busy& e) {
    EXPECT_NE(std::string(e.what()).find("the test queue is full"), std::string::npos);
  }
  release.set_value();
  running.get();
  a.get();
  b.get();
  EXPECT_EQ(worker.run([] { return 3; }), 3);
}

}  // namespace
}  // namespace wm::service
