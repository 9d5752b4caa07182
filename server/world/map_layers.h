#pragma once

#include <optional>
#include <vector>

#include "apriori/export/layer_lines.h"
#include "server/world/world_state.h"

namespace wm::world {

/// The observed map in CAD/GIS form, one layer per state of what it draws (only non-empty layers, in this order):
/// `plan_unobserved` (colour 8) edges of CAD objects never observed, `confirmed` (3) of objects confirmed,
/// `adjusted` (1) of objects moved by a rigid adjustment, `merged` (5) elements with more than one observation,
/// `new` (6) elements seen once. Edges are in the world frame (current poses); ids are edge or element ids.
/// With an excerpt, only its objects and elements.
std::vector<apriori::LayerLines> map_layers(const WorldState& state, const WorldOptions& options,
                                            const std::optional<MapExcerpt>& excerpt = std::nullopt);

}  // namespace wm::world
