#include "apriori/import/layer_mapping.h"

#include <algorithm>
#include <cmath>
#include <nlohmann/json.hpp>

#include "apriori/floor_plan.h"
#include "apriori/import/json_limits.h"

namespace wm::apriori {
namespace {

// Ordered, so that "first match wins" follows the order of the file.
using Json = nlohmann::ordered_json;

char lower(char c) { return (c >= 'A' && c <= 'Z') ? static_cast<char>(c - 'A' + 'a') : c; }

bool is_attribute(std::string_view s) {
  return !s.empty() && s.size() <= 64 && s[0] >= 'a' && s[0] <= 'z' && std::all_of(s.begin(), s.end(), [](char c) {
    return (c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') || c == '_';
  });
}

bool has_control_characters(std::string_view s) {
  return std::any_of(s.begin(), s.end(), [](unsigned char c) { return c < 0x20 || c == 0x7f; });
}

std::string join(const std::string& path, const std::string& key) { return path.empty() ? key : path + "." + key; }

LayerRule parse_rule(const std::string& pattern, const Json& value, const std::string& path, bool is_block) {
  if (pattern.empty()) throw FloorPlanError(path, "empty pattern");
  if (!value.is_object()) throw FloorPlanError(path, "expected an object with \"kind\" or \"ignore\"");
  LayerRule rule;
  rule.pattern = pattern;
  for (const auto& [key, v] : value.items()) {
    const auto kpath = join(path, key);
    if (key == "kind") {
      if (!v.is_string()) throw FloorPlanError(kpath, "expected a string");
      rule.kind = v.get<std::string>();
      if (rule.kind.empty() || rule.kind.size() > 64 || has_control_characters(rule.kind) ||
          rule.kind.find('/') != std::string::npos)
        throw FloorPlanError(kpath, "a kind is 1..64 printable characters without '/'");
    } else if (key == "attributes") {
      if (!v.is_array()) throw FloorPlanError(kpath, "expected an array of attribute names");
      for (std::size_t i = 0; i < v.size(); ++i) {
        const auto apath = kpath + "[" + std::to_string(i) + "]";
        if (!v[i].is_string() || !is_attribute(v[i].get<std::string>()))
          throw FloorPlanError(apath, "attribute must match [a-z][a-z0-9_]* (at most 64 characters)");
        auto a = v[i].get<std::string>();
        if (std::find(rule.attributes.begin(), rule.attributes.end(), a) == rule.attributes.end())
          rule.attributes.push_back(std::move(a));
      }
    } else if (key == "cluster") {
      if (!v.is_boolean()) throw FloorPlanError(kpath, "expected true or false");
      if (is_block) throw FloorPlanError(kpath, "blocks are objects already; \"cluster\" applies to layers only");
      rule.cluster = v.get<bool>();
    } else if (key == "ignore") {
      if (!v.is_boolean()) throw FloorPlanError(kpath, "expected true or false");
      rule.ignore = v.get<bool>();
    } else if (key == "description") {
      if (!v.is_string()) throw FloorPlanError(kpath, "expected a string");
    } else {
      throw FloorPlanError(kpath, "unknown field (expected kind, attributes, cluster, ignore, description)");
    }
  }
  if (rule.ignore) {
    if (!rule.kind.empty() || !rule.attributes.empty() || rule.cluster)
      throw FloorPlanError(path, "an ignored layer takes no kind, attributes or cluster");
  } else if (rule.kind.empty()) {
    throw FloorPlanError(join(path, "kind"), "missing field (or set \"ignore\": true)");
  }
  return rule;
}

std::vector<LayerRule> parse_rules(const Json& value, const std::string& path, bool is_block) {
  if (!value.is_object()) throw FloorPlanError(path, "expected an object of pattern → rule");
  std::vector<LayerRule> rules;
  for (const auto& [pattern, rule] : value.items())
    rules.push_back(parse_rule(pattern, rule, join(path, pattern), is_block));
  return rules;
}

const LayerRule* first_match(const std::vector<LayerRule>& rules, std::string_view name) {
  for (const auto& rule : rules)
    if (glob_match(rule.pattern, name)) return &rule;
  return nullptr;
}

constexpr const char* kDefaultMapping = R"({
  "layers": {
    "0": {"ignore": true},
    "DEFPOINTS": {"ignore": true},
    "WALL*": {"kind": "wall", "attributes": ["solid"]},
    "COLUMN*": {"kind": "column", "attributes": ["solid"], "cluster": true},
    "PILLAR*": {"kind": "column", "attributes": ["solid"], "cluster": true},
    "CRYSTAL*": {"kind": "wall", "attributes": ["solid", "glass"]},
    "GLASS*": {"kind": "wall", "attributes": ["solid", "glass"]},
    "GLAZ*": {"kind": "wall", "attributes": ["solid", "glass"]},
    "WINDOW*": {"kind": "wall", "attributes": ["solid", "glass"]},
    "DOOR*": {"kind": "door", "attributes": ["movable"], "cluster": true},
    "FURN*": {"kind": "furniture", "attributes": ["not_deformable"], "cluster": true}
  },
  "blocks": {
    "TABLE*": {"kind": "table", "attributes": ["not_deformable"]},
    "DESK*": {"kind": "table", "attributes": ["not_deformable"]},
    "CHAIR*": {"kind": "chair", "attributes": ["not_deformable"]},
    "SOFA*": {"kind": "sofa", "attributes": ["not_deformable"]},
    "CABINET*": {"kind": "cabinet", "attributes": ["not_deformable"]},
    "SHELF*": {"kind": "shelf", "attributes": ["not_deformable"]},
    "BED*": {"kind": "bed", "attributes": ["not_deformable"]}
  },
  "cluster_tolerance_m": 0.02,
  "merge_enclosed_clusters": true,
  "unknown_layers": "report"
})";

}  // namespace

