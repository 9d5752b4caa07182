#pragma once

#include <pthread.h>

namespace wm::service {

/// A reader–writer lock that lets a waiting writer in before new readers (a glibc rwlock of kind
/// PTHREAD_RWLOCK_PREFER_WRITER_NONRECURSIVE_NP). std::shared_mutex on glibc prefers readers: with a few
/// clients reading the grid in a loop their shared locks overlap and the writer waited for seconds per scan.
/// Meets SharedMutex, so std::shared_lock and std::unique_lock work with it. Not recursive: a thread that holds
/// it shared must not take it shared again (it would queue behind a waiting writer and deadlock).
class WriterPreferringMutex {
 public:
  WriterPreferringMutex();
  ~WriterPreferringMutex();
  WriterPreferringMutex(const WriterPreferringMutex&) = delete;
  WriterPreferringMutex& operator=(const WriterPreferringMutex&) = delete;
  void lock();
  bool try_lock();
  void unlock();
  void lock_shared();
  bool try_lock_shared();
  void unlock_shared();

 private:
  pthread_rwlock_t rwlock_;
};

}  // namespace wm::service
