// POST /api/v1/query: a sandboxed, read-only knowledge-base goal.
#include "server/api/handlers.h"
#include "server/api/response.h"

namespace wm::api {

Response post_query(const Call& call) {
  const auto doc = parse_json_object(call.request);
  require_known_keys(doc, {"goal", "max_solutions"});
  const auto goal = string_field(doc, "goal", 64 * 1024);
  const auto max_solutions = count_field(doc, "max_solutions", 100, 10000);
  const auto answer = call.world.rules.query(goal, max_solutions);
  const auto max_bytes = call.options.max_query_answer_bytes;
  return json_response(call.request, json_codec::query_result_json(answer, max_bytes), boost::beast::http::status::ok,
                       max_bytes);
}

}  // namespace wm::api
