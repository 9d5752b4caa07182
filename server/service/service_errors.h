#pragma once

#include <stdexcept>

namespace wm::service {

/// A queue of the service is full (the writer's or the knowledge-base reader's): the caller should answer 503
/// and the client retry later. Nothing was applied.
class Busy : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// A request the map's state does not allow now (HTTP 409): no floor plan to place, an empty grid to align against,
/// nothing to undo. Nothing was applied.
class Conflict : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// What the request names is not there (HTTP 404), e.g. a change no longer listed. Nothing was applied.
class NotFound : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// A request id (Idempotency-Key) that was used before with another body or on another endpoint (HTTP 409).
/// Nothing was applied.
class RequestIdConflict : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

}  // namespace wm::service
