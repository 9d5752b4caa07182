#include "server/service/writer_preferring_mutex.h"

#include <system_error>

namespace wm::service {

WriterPreferringMutex::WriterPreferringMutex() {
  pthread_rwlockattr_t attr;
  pthread_rwlockattr_init(&attr);
  pthread_rwlockattr_setkind_np(&attr, PTHREAD_RWLOCK_PREFER_WRITER_NONRECURSIVE_NP);
  const int rc = pthread_rwlock_init(&rwlock_, &attr);
  pthread_rwlockattr_destroy(&attr);
  if (rc != 0) throw std::system_error(rc, std::generic_category(), "pthread_rwlock_init");
}
WriterPreferringMutex::~WriterPreferringMutex() { pthread_rwlock_destroy(&rwlock_); }
void WriterPreferringMutex::lock() {
  if (const int rc = pthread_rwlock_wrlock(&rwlock_)) throw std::system_error(rc, std::generic_category(), "rwlock");
}
bool WriterPreferringMutex::try_lock() { return pthread_rwlock_trywrlock(&rwlock_) == 0; }
void WriterPreferringMutex::unlock() { pthread_rwlock_unlock(&rwlock_); }
void WriterPreferringMutex::lock_shared() {
  // EAGAIN (too many readers) cannot happen below 2^31 readers; EDEADLK is a recursive call: a bug.
  if (const int rc = pthread_rwlock_rdlock(&rwlock_)) throw std::system_error(rc, std::generic_category(), "rwlock");
}
bool WriterPreferringMutex::try_lock_shared() { return pthread_rwlock_tryrdlock(&rwlock_) == 0; }
void WriterPreferringMutex::unlock_shared() { pthread_rwlock_unlock(&rwlock_); }

}  // namespace wm::service
