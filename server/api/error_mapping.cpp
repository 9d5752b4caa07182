#include "server/api/error_mapping.h"

#include <stdexcept>

#include "apriori/floor_plan.h"
#include "fusion/registration/plan_registration.h"
#include "rules/types.h"
#include "server/api/api_error.h"
#include "server/json/codec_error.h"
#include "server/service/service_errors.h"
#include "server/storage/database.h"
#include "server/storage/leases.h"

namespace wm::api {
namespace {

HttpError query_error(const rules::QueryError& e) {
  switch (e.reason()) {
    case rules::QueryError::Reason::syntax:
      return {400, "bad_query", e.what()};
    case rules::QueryError::Reason::unsafe:
      return {403, "forbidden_goal", e.what()};
    case rules::QueryError::Reason::limit:
      return {422, "query_limit", e.what()};
    case rules::QueryError::Reason::failed:
      break;
  }
  return {422, "query_error", e.what()};
}

}  // namespace

HttpError http_error(const std::exception_ptr& failure) {
  try {
    std::rethrow_exception(failure);
  } catch (const ApiError& e) {
    return {e.status(), e.error(), e.what()};
  } catch (const json_codec::CodecError& e) {
    if (e.kind() == json_codec::CodecError::Kind::answer_too_large) return {422, "answer_too_large", e.what()};
    return {400, "bad_request", e.what()};
  } catch (const apriori::FloorPlanError& e) {
    return {400, "bad_floor_plan", e.what()};
  } catch (const rules::QueryError& e) {
    return query_error(e);
  } catch (const rules::RuleError& e) {
    return {422, "rule_error", e.what()};
  } catch (const service::RequestIdConflict& e) {
    return {409, "request_id_conflict", e.what()};
  } catch (const service::Conflict& e) {
    return {409, "conflict", e.what()};
  } catch (const service::NotFound& e) {
    return {404, "not_found", e.what()};
  } catch (const fusion::RegistrationError& e) {
    return {400, "bad_request", e.what()};
  } catch (const service::Busy& e) {
    return {503, "busy", e.what()};
  } catch (const storage::FencedError& e) {
    // This node no longer holds the map's lease: nothing was written; another node writes the map now.
    return {503, "lease_lost", e.what()};
  } catch (const storage::StorageError& e) {
    return {503, "storage_error", e.what()};
  } catch (const std::invalid_argument& e) {
    return {422, "rejected", e.what()};
  } catch (const std::exception& e) {
    return {500, "internal_error", e.what()};
  } catch (...) {
    return {500, "internal_error", "unknown error"};
  }
}

}  // namespace wm::api
