// GET /api/v1/shm: where local processes find the shared-memory export (clients/shm/, docs/shm.md).
#include "server/api/api_error.h"
#include "server/api/handlers.h"
#include "server/api/response.h"

namespace wm::api {

Response get_shm(const Call& call) {
  if (call.shm == nullptr)
    throw ApiError(404, "shm_disabled", "this server runs with --no-shm: read the grid over HTTP (GET /api/v1/grid)");
  const auto s = call.shm->status();
  if (!s.available) throw ApiError(503, "shm_unavailable", "no shared memory segment: " + s.error);
  nlohmann::json answer = {
      {"name", s.name},
      {"path", "/dev/shm/" + s.name},
      {"bytes", s.bytes},
      {"layout_version", 1},
      {"state", "live"},
      {"generation", s.generation},
      {"server_instance", call.map_cache.instance()},
      {"owner_pid", s.owner_pid},
      {"tile_size_cells", s.tile_size_cells},
      {"resolution", s.resolution_m},
      {"layers", {"bayes", "ds_belief", "ds_plausibility", "ds_conflict"}},
      {"tiles",
       {{"count", s.tile_count},
        {"capacity", s.tile_capacity},
        {"offset", s.tiles_offset},
        {"slot_bytes", s.slot_bytes},
        {"complete", s.tiles_complete}}},
      {"map",
       {{"version", s.map_version},
        {"offset", s.map_offset},
        {"capacity_bytes", s.map_capacity_bytes},
        {"complete", s.map_complete},
        {"elements", s.elements},
        {"objects", s.objects},
        {"edges", s.edges}}},
      {"grid_revision", s.grid_revision},
      {"period_ms", s.period.count()},
      {"updated_unix_ns", s.updated_unix_ns},
      {"consistency",
       "a sequence counter (seqlock) per tile and one for the map: copy, then check it was even and "
       "unchanged (docs/shm.md)"}};
  if (!s.error.empty()) answer["warning"] = s.error;
  return json_response(call.request, answer);
}

}  // namespace wm::api
