#pragma once

#include <string>
#include <string_view>
#include <vector>

namespace wm::apriori {

/// What a CAD layer (or block name) becomes in the floor plan.
/// Invariant (after parse_layer_mapping_json): `pattern` is not empty; unless `ignore`, `kind` is not empty and
/// every attribute matches [a-z][a-z0-9_]* (they become Prolog atoms); `ignore` rules have no kind.
struct LayerRule {
  std::string pattern;                  // glob, case-insensitive: '*' any run of characters, '?' one character
  bool ignore = false;                  // drop everything matched (construction lines, floor grids, title blocks)
  std::string kind;                     // the objects' kind: "wall", "door", "furniture", "table", ...
  std::vector<std::string> attributes;  // e.g. {"solid"}, {"not_deformable"}, {"solid", "glass"}
  bool cluster = false;                 // layers only: group loose entities that touch into one object each
};

/// What to do with entities on a layer that no rule matches.
enum class UnknownLayerPolicy {
  kReport,  // skip them and list the layer in ImportReport::unknown_layers
  kIgnore,  // skip them silently (still counted per layer)
  kError,   // refuse the drawing (FloorPlanError naming the layer)
};

/// Layer and block-name mapping of a CAD import: the first rule (in file order) whose pattern matches wins.
///
/// JSON form (parse_layer_mapping_json):
///   {"layers": {"WALL*": {"kind": "wall", "attributes": ["solid"]},
///               "FURN*": {"kind": "furniture", "attributes": ["not_deformable"], "cluster": true},
///               "0": {"ignore": true}},
///    "blocks": {"TABLE*": {"kind": "table", "attributes": ["not_deformable"]}},
///    "cluster_tolerance_m": 0.02, "merge_enclosed_clusters": true, "unknown_layers": "report"}
/// Every key is optional except that a rule needs "kind" or "ignore": true; unknown keys are errors.
struct LayerMapping {
  std::vector<LayerRule> layers;
  std::vector<LayerRule> blocks;  // matched against INSERTed block names; a match makes one object per INSERT
  /// Two entities of a cluster layer belong to the same object when their geometry comes this close [m].
  double cluster_tolerance_m = 0.02;
  /// After clustering, a cluster lying entirely inside the bounding box of a larger cluster of the same layer
  /// joins it: real drawings put loose details (the buttons of a cushion) inside an object's outline.
  bool merge_enclosed_clusters = true;
  UnknownLayerPolicy unknown_layers = UnknownLayerPolicy::kReport;

  /// The first layer rule matching `layer`, or nullptr.
  const LayerRule* match_layer(std::string_view layer) const;
  /// The first block rule matching `block_name`, or nullptr.
  const LayerRule* match_block(std::string_view block_name) const;
};

/// Case-insensitive (ASCII) glob match of the whole `text`: '*' matches any run (also empty), '?' one byte.
bool glob_match(std::string_view pattern, std::string_view text);

/// Parses and validates the JSON mapping above.
/// @throw FloorPlanError with the path of the first bad field, e.g. "layers.WALL*.attributes[1]".
LayerMapping parse_layer_mapping_json(std::string_view text);

/// The built-in mapping, for drawings with the usual English architectural layer names (and the Barcelona
/// pavilion's): WALL* → wall {solid}; COLUMN*, PILLAR* → column {solid}, clustered; CRYSTAL*, GLASS*, GLAZ*,
/// WINDOW* → wall {solid, glass}; DOOR* → door {movable}, clustered; FURN* → furniture {not_deformable},
/// clustered; "0", DEFPOINTS → ignored; blocks TABLE*, DESK*, CHAIR*, SOFA*, CABINET*, SHELF*, BED* →
/// {not_deformable} objects; other layers reported. The JSON text of this mapping is default_layer_mapping_json().
LayerMapping default_layer_mapping();
std::string default_layer_mapping_json();

}  // namespace wm::apriori
