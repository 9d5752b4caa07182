#pragma once

#include <signal.h>

#include <atomic>
#include <cstddef>

namespace wm::shm {

/// Lets this thread touch a shared file mapping that another process may truncate under it. Any process of the
/// file's owner can shrink a /dev/shm file; an access to a page of a MAP_SHARED mapping past the file's new end
/// raises SIGBUS, which would end the server. While a guard lives, a SIGBUS at an address in [base, base + bytes)
/// replaces that whole range with private anonymous memory, sets `lost`, and lets the faulting access go on there:
/// from then on nothing written to the range reaches the file, and its owner should drop the mapping. No check of the
/// file's size beforehand can do this, since the file can shrink between the check and the access.
///
/// SIGBUS elsewhere, or in a thread without a guard, goes to the handler that was installed before (the SWI-Prolog
/// runtime's, say) or, when there was none, ends the process as it would have. The handler is process-wide by
/// nature: it is installed by the first guard, and again by any later guard that finds another one installed since.
/// Guards nest, in stack order, on one thread.
class SigbusGuard {
 public:
  SigbusGuard(void* base, std::size_t bytes, std::atomic<bool>& lost);
  ~SigbusGuard();
  SigbusGuard(const SigbusGuard&) = delete;
  SigbusGuard& operator=(const SigbusGuard&) = delete;

 private:
  static void handle(int signal, siginfo_t* info, void* context);

  unsigned char* const base_;
  const std::size_t bytes_;
  std::atomic<bool>& lost_;
  const SigbusGuard* const outer_;
};

}  // namespace wm::shm
