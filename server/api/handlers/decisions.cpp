// GET /api/v1/decisions: the decision log, paged by sequence number.
#include <limits>

#include "server/api/handlers.h"
#include "server/api/response.h"
#include "server/json/answers.h"

namespace wm::api {

Response get_decisions(const Call& call) {
  const auto since = query_int(call.target, "since", 0, 0, std::numeric_limits<std::int64_t>::max());
  const auto limit =
      query_int(call.target, "limit", 1000, 1, static_cast<std::int64_t>(call.options.max_decisions_per_page));
  const auto rows = call.world.map.decisions(since, static_cast<std::size_t>(limit), call.target.param("element"));
  const auto next = rows.empty() ? since : rows.back().seq;
  return json_response(call.request, {{"decisions", json_codec::decisions_json(rows)}, {"next", next}});
}

}  // namespace wm::api
