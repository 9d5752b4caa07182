// The floor plan: GET the loaded plan; PUT a JSON plan, a DXF drawing, an Open-RMF building.yaml, an AMRL vector
// map, or the import envelope {"import": {...}} that carries any of them.
#include <algorithm>
#include <array>
#include <utility>

#include "apriori/import/amrl_import.h"
#include "apriori/import/dxf_import.h"
#include "apriori/import/rmf_import.h"
#include "server/api/access.h"
#include "server/api/api_error.h"
#include "server/api/handlers.h"
#include "server/api/response.h"

namespace wm::api {
namespace {

// The options an import may carry, from the query string or the envelope.
struct ImportOptions {
  std::optional<std::string> units, level, name;
  std::optional<std::string> mapping_json;  // a layer mapping for DXF, in file order
};

// Units names for ?units= and "units" of an import envelope [m per unit].
double units_to_metres(const std::string& units, const std::string& path) {
  if (units == "m") return 1.0;
  if (units == "cm") return 0.01;
  if (units == "mm") return 0.001;
  if (units == "in") return 0.0254;
  if (units == "ft") return 0.3048;
  throw bad_request(path, "expected m, cm, mm, in or ft");
}

// An import of a CAD or robotics file: DXF (with a layer mapping), Open-RMF building.yaml or an AMRL vector map.
apriori::ImportResult import_plan(const std::string& format, std::string_view data, const ImportOptions& options,
                                  const ApiOptions& api) {
  if (format == "dxf") {
    apriori::DxfImportOptions o;
    o.limits = api.plan_limits;
    if (options.units) o.units_to_m = units_to_metres(*options.units, "import.units");
    if (options.name) o.name = *options.name;
    const auto mapping =
        options.mapping_json ? apriori::parse_layer_mapping_json(*options.mapping_json) : api.layer_mapping;
    return apriori::import_dxf(data, mapping, o);
  }
  if (format == "rmf") {
    apriori::RmfImportOptions o;
    o.limits = api.plan_limits;
    if (options.level) o.level = *options.level;
    if (options.name) o.name = *options.name;
    return apriori::import_rmf_building(data, o);
  }
  if (format == "amrl") {
    apriori::AmrlImportOptions o;
    o.limits = api.plan_limits;
    if (options.name) o.name = *options.name;
    return apriori::import_amrl_vectormap(data, o);
  }
  throw bad_request("import.format", "expected dxf, rmf or amrl");
}

// {"import": {"format": "dxf", "data": "<the file's text>", "mapping": {...}, "units": "mm", ...}}
apriori::ImportResult import_envelope(const nlohmann::ordered_json& spec, const ApiOptions& api) {
  if (!spec.is_object()) throw bad_request("import", "expected an object");
  for (const auto& [key, value] : spec.items())
    if (key != "format" && key != "data" && key != "mapping" && key != "units" && key != "level" && key != "name")
      throw bad_request("import." + key, "unknown field");
  if (!spec.contains("format") || !spec["format"].is_string())
    throw bad_request("import.format", "expected dxf, rmf or amrl");
  if (!spec.contains("data") || !spec["data"].is_string()) throw bad_request("import.data", "expected the file's text");
  ImportOptions options;
  using Field = std::pair<const char*, std::optional<std::string>*>;
  for (const auto& [key, field] :
       std::array<Field, 3>{{{"units", &options.units}, {"level", &options.level}, {"name", &options.name}}}) {
    if (!spec.contains(key)) continue;
    if (!spec[key].is_string()) throw bad_request(std::string("import.") + key, "expected a string");
    *field = spec[key].get<std::string>();
  }
  if (spec.contains("mapping")) {
    if (!spec["mapping"].is_object()) throw bad_request("import.mapping", "expected a layer mapping object");
    options.mapping_json = spec["mapping"].dump();
  }
  return import_plan(spec["format"].get<std::string>(), spec["data"].get<std::string>(), options, api);
}

// YAML is UTF-8 text: a body that is not is refused here with its line, before the importer.
void require_utf8_body(const std::string& body) {
  if (const auto at = json_codec::invalid_utf8_offset(body)) {
    const auto line = 1 + std::count(body.begin(), body.begin() + static_cast<std::ptrdiff_t>(*at), '\n');
    throw bad_request("body", "invalid UTF-8 at byte " + std::to_string(*at) + " (line " + std::to_string(line) +
                                  "); YAML is UTF-8 text");
  }
}

// Every name of a plan is stored and written as JSON: one that is not UTF-8 (from a file format that does not
// check it) is refused here, by field, instead of failing when it is written.
void require_utf8_names(const apriori::FloorPlan& plan) {
  const auto check = [](const std::string& text, const std::string& path) {
    if (const auto at = json_codec::invalid_utf8_offset(text))
      throw bad_request(path, "invalid UTF-8 at byte " + std::to_string(*at));
  };
  check(plan.name, "name");
  for (std::size_t i = 0; i < plan.objects.size(); ++i) {
    const auto path = "objects[" + std::to_string(i) + "]";
    check(plan.objects[i].id, path + ".id");
    check(plan.objects[i].kind, path + ".kind");
    for (std::size_t k = 0; k < plan.objects[i].attributes.size(); ++k)
      check(plan.objects[i].attributes[k], path + ".attributes[" + std::to_string(k) + "]");
  }
}

// The file in the body, by its Content-Type (and, for JSON, its shape); nullopt for a JSON floor plan.
std::optional<apriori::ImportResult> import_body(const Call& call) {
  const auto& request = call.request;
  const ImportOptions query_options{call.target.param("units"), call.target.param("level"), call.target.param("name"),
                                    std::nullopt};
  if (has_content_type(request, "image/vnd.dxf") || has_content_type(request, "application/dxf"))
    return import_plan("dxf", request.body(), query_options, call.options);
  if (has_content_type(request, "application/yaml") || has_content_type(request, "application/x-yaml")) {
    require_utf8_body(request.body());
    return import_plan("rmf", request.body(), query_options, call.options);
  }
  require_json_body(request);
  // Ordered: a layer mapping's rules apply in file order (first match wins).
  const auto doc = json_codec::parse_ordered_json(request.body());
  if (doc.is_object() && doc.contains("import")) return import_envelope(doc["import"], call.options);
  // An AMRL vector map is a bare array of lines.
  if (doc.is_array()) return import_plan("amrl", request.body(), query_options, call.options);
  return std::nullopt;
}

}  // namespace

Response get_floor_plan(const Call& call) {
  const auto snap = call.world.map.snapshot();
  apriori::FloorPlan plan{snap->plan_name, {}};
  for (const auto& o : snap->objects) plan.objects.push_back(*o.plan);
  // The plan as drawn, and where it sits in the world.
  auto answer = json_codec::parse_json(apriori::to_json_text(plan));
  answer["placement"] = json_codec::placement_json(snap->placement, snap->placement_cov);
  answer["georeference"] = json_codec::georeference_json(snap->georeference);
  return json_response(call.request, answer);
}

Response put_floor_plan(const Call& call) {
  require_token(call.request, call.options);
  if (call.request.body().empty()) throw bad_request("", "empty body");
  auto imported = import_body(call);
  auto plan = imported ? std::move(imported->plan)
                       : apriori::parse_floor_plan_json(call.request.body(), call.options.plan_limits);
  require_utf8_names(plan);
  std::size_t edges = 0;
  for (const auto& o : plan.objects) edges += o.edges().size();
  const auto objects = plan.objects.size();
  const auto name = plan.name;
  const auto version = call.world.plan.load_floor_plan(std::move(plan));
  nlohmann::json answer = {{"name", name}, {"objects", objects}, {"edges", edges}, {"version", version}};
  if (imported) answer["report"] = json_codec::parse_json(apriori::to_json_text(imported->report));
  return json_response(call.request, answer);
}

}  // namespace wm::api
