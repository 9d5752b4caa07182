#pragma once

#include <stdexcept>
#include <string>

namespace wm::api {

/// A request the server refuses, with the HTTP status to answer. `error` is a short stable code
/// ("bad_request", "not_found", ...); what() is the human-readable detail (with the field path for 400).
class ApiError : public std::runtime_error {
 public:
  ApiError(int status, std::string error, const std::string& detail)
      : std::runtime_error(detail), status_(status), error_(std::move(error)) {}
  int status() const { return status_; }
  const std::string& error() const { return error_; }

 private:
  int status_;
  std::string error_;
};

inline ApiError bad_request(const std::string& path, const std::string& message) {
  return ApiError(400, "bad_request", path.empty() ? message : path + ": " + message);
}

/// 404 for a map id that names no map of the registry (the default map always exists).
inline ApiError map_not_found(const std::string& id) {
  return ApiError(404, "map_not_found", "no map '" + id + "' (GET /api/v1/maps lists them)");
}

}  // namespace wm::api
