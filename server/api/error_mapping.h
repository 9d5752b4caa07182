#pragma once

#include <exception>
#include <string>

namespace wm::api {

/// What a failure answers: the HTTP status and the JSON error body {"error": error, "detail": detail}.
struct HttpError {
  int status = 500;
  std::string error;   // a short stable code: "bad_request", "not_found", "rule_error", ...
  std::string detail;  // human-readable, with the field path for 400
};

/// The one place where the errors of every module become HTTP: ApiError (its own status), json_codec::CodecError
/// (400 bad_request, 422 answer_too_large), apriori::FloorPlanError (400 bad_floor_plan), rules::QueryError (400
/// bad_query, 403 forbidden_goal, 422 query_limit or query_error), rules::RuleError (422 rule_error),
/// service::RequestIdConflict (409), service::Busy (503 busy), storage::StorageError (503 storage_error),
/// std::invalid_argument (422 rejected: a request the world model refused), anything else 500 internal_error.
HttpError http_error(const std::exception_ptr& failure);

}  // namespace wm::api
