#pragma once

#include <condition_variable>
#include <deque>
#include <functional>
#include <future>
#include <memory>
#include <mutex>
#include <stdexcept>
#include <string>
#include <thread>

#include "rules/engine.h"
#include "server/service/service_errors.h"

namespace wm::service {

/// One thread with a Prolog engine attached, running queued jobs in order. Attaching costs ~95 µs, so the
/// thread lives as long as the worker.
class PrologWorker {
 public:
  PrologWorker(rules::Engine& engine, std::size_t max_queued, std::string name)
      : max_queued_(max_queued), name_(std::move(name)), thread_([this, &engine] { loop(engine); }) {}

  ~PrologWorker() {
    {
      std::lock_guard lock(mutex_);
      stopping_ = true;
    }
    cv_.notify_all();
    thread_.join();
  }
  PrologWorker(const PrologWorker&) = delete;
  PrologWorker& operator=(const PrologWorker&) = delete;

  /// Runs `work` on the worker thread and returns its result (or rethrows its exception).
  /// @throw Busy when the queue is full.
  template <typename F>
  auto run(F&& work) -> decltype(work()) {
    return submit(std::forward<F>(work)).get();
  }

  /// Queues `work` and returns at once. @throw Busy when the queue is full.
  template <typename F>
  auto submit(F&& work) -> std::future<decltype(work())> {
    using Result = decltype(work());
    auto task = std::make_shared<std::packaged_task<Result()>>(std::forward<F>(work));
    auto future = task->get_future();
    {
      std::lock_guard lock(mutex_);
      if (queue_.size() >= max_queued_) throw Busy("the " + name_ + " queue is full; retry later");
      queue_.emplace_back([task] { (*task)(); });
    }
    cv_.notify_one();
    return future;
  }

 private:
  void loop(rules::Engine& engine) {
    rules::ThreadAttachment prolog(engine);
    for (;;) {
      std::function<void()> job;
      {
        std::unique_lock lock(mutex_);
        cv_.wait(lock, [this] { return stopping_ || !queue_.empty(); });
        if (queue_.empty()) return;  // stopping, and everything queued has run
        job = std::move(queue_.front());
        queue_.pop_front();
      }
      job();  // packaged_task keeps any exception for the waiting caller
    }
  }

  const std::size_t max_queued_;
  const std::string name_;
  std::mutex mutex_;
  std::condition_variable cv_;
  std::deque<std::function<void()>> queue_;
  bool stopping_ = false;
  std::thread thread_;  // last: starts after the members it uses exist
};

}  // namespace wm::service