bool glob_match(std::string_view pattern, std::string_view text) {
  // Iterative matcher with one backtrack point (the last '*'): linear in practice, no recursion.
  std::size_t p = 0, t = 0, star = std::string_view::npos, star_text = 0;
  while (t < text.size()) {
    if (p < pattern.size() && (pattern[p] == '?' || lower(pattern[p]) == lower(text[t]))) {
      ++p;
      ++t;
    } else if (p < pattern.size() && pattern[p] == '*') {
      star = p++;
      star_text = t;
    } else if (star != std::string_view::npos) {
      p = star + 1;
      t = ++star_text;
    } else {
      return false;
    }
  }
  while (p < pattern.size() && pattern[p] == '*') ++p;
  return p == pattern.size();
}

const LayerRule* LayerMapping::match_layer(std::string_view layer) const { return first_match(layers, layer); }
const LayerRule* LayerMapping::match_block(std::string_view block_name) const {
  return first_match(blocks, block_name);
}

LayerMapping parse_layer_mapping_json(std::string_view text) {
  if (auto error = json_nesting_error(text)) throw FloorPlanError("", *error);
  Json doc;
  try {
    doc = Json::parse(text.begin(), text.end());
  } catch (const Json::exception& e) {
    throw FloorPlanError("", std::string("malformed JSON: ") + e.what());
  }
  if (!doc.is_object()) throw FloorPlanError("", "a layer mapping is a JSON object with \"layers\" and/or \"blocks\"");
  LayerMapping mapping;
  for (const auto& [key, v] : doc.items()) {
    if (key == "layers") {
      mapping.layers = parse_rules(v, "layers", false);
    } else if (key == "blocks") {
      mapping.blocks = parse_rules(v, "blocks", true);
    } else if (key == "cluster_tolerance_m") {
      if (!v.is_number()) throw FloorPlanError(key, "expected a number");
      const double tol = v.get<double>();
      if (!(std::isfinite(tol) && tol > 0.0 && tol <= 10.0)) throw FloorPlanError(key, "must be in (0, 10] metres");
      mapping.cluster_tolerance_m = tol;
    } else if (key == "merge_enclosed_clusters") {
      if (!v.is_boolean()) throw FloorPlanError(key, "expected true or false");
      mapping.merge_enclosed_clusters = v.get<bool>();
    } else if (key == "unknown_layers") {
      const std::string policy = v.is_string() ? v.get<std::string>() : std::string();
      if (policy == "report") {
        mapping.unknown_layers = UnknownLayerPolicy::kReport;
      } else if (policy == "ignore") {
        mapping.unknown_layers = UnknownLayerPolicy::kIgnore;
      } else if (policy == "error") {
        mapping.unknown_layers = UnknownLayerPolicy::kError;
      } else {
        throw FloorPlanError(key, "expected \"report\", \"ignore\" or \"error\"");
      }
    } else if (key == "description") {
      if (!v.is_string()) throw FloorPlanError(key, "expected a string");
    } else {
      throw FloorPlanError(key,
                           "unknown field (expected layers, blocks, cluster_tolerance_m, "
                           "merge_enclosed_clusters, unknown_layers, description)");
    }
  }
  return mapping;
}

LayerMapping default_layer_mapping() { return parse_layer_mapping_json(kDefaultMapping); }
std::string default_layer_mapping_json() { return kDefaultMapping; }

}  // namespace wm::apriori
