#include "server/world/map_layers.h"

namespace wm::world {

std::vector<apriori::LayerLines> map_layers(const WorldState& state, const WorldOptions& options,
                                            const std::optional<MapExcerpt>& excerpt) {
  apriori::LayerLines plan{"plan_unobserved", {}, {}, 8}, confirmed{"confirmed", {}, {}, 3},
      adjusted{"adjusted", {}, {}, 1}, merged{"merged", {}, {}, 5}, added{"new", {}, {}, 6};
  std::vector<std::size_t> objects;
  std::vector<std::int64_t> elements;
  if (excerpt) {
    objects = excerpt->objects;
    elements = excerpt->elements;
  } else {
    for (std::size_t i = 0; i < state.objects.size(); ++i) objects.push_back(i);
    for (const auto& [number, element] : state.elements) elements.push_back(number);
  }
  for (const auto index : objects) {
    const auto& object = state.objects[index];
    auto& layer = object.adjustments > 0 ? adjusted : object.confirmations > 0 ? confirmed : plan;
    for (std::size_t k = 0; k < object.body.edges().size(); ++k) {
      const auto edge = apriori_edge(object, k, options);
      layer.polylines.push_back({edge.p0(), edge.p1()});
      layer.ids.push_back(edge_id(object.plan->id, k));
    }
  }
  for (const auto number : elements) {
    const auto& element = state.elements.at(number);
    auto& layer = element.support > 1 ? merged : added;
    layer.polylines.push_back({element.segment.p0(), element.segment.p1()});
    layer.ids.push_back(element.id());
  }
  std::vector<apriori::LayerLines> layers;
  for (auto* layer : {&plan, &confirmed, &adjusted, &merged, &added})
    if (!layer->polylines.empty()) layers.push_back(std::move(*layer));
  return layers;
}

}  // namespace wm::world
