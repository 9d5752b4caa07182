#include "server/shm/sigbus_guard.h"

#include <sys/mman.h>

#include <mutex>

namespace wm::shm {
namespace {

// What the handler reads: constant-initialised thread locals (plain TLS accesses, safe in a signal handler) and
// the handler installed before ours. A disposition is process state, so this is too; it is written under the
// mutex, before our handler is (re)installed.
thread_local const SigbusGuard* t_innermost = nullptr;
thread_local bool t_passing_on = false;
std::mutex g_install_mutex;
struct sigaction g_previous {};

}  // namespace

SigbusGuard::SigbusGuard(void* base, std::size_t bytes, std::atomic<bool>& lost)
    : base_(static_cast<unsigned char*>(base)), bytes_(bytes), lost_(lost), outer_(t_innermost) {
  {
    std::lock_guard lock(g_install_mutex);
    struct sigaction current {};
    ::sigaction(SIGBUS, nullptr, &current);
    if (!(current.sa_flags & SA_SIGINFO) || current.sa_sigaction != &SigbusGuard::handle) {
      struct sigaction ours {};
      ours.sa_sigaction = &SigbusGuard::handle;
      ours.sa_flags = SA_SIGINFO | SA_ONSTACK;
      sigemptyset(&ours.sa_mask);
      g_previous = current;
      ::sigaction(SIGBUS, &ours, nullptr);
    }
  }
  t_innermost = this;
  std::atomic_signal_fence(std::memory_order_seq_cst);  // registered before any access it guards
}

SigbusGuard::~SigbusGuard() {
  std::atomic_signal_fence(std::memory_order_seq_cst);  // every guarded access done before it leaves
  t_innermost = outer_;
}

void SigbusGuard::handle(int signal, siginfo_t* info, void* context) {
  const auto* address = static_cast<const unsigned char*>(info->si_addr);
  for (const auto* guard = t_innermost; guard != nullptr && !t_passing_on; guard = guard->outer_) {
    if (address < guard->base_ || address >= guard->base_ + guard->bytes_) continue;
    guard->lost_.store(true, std::memory_order_relaxed);
    // mmap is a bare system call (Wayland's compositors do the same for their clients' shm pools); the faulting
    // access is restarted on return and lands in the new pages.
    if (::mmap(guard->base_, guard->bytes_, PROT_READ | PROT_WRITE,
               MAP_PRIVATE | MAP_FIXED | MAP_ANONYMOUS | MAP_NORESERVE, -1, 0) != MAP_FAILED)
      return;
    break;
  }
  // Not ours: whoever handled SIGBUS before; a handler that hands it back to us ends the process.
  const struct sigaction previous = g_previous;
  if (!t_passing_on) {
    t_passing_on = true;
    if ((previous.sa_flags & SA_SIGINFO) && previous.sa_sigaction != nullptr) {
      previous.sa_sigaction(signal, info, context);
      t_passing_on = false;
      return;
    }
    if (!(previous.sa_flags & SA_SIGINFO) && previous.sa_handler != SIG_DFL && previous.sa_handler != SIG_IGN) {
      previous.sa_handler(signal);
      t_passing_on = false;
      return;
    }
  }
  // The default action (a fault cannot be ignored): delivered again as soon as this handler returns.
  struct sigaction fallback {};
  fallback.sa_handler = SIG_DFL;
  sigemptyset(&fallback.sa_mask);
  ::sigaction(SIGBUS, &fallback, nullptr);
  ::raise(SIGBUS);
}

}  // namespace wm::shm
