#include "apriori/import/import_report.h"

#include <nlohmann/json.hpp>

namespace wm::apriori {

std::string to_json_text(const ImportReport& report) {
  using nlohmann::json;
  json layers = json::object();
  for (const auto& [name, layer] : report.layers)
    layers[name] = {
        {"entities", layer.entities}, {"objects", layer.objects}, {"rule", layer.rule}, {"status", layer.status}};
  json extent = nullptr;
  if (report.extent)
    extent = {{"min", {report.extent->min_m.x(), report.extent->min_m.y()}},
              {"max", {report.extent->max_m.x(), report.extent->max_m.y()}}};
  const json j = {{"format", report.format},
                  {"version", report.version},
                  {"units_to_m", report.units_to_m},
                  {"units_source", report.units_source},
                  {"entity_counts", report.entity_counts},
                  {"layers", layers},
                  {"unknown_layers", report.unknown_layers},
                  {"skipped", report.skipped},
                  {"block_inserts", report.block_inserts},
                  {"block_objects", report.block_objects},
                  {"clustered_objects", report.clustered_objects},
                  {"objects", report.objects},
                  {"extent", extent},
                  {"warnings", report.warnings}};
  // Names come from files (layers, blocks): never let a stray byte make the answer invalid JSON.
  return j.dump(-1, ' ', false, json::error_handler_t::replace);
}

}  // namespace wm::apriori
