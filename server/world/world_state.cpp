#include "server/world/world_state.h"

#include <Eigen/Geometry>
#include <charconv>
#include <stdexcept>

namespace wm::world {

namespace {

// Edges are keyed in the spatial index as object << 24 | edge.
constexpr int kEdgeBits = 24;

std::int64_t edge_key(std::size_t object, std::size_t edge) {
  return static_cast<std::int64_t>(object) << kEdgeBits | static_cast<std::int64_t>(edge);
}

// Keys back to (object index, edge index), in key order (so sorted).
std::vector<std::pair<std::size_t, std::size_t>> edges_of(const std::vector<std::int64_t>& keys) {
  std::vector<std::pair<std::size_t, std::size_t>> edges;
  const std::int64_t edge_mask = (std::int64_t{1} << kEdgeBits) - 1;
  for (const auto key : keys)
    edges.emplace_back(static_cast<std::size_t>(key >> kEdgeBits), static_cast<std::size_t>(key & edge_mask));
  return edges;
}

fusion::LineSegment edge_segment(const ObjectState& object, std::size_t k) {
  return object.body.world_edge(k, Eigen::Matrix2d::Zero());
}

}  // namespace

void ElementTable::put(Element element) {
  if (element.number <= 0) throw std::out_of_range("ElementTable: element numbers start at 1");
  const auto number = element.number;
  if (const Element* old = elements_.find(number))
    index_.move(number, old->segment, element.segment);
  else
    index_.insert(number, element.segment);
  elements_.put(number, std::move(element));
}

bool ElementTable::erase(std::int64_t number) {
  const Element* old = elements_.find(number);
  if (!old) return false;
  index_.erase(number, old->segment);
  return elements_.erase(number);
}

void ElementTable::clear() {
  elements_.clear();
  index_.clear();
}

ObjectTable::ObjectTable(std::vector<ObjectState> objects) {
  auto by_id = std::make_shared<std::unordered_map<std::string, std::size_t>>();
  std::vector<std::pair<std::int64_t, fusion::LineSegment>> edges;
  for (std::size_t i = 0; i < objects.size(); ++i) {
    const auto& object = objects[i];
    if (!by_id->emplace(object.plan->id, i).second)
      throw std::invalid_argument("two plan objects share the id '" + object.plan->id + "'");
    if (object.body.edges().size() >= (std::size_t{1} << kEdgeBits))
      throw std::invalid_argument("plan object '" + object.plan->id + "' has too many edges");
    for (std::size_t k = 0; k < object.body.edges().size(); ++k)
      edges.emplace_back(edge_key(i, k), edge_segment(object, k));
    objects_.put(static_cast<std::int64_t>(i), std::move(objects[i]));
  }
  edges_.insert_all(edges);
  by_id_ = std::move(by_id);
}

std::optional<std::size_t> ObjectTable::index_of(const std::string& id) const {
  if (!by_id_) return std::nullopt;
  const auto it = by_id_->find(id);
  if (it == by_id_->end()) return std::nullopt;
  return it->second;
}

void ObjectTable::put(std::size_t index, ObjectState object) {
  const ObjectState& old = at(index);
  if (old.plan->id != object.plan->id || old.body.edges().size() != object.body.edges().size())
    throw std::invalid_argument("ObjectTable::put: object " + std::to_string(index) + " is '" + old.plan->id + "'");
  if (old.body.pose().x_m != object.body.pose().x_m || old.body.pose().y_m != object.body.pose().y_m ||
      old.body.pose().theta_rad != object.body.pose().theta_rad) {
    for (std::size_t k = 0; k < object.body.edges().size(); ++k)
      edges_.move(edge_key(index, k), edge_segment(old, k), edge_segment(object, k));
  }
  objects_.put(static_cast<std::int64_t>(index), std::move(object));
}

std::vector<std::pair<std::size_t, std::size_t>> ObjectTable::edges_near(const Box& box) const {
  return edges_of(edges_.query(box));
}

std::vector<std::pair<std::size_t, std::size_t>> ObjectTable::edges_near(const fusion::LineSegment& segment,
                                                                         double reach) const {
  return edges_of(edges_.query(segment, reach));
}

const ObjectState* WorldState::find_object(const std::string& id) const {
  const auto index = objects.index_of(id);
  return index ? &objects[*index] : nullptr;
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
  return elements.find(*n);
}

MapExcerpt map_excerpt(const WorldState& state, const Box& box) {
  MapExcerpt excerpt;
  for (const auto& [i, k] : state.objects.edges_near(box)) {
    if (!excerpt.objects.empty() && excerpt.objects.back() == i) continue;  // edges come sorted by object
    if (box.crossed_by(state.objects[i].body.world_edge(k, Eigen::Matrix2d::Zero()))) excerpt.objects.push_back(i);
  }
  for (const auto number : state.elements.near(box))
    if (box.crossed_by(state.elements.at(number).segment)) excerpt.elements.push_back(number);
  return excerpt;
}

namespace {

// The object's edges at the placement's scale (its own frame turns with its pose).
std::vector<fusion::LocalEdge> scaled_edges(const apriori::PlanObject& drawn, double scale) {
  auto edges = drawn.edges();
  if (scale != 1.0)
    for (auto& e : edges) {
      e.p0 *= scale;
      e.p1 *= scale;
    }
  return edges;
}

// A pose covariance carried through a change of placement: its position part turns by dθ. It is not scaled with the
// drawing: how well an object's position is known in the world does not depend on the units it was drawn in (a
// plan drawn in millimetres placed at 0.001 would otherwise freeze every rigid adjustment).
Eigen::Matrix3d placed_cov(const Eigen::Matrix3d& cov, double dtheta) {
  Eigen::Matrix3d j = Eigen::Matrix3d::Identity();
  j.topLeftCorner<2, 2>() = Eigen::Rotation2Dd(dtheta).toRotationMatrix();
  return j * cov * j.transpose();
}

}  // namespace

std::vector<ObjectState> make_objects(const apriori::FloorPlan& plan, const WorldOptions& options, std::int64_t version,
                                      const fusion::Similarity2D& placement) {
  std::vector<ObjectState> objects;
  objects.reserve(plan.objects.size());
  for (const auto& drawn : plan.objects) {
    auto shared = std::make_shared<const apriori::PlanObject>(drawn);
    const auto cov = placed_cov(drawn.pose_cov.value_or(options.default_pose_cov), placement.theta_rad);
    fusion::RigidObject body(placement.transform_pose(drawn.pose), cov, scaled_edges(drawn, placement.scale));
    objects.push_back(ObjectState{std::move(shared), std::move(body), 0, 0, version});
  }
  return objects;
}

ObjectState replaced(const ObjectState& object, const fusion::Similarity2D& from, const fusion::Similarity2D& to) {
  ObjectState moved = object;
  const auto in_drawing = from.inverse_transform_pose(object.body.pose());
  const auto cov = placed_cov(object.body.pose_cov(), to.theta_rad - from.theta_rad);
  moved.body = fusion::RigidObject(to.transform_pose(in_drawing), cov, scaled_edges(*object.plan, to.scale));
  return moved;
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
