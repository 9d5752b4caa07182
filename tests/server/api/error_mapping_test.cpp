#include "server/api/error_mapping.h"

#include <gtest/gtest.h>

#include "apriori/floor_plan.h"
#include "rules/types.h"
#include "server/api/api_error.h"
#include "server/json/codec_error.h"
#include "server/service/service_errors.h"
#include "server/storage/database.h"
#include "server/storage/leases.h"

namespace wm::api {
namespace {

template <typename Error>
HttpError mapped(const Error& error) {
  return http_error(std::make_exception_ptr(error));
}

TEST(ErrorMappingTest, EveryModulesErrorHasItsStatusAndCode) {
  struct Case {
    HttpError got;
    int status;
    std::string error;
  };
  using QE = rules::QueryError;
  const Case cases[] = {
      {mapped(ApiError(421, "misdirected_request", "x")), 421, "misdirected_request"},
      {mapped(json_codec::bad_request("segments[0]", "x")), 400, "bad_request"},
      {mapped(json_codec::CodecError(json_codec::CodecError::Kind::answer_too_large, "", "x")), 422,
       "answer_too_large"},
      {mapped(apriori::FloorPlanError("objects[0]", "x")), 400, "bad_floor_plan"},
      {mapped(QE(QE::Reason::syntax, "x")), 400, "bad_query"},
      {mapped(QE(QE::Reason::unsafe, "x")), 403, "forbidden_goal"},
      {mapped(QE(QE::Reason::limit, "x")), 422, "query_limit"},
      {mapped(QE(QE::Reason::failed, "x")), 422, "query_error"},
      {mapped(rules::RuleError("world_model.pl:3: x")), 422, "rule_error"},
      {mapped(service::RequestIdConflict("x")), 409, "request_id_conflict"},
      {mapped(service::Busy("x")), 503, "busy"},
      {mapped(storage::StorageError("x")), 503, "storage_error"},
      {mapped(storage::FencedError("x")), 503, "lease_lost"},
      {mapped(std::invalid_argument("x")), 422, "rejected"},
      {mapped(std::runtime_error("x")), 500, "internal_error"},
      {http_error(std::make_exception_ptr(42)), 500, "internal_error"},
  };
  for (const auto& c : cases) {
    EXPECT_EQ(c.got.status, c.status) << c.error;
    EXPECT_EQ(c.got.error, c.error);
  }
}

TEST(ErrorMappingTest, TheDetailIsTheErrorsTextWithItsFieldPath) {
  EXPECT_EQ(mapped(json_codec::bad_request("segments[1].p0[0]", "not a finite number")).detail,
            "segments[1].p0[0]: not a finite number");
  EXPECT_EQ(mapped(json_codec::bad_request("", "empty body")).detail, "empty body");
  EXPECT_EQ(mapped(bad_request("since", "expected an integer")).detail, "since: expected an integer");
}

}  // namespace
}  // namespace wm::api
