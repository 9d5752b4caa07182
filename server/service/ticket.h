#pragma once

#include <exception>
#include <future>
#include <optional>
#include <utility>

#include "server/service/service_errors.h"

namespace wm::service {

/// A waiting request's answer, held (by shared_ptr) by every stage of the processing network the request still has
/// work in: the scan's commit, its grid insert, the trim or extraction it made due. The outcome or the error is set
/// by the stage that knows it; the request is answered when the last holder lets go, so a client that posts one scan
/// at a time sees the map with everything its scan caused. Dropped without either (the server stopping with the
/// request on its way): Busy, since it may or may not have been applied.
template <typename Outcome>
class Ticket {
 public:
  Ticket() = default;
  Ticket(const Ticket&) = delete;
  Ticket& operator=(const Ticket&) = delete;
  ~Ticket() {
    if (error_)
      promise_.set_exception(error_);
    else if (outcome_)
      promise_.set_value(std::move(*outcome_));
    else
      promise_.set_exception(std::make_exception_ptr(
          Busy("the server stopped while the request was on its way; it may have been applied (a retry with the "
               "same request id is answered, not applied twice)")));
  }
  /// Call once, before the ticket is shared.
  std::future<Outcome> future() { return promise_.get_future(); }
  void succeed(Outcome outcome) { outcome_ = std::move(outcome); }
  /// An error wins over an outcome set before or after it.
  void fail(std::exception_ptr error) { error_ = std::move(error); }

 private:
  std::promise<Outcome> promise_;
  std::optional<Outcome> outcome_;
  std::exception_ptr error_;
};

}  // namespace wm::service
