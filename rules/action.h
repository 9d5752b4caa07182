#pragma once

// What a decision does to the map, as the server applies it. The rules answer an atom (rules::Decision::action);
// parse_action() turns it into an Action once, where the world applies the decision, and wire_name() gives the
// atom back for the decision log, JSON and the knowledge base's decision/7 facts.
#include <array>
#include <optional>
#include <string_view>
#include <utility>

namespace wm::rules {

enum class Action {
  /// Wire name "delete", the seed paper's word: the observation only confirms what the map already holds (a
  /// solid wall of the plan, or an element), so it is not added; the matched object or element counts one more
  /// confirmation. Nothing is removed from the map.
  confirm,
  merge,         // Kalman-fuse the observation into the matched element (or start one from a matched CAD edge)
  rigid_adjust,  // EKF update of the matched not-deformable object's pose from the observed edge
  add,           // keep the observation as a new element
  ignore,        // change nothing
  prune,         // remove an element the rules' prune/3 named (not an answer of decide/5)
  trim,          // cut an element's ends back to what the occupancy grid backs (not an answer of decide/5)
  place,         // the floor plan's placement in the world changed (not an answer of decide/5)
  accept,        // a person accepted a change into the plan: a new version of the plan (not an answer of decide/5)
  reject,        // a person rejected a change: it is no longer listed (not an answer of decide/5)
  undo,          // a person undid the last accept or reject (not an answer of decide/5)
};

namespace detail {
inline constexpr std::array<std::pair<Action, std::string_view>, 11> kActionNames{{
    {Action::confirm, "delete"},
    {Action::merge, "merge"},
    {Action::rigid_adjust, "rigid_adjust"},
    {Action::add, "add"},
    {Action::ignore, "ignore"},
    {Action::prune, "prune"},
    {Action::trim, "trim"},
    {Action::place, "place"},
    {Action::accept, "accept"},
    {Action::reject, "reject"},
    {Action::undo, "undo"},
}};
}  // namespace detail

/// The atom the rules, the decision log and the JSON API use for `action`.
constexpr std::string_view wire_name(Action action) {
  for (const auto& [value, name] : detail::kActionNames)
    if (value == action) return name;
  return "unknown";
}

/// The Action of a wire name; nullopt for an atom the server does not know.
constexpr std::optional<Action> parse_action(std::string_view name) {
  for (const auto& [value, wire] : detail::kActionNames)
    if (wire == name) return value;
  return std::nullopt;
}

}  // namespace wm::rules
