#include "server/foxglove/messages.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <nlohmann/json.hpp>
#include <stdexcept>

#include "rules/action.h"

namespace wm::foxglove {
namespace {

using json = nlohmann::json;

constexpr int kFloat32 = 7;   // foxglove.NumericType FLOAT32
constexpr int kLineList = 2;  // foxglove.LineType LINE_LIST
constexpr int kDeleteMatchingId = 0, kDeleteAll = 1;
constexpr int kLogInfo = 2, kLogWarning = 3;
// Line width in screen pixels, whatever the zoom (the web viewer draws 2–2.5 px too).
constexpr double kLineThicknessPx = 2.0;

std::string dump(const json& j) { return j.dump(-1, ' ', false, json::error_handler_t::replace); }

json stamp_json(std::uint64_t ns) { return {{"sec", ns / 1'000'000'000u}, {"nsec", ns % 1'000'000'000u}}; }
json vector3_json(double x, double y, double z) { return {{"x", x}, {"y", y}, {"z", z}}; }
// Rotation by θ about z as a unit quaternion.
json yaw_json(double theta_rad) {
  return {{"x", 0.0}, {"y", 0.0}, {"z", std::sin(theta_rad / 2)}, {"w", std::cos(theta_rad / 2)}};
}
json identity_pose_json() { return {{"position", vector3_json(0, 0, 0)}, {"orientation", yaw_json(0)}}; }

// "#rrggbb" → components in [0, 1].
constexpr Rgba hex(std::uint32_t rgb) {
  return {((rgb >> 16) & 0xff) / 255.0, ((rgb >> 8) & 0xff) / 255.0, (rgb & 0xff) / 255.0, 1.0};
}

void check_fields(const fusion::GridGeometry& region, const std::vector<GridField>& fields, const char* function) {
  if (fields.empty()) throw std::invalid_argument(std::string(function) + ": no field");
  const auto cells = static_cast<std::size_t>(region.width() * region.height());
  for (const auto& f : fields)
    if (f.values.size() != cells)
      throw std::invalid_argument(std::string(function) + ": field '" + f.name + "' has " +
                                  std::to_string(f.values.size()) + " values for " + std::to_string(cells) + " cells");
}

}  // namespace

std::string base64(std::string_view bytes) {
  static constexpr char kAlphabet[] = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  out.reserve((bytes.size() + 2) / 3 * 4);
  std::size_t i = 0;
  for (; i + 3 <= bytes.size(); i += 3) {
    const std::uint32_t n = (std::uint32_t{static_cast<unsigned char>(bytes[i])} << 16) |
                            (std::uint32_t{static_cast<unsigned char>(bytes[i + 1])} << 8) |
                            static_cast<unsigned char>(bytes[i + 2]);
    out += kAlphabet[(n >> 18) & 63];
    out += kAlphabet[(n >> 12) & 63];
    out += kAlphabet[(n >> 6) & 63];
    out += kAlphabet[n & 63];
  }
  if (const auto rest = bytes.size() - i; rest > 0) {
    std::uint32_t n = std::uint32_t{static_cast<unsigned char>(bytes[i])} << 16;
    if (rest == 2) n |= std::uint32_t{static_cast<unsigned char>(bytes[i + 1])} << 8;
    out += kAlphabet[(n >> 18) & 63];
    out += kAlphabet[(n >> 12) & 63];
    out += rest == 2 ? kAlphabet[(n >> 6) & 63] : '=';
    out += '=';
  }
  return out;
}

std::string grid_message(const fusion::GridGeometry& region, const std::vector<GridField>& fields,
                         std::uint64_t stamp_ns) {
  check_fields(region, fields, "grid_message");
  const auto cells = static_cast<std::size_t>(region.width() * region.height());
  const std::size_t cell_stride = 4 * fields.size();
  std::string packed(cells * cell_stride, '\0');
  for (std::size_t f = 0; f < fields.size(); ++f) {
    const auto& values = fields[f].values;
    for (std::size_t i = 0; i < cells; ++i) {
      std::uint32_t bits = 0;
      std::memcpy(&bits, &values[i], 4);
      char* out = packed.data() + i * cell_stride + 4 * f;
      for (int b = 0; b < 4; ++b) out[b] = static_cast<char>((bits >> (8 * b)) & 0xff);  // little-endian
    }
  }
  json field_list = json::array();
  for (std::size_t f = 0; f < fields.size(); ++f)
    field_list.push_back({{"name", fields[f].name}, {"offset", 4 * f}, {"type", kFloat32}});
  const double r = region.resolution_m();
  std::string text = dump(
      {{"timestamp", stamp_json(stamp_ns)},
       {"frame_id", kMapFrame},
       {"pose",
        {{"position", vector3_json(region.origin_m().x(), region.origin_m().y(), 0)}, {"orientation", yaw_json(0)}}},
       {"column_count", region.width()},
       {"cell_size", {{"x", r}, {"y", r}}},
       {"row_stride", static_cast<std::size_t>(region.width()) * cell_stride},
       {"cell_stride", cell_stride},
       {"fields", std::move(field_list)}});
  // The cells go in last, written straight in: base64 needs no JSON escaping, and megabytes of it are not worth a
  // round through a JSON string node.
  text.pop_back();
  text += ",\"data\":\"";
  text += base64(packed);
  text += "\"}";
  return text;
}

std::int64_t coarsening_factor(std::int64_t width, std::int64_t height, std::size_t max_cells) {
  if (max_cells == 0) throw std::invalid_argument("coarsening_factor: max_cells is 0");
  if (width < 1 || height < 1) throw std::invalid_argument("coarsening_factor: an empty grid");
  std::int64_t k = 1;
  while (static_cast<std::size_t>(((width + k - 1) / k) * ((height + k - 1) / k)) > max_cells) ++k;
  return k;
}

std::pair<fusion::GridGeometry, std::vector<GridField>> coarsened(const fusion::GridGeometry& region,
                                                                  std::vector<GridField> fields, std::int64_t k) {
  if (k < 1) throw std::invalid_argument("coarsened: k < 1");
  check_fields(region, fields, "coarsened");
  if (k == 1) return {region, std::move(fields)};
  const std::int64_t w = region.width(), h = region.height();
  const std::int64_t cw = (w + k - 1) / k, ch = (h + k - 1) / k;
  const fusion::GridGeometry coarse(region.origin_m(), region.resolution_m() * static_cast<double>(k), cw, ch);
  for (auto& field : fields) {
    std::vector<float> out(static_cast<std::size_t>(cw * ch), std::nanf(""));
    for (std::int64_t y = 0; y < h; ++y)
      for (std::int64_t x = 0; x < w; ++x) {
        fusion::pool_max(out[static_cast<std::size_t>((y / k) * cw + x / k)],
                         field.values[static_cast<std::size_t>(y * w + x)]);
      }
    field.values = std::move(out);
  }
  return {coarse, std::move(fields)};
}

LineEntity element_entity(const world::Element& element) {
  // The web viewer's colours (clients/web/js/map_view.js, kColors.elements), so both views read alike.
  Rgba color = hex(0x6b6b6b);
  if (element.origin == "scan") color = hex(0xec6a00);
  if (element.origin == "grid") color = hex(0x9c36b5);
  if (element.origin == "client") color = hex(0x8d5524);
  return {element.id(),
          {{element.segment.p0(), element.segment.p1()}},
          color,
          {{"origin", element.origin}, {"observer", element.observer}, {"support", std::to_string(element.support)}}};
}

LineEntity object_entity(const world::ObjectState& object, const world::WorldOptions& options) {
  const auto& plan = *object.plan;
  const auto has = [&](const char* attribute) {
    return std::find(plan.attributes.begin(), plan.attributes.end(), attribute) != plan.attributes.end();
  };
  // kColors.objects of the web viewer: solid walls, rigid furniture, anything else.
  const Rgba color = has("solid") ? hex(0x2451a6) : has("not_deformable") ? hex(0x1e9e4a) : hex(0xc08a00);
  LineEntity entity{plan.id, {}, color, {{"kind", plan.kind}}};
  std::string attributes;
  for (const auto& a : plan.attributes) attributes += (attributes.empty() ? "" : ",") + a;
  entity.metadata.emplace_back("attributes", attributes);
  for (std::size_t k = 0; k < object.body.edges().size(); ++k) {
    const auto edge = world::apriori_edge(object, k, options);
    entity.segments.push_back({edge.p0(), edge.p1()});
  }
  return entity;
}

std::string scene_update_message(const std::vector<LineEntity>& entities, const std::vector<std::string>& deleted,
                                 bool replace_all, std::uint64_t stamp_ns) {
  const auto stamp = stamp_json(stamp_ns);
  json deletions = json::array();
  if (replace_all) deletions.push_back({{"timestamp", stamp}, {"type", kDeleteAll}, {"id", ""}});
  for (const auto& id : deleted) deletions.push_back({{"timestamp", stamp}, {"type", kDeleteMatchingId}, {"id", id}});
  json list = json::array();
  for (const auto& e : entities) {
    json points = json::array();
    for (const auto& [p0, p1] : e.segments) {
      points.push_back(vector3_json(p0.x(), p0.y(), 0));
      points.push_back(vector3_json(p1.x(), p1.y(), 0));
    }
    json metadata = json::array();
    for (const auto& [key, value] : e.metadata) metadata.push_back({{"key", key}, {"value", value}});
    list.push_back({{"timestamp", stamp},
                    {"frame_id", kMapFrame},
                    {"id", e.id},
                    {"lifetime", {{"sec", 0}, {"nsec", 0}}},  // zero: stays until replaced or deleted
                    {"frame_locked", false},
                    {"metadata", std::move(metadata)},
                    {"lines",
                     {{{"type", kLineList},
                       {"pose", identity_pose_json()},
                       {"thickness", kLineThicknessPx},
                       {"scale_invariant", true},
                       {"points", std::move(points)},
                       {"color", {{"r", e.color.r}, {"g", e.color.g}, {"b", e.color.b}, {"a", e.color.a}}},
                       {"colors", json::array()},
                       {"indices", json::array()}}}},
                    // Foxglove's schema requires every primitive list, empty or not.
                    {"arrows", json::array()},
                    {"cubes", json::array()},
                    {"spheres", json::array()},
                    {"cylinders", json::array()},
                    {"triangles", json::array()},
                    {"texts", json::array()},
                    {"models", json::array()}});
  }
  return dump({{"deletions", std::move(deletions)}, {"entities", std::move(list)}});
}

std::string pose_in_frame_message(double x_m, double y_m, double theta_rad, std::uint64_t stamp_ns) {
  return dump({{"timestamp", stamp_json(stamp_ns)},
               {"frame_id", kMapFrame},
               {"pose", {{"position", vector3_json(x_m, y_m, 0)}, {"orientation", yaw_json(theta_rad)}}}});
}

std::string frame_transforms_message(const std::vector<PlanarTransform>& transforms) {
  json list = json::array();
  for (const auto& t : transforms)
    list.push_back({{"timestamp", stamp_json(t.stamp_ns)},
                    {"parent_frame_id", t.parent_frame},
                    {"child_frame_id", t.child_frame},
                    {"translation", vector3_json(t.x_m, t.y_m, 0)},
                    {"rotation", yaw_json(t.theta_rad)}});
  return dump({{"transforms", std::move(list)}});
}

std::string log_message(const world::DecisionRecord& decision, std::uint64_t stamp_ns) {
  std::string text = "decision " + std::to_string(decision.seq) + ": " + std::string(rules::wire_name(decision.action));
  if (decision.element) text += " " + *decision.element;
  if (decision.object && decision.object != decision.element) text += " (object " + *decision.object + ")";
  text += " by " + (decision.observer.empty() ? std::string("?") : decision.observer) + " (" + decision.origin + "/" +
          decision.sensor + ")";
  if (decision.fallback) text += " [fallback]";
  if (!decision.explanation.empty()) text += ": " + decision.explanation;
  return dump({{"timestamp", stamp_json(stamp_ns)},
               {"level", decision.fallback ? kLogWarning : kLogInfo},
               {"message", text},
               {"name", decision.rule},
               {"file", ""},
               {"line", 0}});
}

}  // namespace wm::foxglove
