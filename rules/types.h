#pragma once

// The knowledge base's value types: the facts it holds, the questions it answers and its answers. Plain C++,
// no Prolog: the world, storage and the JSON codec use them without linking SWI-Prolog (wm::rules_types).
#include <cstdint>
#include <optional>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

namespace wm::rules {

/// Error from the knowledge base: a rule file that does not load (one "file:line: text" line per
/// problem), a Prolog exception, or misuse (e.g. a call from a thread without a Prolog engine).
/// what() is human readable.
class RuleError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// One a-priori object of the floor plan, as the rules see it (wm_kb:object/2, attribute/2, edge/5).
struct ObjectFacts {
  std::string id;                       // unique, non-empty, not "none" (that atom means "not in the plan")
  std::string kind;                     // e.g. "wall", "table"
  std::vector<std::string> attributes;  // e.g. "solid", "not_deformable"
  /// An edge in the world frame, Hesse normal form x cos φ + y sin φ = ρ.
  struct Edge {
    std::string id;
    double rho_m;
    double phi_rad;
    double length_m;
  };
  std::vector<Edge> edges;
};

/// One observed line primitive and what the numeric matcher found for it.
struct DecisionQuery {
  std::string observer;  // the robot (or client) that observed it
  double rho_m = 0, phi_rad = 0, length_m = 0;
  std::optional<std::string> element_id;  // matched element (nullopt = unmatched)
  std::optional<std::string> object_id;   // a-priori object of that element (nullopt = not in the plan)
  double mahalanobis_sq = 0;              // squared Mahalanobis distance of the match, >= 0
  /// Context the rules read with observation_origin/1 and observation_sensor/1.
  std::string origin = "client";   // client | scan | grid
  std::string sensor = "unknown";  // laser | sonar | ... | unknown
};

/// One observed map element (not in the plan), as the rules see it (wm_kb:element/8):
/// element(Id, Origin, Observer, Rho, Phi, Length, Support, UpdatedAt).
struct ElementFacts {
  std::string id;        // e.g. "e12"
  std::string origin;    // client | scan | grid: how the element was observed
  std::string observer;  // e.g. "robot-1"
  double rho_m = 0, phi_rad = 0, length_m = 0;
  std::int64_t support = 1;      // observations fused into it
  double updated_at_unix_s = 0;  // wall-clock time of its last change [s]
};

/// What the occupancy grid says of an element (wm_kb:element_grid/3), from the server's last grid check of it:
/// element_grid(Id, Backed, Contrary) with the shares of its length that an occupied cell backs and that the grid
/// has seen without backing (the rest is unknown to the grid). Dropped when the element changes.
struct ElementGridFacts {
  std::string id;                   // e.g. "e12"
  double backed = 0, contrary = 0;  // [0, 1]
};

/// What the occupancy grid says of one edge of a plan object (wm_kb:edge_evidence/5, edge_seen_through/6 and
/// edge_beams/4), from the server's last grid check of it: edge_evidence(Object, Edge, Backed, SeenThrough, Observed)
/// with the shares of its length within one cell of an occupied cell, seen free with nothing occupied near, and seen
/// at all; and one edge_seen_through(Object, Edge, S0, S1, Through, Ended) per stretch seen through, [m] from the
/// edge's first end, with the beams counted passing through it and returning on it.
struct EdgeEvidenceFacts {
  std::string object_id;                              // e.g. "wall-12"
  std::string edge_id;                                // e.g. "wall-12/0", as edge/5 names it
  double backed = 0, seen_through = 0, observed = 0;  // [0, 1]
  struct Stretch {
    double s0_m = 0, s1_m = 0;                        // S0 < S1 [m]
    std::int64_t beams_through = 0, beams_ended = 0;  // beams counted passing through it, returning on it
  };
  std::vector<Stretch> stretches;
  /// Laser beams counted at the edge (edge_beams(Object, Edge, Through, Ended)): passed through it, returned on it.
  std::int64_t beams_through = 0, beams_ended = 0;
};

/// An edge of the plan by its ids, as edge/5 names it.
struct EdgeKey {
  std::string object_id, edge_id;
};

/// What the rules conclude about the plan from the evidence: verdict(Object, Edge, Verdict, S0, S1, Rule,
/// Explanation), from edge_verdict/5 and object_verdict/4 (verdict_override/5 first), e.g. an edge `missing` or
/// `partly_missing` over [S0, S1], an object `gone`.
struct VerdictFacts {
  std::string object_id;
  std::optional<std::string> edge_id;  // nullopt: about the whole object
  std::string verdict;                 // missing | partly_missing | gone | ...
  double s0_m = 0, s1_m = 0;           // the stretch concerned (edges; the whole edge unless partly_...)
  std::string rule, explanation;
};

/// One logged decision, as the rules see it (wm_kb:decision/7):
/// decision(Seq, Action, Rule, Element, Object, Observer, At) with `none` for a missing element/object.
struct DecisionFacts {
  std::int64_t seq = 0;
  std::string action, rule;
  std::optional<std::string> element, object;
  std::string observer;
  double at_unix_s = 0;
};

/// An element the rules' prune/3 asks to remove.
struct PruneOrder {
  std::string element_id;
  std::string rule;
  std::string explanation;
};

/// A value bound by a query: JSON-like, no Prolog types.
struct QueryValue {
  enum class Kind { unbound, atom, string, integer, floating, list, compound };
  Kind kind = Kind::unbound;
  std::string text;               // atom/string text; compound: the term as writeq/1 prints it
  std::int64_t integer = 0;       // Kind::integer (integers beyond 64 bits come as Kind::compound text)
  double floating = 0;            // Kind::floating
  std::vector<QueryValue> items;  // Kind::list
};

struct QueryResult {
  std::vector<std::string> variables;              // named variables of the goal, in order
  std::vector<std::vector<QueryValue>> solutions;  // one row per solution, values by variable
  bool truncated = false;                          // more solutions than asked for exist
};

/// A query the knowledge base refuses or cannot finish.
class QueryError : public RuleError {
 public:
  enum class Reason { syntax, unsafe, limit, failed };
  QueryError(Reason reason, const std::string& message) : RuleError(message), reason_(reason) {}
  Reason reason() const { return reason_; }

 private:
  Reason reason_;
};

/// A rule file given in memory (a candidate for a dry run).
struct RuleText {
  std::string name;  // file name, e.g. "world_model.pl"; replaces the file of that name, if any
  std::string text;
};

/// The rules' answer for one observation, as they gave it.
struct Decision {
  /// The atom the rules answered: delete | merge | rigid_adjust | add | ignore, or any other atom (the world
  /// turns an atom it does not know into the fallback add; see rules/action.h).
  std::string action;
  std::string rule;
  std::string explanation;
  bool fallback = false;  // true when the rules failed and the fallback "add" was used
};

struct RuleFile {
  std::string path;                // rules_dir / file name
  std::string sha256_or_checksum;  // SHA-256 (hex) of the text that was loaded
  std::int64_t loaded_at_unix_s;
};

struct RulesStatus {
  std::vector<RuleFile> files;  // the active rule files
  std::string last_error;       // last reload or decision error; cleared by a successful reload
  std::int64_t generation;      // number of successful loads (1 after construction)
};

}  // namespace wm::rules
