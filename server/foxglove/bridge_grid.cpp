#include <algorithm>
#include <cmath>
#include <limits>

#include "server/foxglove/bridge_internal.h"
#include "server/foxglove/messages.h"

// The grid's messages (/grid, /grid/ds): the tiles copied as they change, assembled and, past
// max_grid_cells, coarsened.
namespace wm::foxglove {

using internal::share;
using internal::unix_ns_now;

// Lists the tiles and reads those whose revision moved (and those never read).
void Bridge::Core::refresh(TileCache& cache) {
  const auto listing = world.grid.grid_tiles();
  if (listing.tile_size_cells != cache.tile_size || listing.resolution_m != cache.resolution_m) {
    cache.tiles.clear();
    cache.tile_size = listing.tile_size_cells;
    cache.resolution_m = listing.resolution_m;
  }
  const auto cells = static_cast<std::size_t>(cache.tile_size * cache.tile_size);
  for (const auto& t : listing.tiles) {
    auto& [revision, values] = cache.tiles[{t.tx, t.ty}];
    if (revision == t.revision && !values.empty()) continue;
    if (cache.layers.size() == 1) {
      auto tile = world.grid.grid_tile(cache.layers.front(), t.tx, t.ty);
      if (!tile) continue;
      revision = tile->revision;
      values = std::move(tile->values);
    } else {  // every layer of the tile under one lock: all of one revision; the DS ones follow Bayes in Layer order
      auto tile = world.grid.grid_tile_layers(t.tx, t.ty);
      if (!tile || tile->values.size() < 4 * cells) continue;
      revision = tile->revision;
      values.assign(tile->values.begin() + static_cast<std::ptrdiff_t>(cells), tile->values.end());
    }
  }
  cache.revision = listing.revision;
}

std::optional<Bridge::Core::GridCache> Bridge::Core::build_grid(std::uint32_t channel) {
  auto& cache = channel == kGridChannel ? bayes_tiles_ : ds_tiles_;
  const std::vector<std::string> names = channel == kGridChannel
                                             ? std::vector<std::string>{"probability"}
                                             : std::vector<std::string>{"belief", "plausibility", "conflict"};
  refresh(cache);
  if (cache.tiles.empty()) return std::nullopt;  // nothing observed yet
  // The tiles' bounding box, as GET /api/v1/grid answers by default.
  std::int64_t tx0 = std::numeric_limits<std::int64_t>::max(), ty0 = tx0,
               tx1 = std::numeric_limits<std::int64_t>::min(), ty1 = tx1;
  for (const auto& [index, tile] : cache.tiles) {
    tx0 = std::min(tx0, index.first);
    ty0 = std::min(ty0, index.second);
    tx1 = std::max(tx1, index.first);
    ty1 = std::max(ty1, index.second);
  }
  const double tile_m = cache.resolution_m * static_cast<double>(cache.tile_size);
  const fusion::GridGeometry region({static_cast<double>(tx0) * tile_m, static_cast<double>(ty0) * tile_m},
                                    cache.resolution_m, (tx1 - tx0 + 1) * cache.tile_size,
                                    (ty1 - ty0 + 1) * cache.tile_size);
  const auto k = coarsening_factor(region.width(), region.height(), options.max_grid_cells);
  // Pooled tile by tile straight into the grid sent (k = 1: each cell its own value; k > 1: the largest known value
  // of its k × k block, as coarsened() does), so the cost follows the tiles observed, not their bounding box, which
  // two scans kilometres apart make 10^12 cells.
  const std::int64_t cw = (region.width() + k - 1) / k, ch = (region.height() + k - 1) / k, t = cache.tile_size;
  std::vector<GridField> fields;
  for (const auto& name : names)
    fields.push_back({name, std::vector<float>(static_cast<std::size_t>(cw * ch), std::nanf(""))});
  for (const auto& [index, tile] : cache.tiles) {
    const auto& values = tile.second;
    if (values.size() < names.size() * static_cast<std::size_t>(t * t)) continue;
    const std::int64_t gx0 = (index.first - tx0) * t, gy0 = (index.second - ty0) * t;
    for (std::size_t l = 0; l < names.size(); ++l) {
      auto& out = fields[l].values;
      for (std::int64_t iy = 0; iy < t; ++iy) {
        const std::int64_t row = ((gy0 + iy) / k) * cw;
        const float* in = values.data() + l * static_cast<std::size_t>(t * t) + static_cast<std::size_t>(iy * t);
        for (std::int64_t ix = 0; ix < t; ++ix)
          fusion::pool_max(out[static_cast<std::size_t>(row + (gx0 + ix) / k)], in[ix]);
      }
    }
  }
  const fusion::GridGeometry sent(region.origin_m(), region.resolution_m() * static_cast<double>(k), cw, ch);
  auto payload = share(grid_message(sent, fields, unix_ns_now()));
  ++grid_messages;
  if (channel == kGridChannel) last_grid_bytes = payload->size();
  return GridCache{cache.revision, std::move(payload)};
}

void Bridge::Core::produce_grids() {
  for (const auto channel : {kGridChannel, kGridDsChannel}) {
    auto& cache = channel == kGridChannel ? grid_cache_ : ds_cache_;
    auto& published = channel == kGridChannel ? grid_published_ : ds_published_;
    if (!has_subscribers(channel)) {
      cache = {};  // stale from now on; a new subscriber reads the grid afresh
      published = -1;
      (channel == kGridChannel ? bayes_tiles_ : ds_tiles_).tiles.clear();  // its memory too
      continue;
    }
    auto built = build_grid(channel);
    if (!built) continue;  // nothing observed yet
    cache = std::move(*built);
    if (cache.revision != published) {
      published = cache.revision;
      publish(channel, cache.payload, unix_ns_now());
    }
  }
  grid_dirty_ = false;
}

}  // namespace wm::foxglove
