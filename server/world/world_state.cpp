#include "server/world/world_state.h"

#include <charconv>

namespace wm::world {

const ObjectState* WorldState::find_object(const std::string& id) const {
  auto it = object_index.find(id);
  return it == object_index.end() ? nullptr : &objects[it->second];
}

std::optional<std::int64_t> WorldState::element_number(const std::string& id) {
  if (id.size() < 2 || id[0] != 'e') return std::nullopt;
  std::int64_t n = 0;
  auto [ptr, ec] = std::from_chars(id.data() + 1, id.data() + id.size(), n);
  if (ec != std::errc() || ptr != id.data() + id.size() || n <= 0) return std::nullopt;
  return n;
}

const Element* WorldState::find_element(const std::string& id) const {
  auto n = element_number(id);
  if (!n) return nullptr;
  auto it = elements.find(*n);
  return it == elements.end() ? nullptr : &it->second;
}

std::vector<ObjectState> make_objects(const apriori::FloorPlan& plan, const WorldOptions& options,
                                      std::int64_t version) {
  std::vector<ObjectState> objects;
  objects.reserve(plan.objects.size());
  for (const auto& drawn : plan.objects) {
    auto shared = std::make_shared<const apriori::PlanObject>(drawn);
    fusion::RigidObject body(drawn.pose, drawn.pose_cov.value_or(options.default_pose_cov), drawn.edges());
    objects.push_back(ObjectState{std::move(shared), std::move(body), 0, 0, version});
  }
  return objects;
}

void rebuild_object_index(WorldState& state) {
  state.object_index.clear();
  for (std::size_t i = 0; i < state.objects.size(); ++i) state.object_index.emplace(state.objects[i].plan->id, i);
}

Eigen::Matrix2d midpoint_line_cov(const fusion::LineSegment& segment, double sigma_offset_m, double sigma_angle_rad) {
  const double t_mid = 0.5 * (segment.t0_m + segment.t1_m);
  Eigen::Matrix2d jacobian;
  jacobian << 1.0, t_mid, 0.0, 1.0;
  return jacobian * Eigen::Vector2d(sigma_offset_m * sigma_offset_m, sigma_angle_rad * sigma_angle_rad).asDiagonal() *
         jacobian.transpose();
}

Eigen::Matrix2d apriori_edge_noise(const ObjectState& object, std::size_t k, const WorldOptions& options) {
  const auto drawn = object.body.world_edge(k, Eigen::Matrix2d::Zero());
  return midpoint_line_cov(drawn, options.apriori_offset_sigma_m, options.apriori_angle_sigma_rad);
}

fusion::LineSegment apriori_edge(const ObjectState& object, std::size_t k, const WorldOptions& options) {
  return object.body.world_edge(k, apriori_edge_noise(object, k, options));
}

std::string edge_id(const std::string& object_id, std::size_t k) { return object_id + "/" + std::to_string(k); }

}  // namespace wm::world
