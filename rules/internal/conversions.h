#pragma once

// Conversions between the value types of rules/types.h and the terms the support module
// (engine_support.pl) takes and answers. Internal to rules::Engine; every function runs on a thread
// with an attached Prolog engine, inside the caller's Frame, and the terms it builds live until that
// Frame ends.
//
// Validation of the values (finite numbers, reserved ids) happens here too, before any term is built,
// so that a refused value leaves no half-built term behind.

#include <SWI-Prolog.h>

#include <cstddef>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "rules/types.h"

namespace wm::rules::internal {

/// The functors and atoms of the support module's term shapes, looked up once per Engine. The handles
/// are process-wide in SWI-Prolog (valid on every thread) and never released.
struct Vocabulary {
  functor_t context = 0;            // context(Origin, Sensor)
  functor_t case_ = 0;              // case(Observation, Match, Context)
  functor_t element_fact = 0;       // element(Id, Source, Observer, Rho, Phi, Length, Support, UpdatedAt)
  functor_t decision_fact = 0;      // decision(Seq, Action, Rule, Element, Object, Observer, At)
  functor_t element_grid_fact = 0;  // element_grid(Id, Backed, Contrary)
  functor_t evidence = 0;           // evidence(Object, Edge, Backed, SeenThrough, Observed, Stretches, Through, Ended)
  functor_t minus = 0;              // Object-Edge
  functor_t stretch = 0;            // stretch(S0, S1, Beams)
  functor_t file = 0;               // file(Path, AbsolutePath)
  functor_t text = 0;               // text(Path, Text)
  functor_t observation = 0;        // observation(Source, Rho, Phi, Length)
  functor_t element = 0;            // element(ElementId, ObjectId, D2), a match
  functor_t object = 0;             // object(Id, Kind, Attributes, Edges)
  functor_t edge = 0;               // edge(Id, Rho, Phi, Length)
  functor_t decision = 0;           // decision(Action, Rule, Explanation), a result
  functor_t error = 0;              // error(Message)
  functor_t ok = 0;                 // ok(Value)
  atom_t none = 0;                  // `none`: no match, not in the plan

  /// Looks every handle up (needs an initialised runtime).
  static Vocabulary lookup();
};

/// @throw std::invalid_argument for an empty, duplicate or "none" object id or a non-finite edge number
///        (messages start with "set_floor_plan: ").
void validate_objects(const std::vector<ObjectFacts>& objects);
/// Puts the list of object(Id, Kind, Attributes, Edges) terms, in order. @throw RuleError when out of stack.
void put_objects(term_t list, const std::vector<ObjectFacts>& objects, const Vocabulary& v);

/// @throw std::invalid_argument for a non-finite number, a negative mahalanobis_sq, an object_id without
///        element_id, or object_id "none" (messages start with "decide: ").
void validate_query(const DecisionQuery& query);
/// Puts the three arguments of one case: observation/4, the match (element/3 or none), context/2.
void put_case(term_t observation, term_t match, term_t context, const DecisionQuery& query, const Vocabulary& v);
/// Puts the list of case(Observation, Match, Context) terms, in order; `where` names the caller in errors.
void put_cases(term_t list, const std::vector<DecisionQuery>& queries, const Vocabulary& v, const char* where);

/// Puts the list of element/8 facts, in order. @throw std::invalid_argument for an empty id or a
/// non-finite number (messages start with "set_elements: ").
void put_element_facts(term_t list, const std::vector<ElementFacts>& elements, const Vocabulary& v);
/// Puts the list of decision/7 facts, in order. @throw std::invalid_argument for a non-finite at_unix_s.
void put_element_grid_facts(term_t list, const std::vector<ElementGridFacts>& facts, const Vocabulary& v);
/// Puts the list of evidence/8 terms, in order. @throw std::invalid_argument for an empty id or a non-finite number.
void put_edge_evidence_facts(term_t list, const std::vector<EdgeEvidenceFacts>& facts, const Vocabulary& v);
/// Reads a list of verdict(Object, Edge, Verdict, S0, S1, Rule, Explanation) (Edge `none` for an object).
/// @throw RuleError for a malformed item.
std::vector<VerdictFacts> read_verdicts(term_t list);
void put_decision_facts(term_t list, const std::vector<DecisionFacts>& decisions, const Vocabulary& v);
/// Puts a list of atoms, in order.
void put_atoms(term_t list, const std::vector<std::string>& atoms);

/// Puts the rule files to load: file(Path, AbsolutePath) for each path, sorted by file name as given,
/// with text(rules_dir/Name, Text) for `candidate` replacing the file of its name or in its sorted
/// place. `candidate` may be null.
void put_rule_files(term_t list, const std::filesystem::path& rules_dir, const std::vector<std::string>& paths,
                    const RuleText* candidate, const Vocabulary& v);

/// A decision/3 result read, or the error it stands for.
struct DecisionOrError {
  std::optional<Decision> decision;  // set when the term is decision(Action, Rule, Explanation)
  std::string error;                 // otherwise: the message of error(Message), or what is malformed
};

/// Reads decision(Action, Rule, Explanation) or error(Message).
DecisionOrError read_decision(term_t result, const Vocabulary& v);

/// The elements of a list of atoms or strings as text (other terms as written()).
std::vector<std::string> read_texts(term_t list);

/// Reads a list of prune(ElementId, Rule, Explanation). @throw RuleError for a malformed order.
std::vector<PruneOrder> read_prune_orders(term_t list);

/// Reads the answer of wm_engine:query/5: ok(Names, Rows, Truncated) or syntax|unsafe|limit|error(Message).
/// @throw QueryError for every answer but ok/3, and with Reason::limit when the answer's text exceeds
///        8 MiB; RuleError for a malformed answer.
QueryResult read_query_answer(term_t result);

}  // namespace wm::rules::internal
