#include "server/api/map_json_writer.h"

#include <nlohmann/json.hpp>

#include "server/json/codec.h"

namespace wm::api {
namespace {

std::string dump(const nlohmann::json& value) {
  return value.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace);
}

}  // namespace

std::string MapJsonWriter::write(const world::WorldState& state, const world::WorldOptions& options,
                                 const std::string& instance) {
  std::lock_guard lock(mutex_);
  std::string out;
  out.reserve(64 * 1024);
  // Keys in the order nlohmann's std::map-backed objects dump them: alphabetical.
  out += "{\"elements\":[";
  std::map<std::int64_t, Fragment> elements;
  bool first = true;
  for (const auto& [number, element] : state.elements) {
    auto kept = elements_.extract(number);
    Fragment fragment = kept ? std::move(kept.mapped()) : Fragment{};
    if (fragment.updated_version != element.updated_version || fragment.text.empty()) {
      fragment.updated_version = element.updated_version;
      fragment.text = dump(json_codec::element_json(element));
    }
    if (!first) out += ',';
    first = false;
    out += fragment.text;
    elements.emplace_hint(elements.end(), number, std::move(fragment));
  }
  elements_ = std::move(elements);  // removed elements' texts go
  out += "],\"georeference\":";
  out += dump(json_codec::georeference_json(state.georeference));
  out += ",\"objects\":[";
  objects_.resize(state.objects.size());
  for (std::size_t i = 0; i < state.objects.size(); ++i) {
    const auto& object = state.objects[i];
    auto& fragment = objects_[i];
    if (fragment.updated_version != object.updated_version || fragment.identity != object.plan.get() ||
        fragment.text.empty()) {
      fragment = {object.updated_version, object.plan.get(), dump(json_codec::object_json(object, options))};
    }
    if (i > 0) out += ',';
    out += fragment.text;
  }
  out += "],\"placement\":";
  out += dump(json_codec::placement_json(state.placement, state.placement_cov));
  out += ",\"plan\":";
  out += dump(state.plan_name);
  out += ",\"server_instance\":";
  out += dump(instance);
  out += ",\"version\":";
  out += std::to_string(state.version);
  out += '}';
  return out;
}

}  // namespace wm::api
