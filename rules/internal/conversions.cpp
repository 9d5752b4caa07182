#include "rules/internal/conversions.h"

#include <cmath>
#include <cstdint>
#include <set>
#include <stdexcept>
#include <string_view>
#include <system_error>
#include <utility>

#include "rules/internal/prolog_api.h"

namespace wm::rules::internal {
namespace {

void require_finite(double value, const char* function, const char* what) {
  if (!std::isfinite(value)) {
    throw std::invalid_argument(std::string(function) + ": " + what + " is not finite");
  }
}

void put_optional_atom(term_t t, const std::optional<std::string>& text, atom_t none) {
  if (text) {
    put_atom(t, *text);
  } else {
    PL_put_atom(t, none);
  }
}

void put_element_fact(term_t t, const ElementFacts& e, const Vocabulary& v) {
  constexpr const char* kWhere = "set_elements";
  if (e.id.empty()) throw std::invalid_argument("set_elements: an element id is empty");
  require_finite(e.rho_m, kWhere, "rho_m");
  require_finite(e.phi_rad, kWhere, "phi_rad");
  require_finite(e.length_m, kWhere, "length_m");
  require_finite(e.updated_at_unix_s, kWhere, "updated_at_unix_s");
  term_t a = PL_new_term_refs(8);
  put_atom(a, e.id);
  put_atom(a + 1, e.origin);
  put_atom(a + 2, e.observer);
  put_float(a + 3, e.rho_m);
  put_float(a + 4, e.phi_rad);
  put_float(a + 5, e.length_m);
  put_int64(a + 6, e.support, kWhere);
  put_float(a + 7, e.updated_at_unix_s);
  put_functor(t, v.element_fact, a, kWhere);
}

// Text an answer may carry in total [bytes]; beyond it the query fails with a limit error.
constexpr std::size_t kMaxAnswerTextBytes = std::size_t{8} << 20;

void charge(std::size_t& used, const QueryValue& v) {
  used += v.text.size() + 16;
  if (used > kMaxAnswerTextBytes) {
    throw QueryError(QueryError::Reason::limit, "the answer is larger than " +
                                                    std::to_string(kMaxAnswerTextBytes >> 20) +
                                                    " MiB: ask for fewer solutions or smaller values");
  }
}

// The support module bounds answers (depth 64, 1000 list items per level) before they get here, so
// the recursion over nested lists stays shallow.
QueryValue query_value(term_t t, std::size_t& used) {
  QueryValue v;
  switch (PL_term_type(t)) {
    case PL_VARIABLE:
      v.kind = QueryValue::Kind::unbound;
      v.text = "_";
      break;
    case PL_ATOM:
    case PL_NIL:
      v.kind = QueryValue::Kind::atom;
      v.text = text_or_written(t);
      break;
    case PL_STRING:
      v.kind = QueryValue::Kind::string;
      v.text = text_of(t).value_or("");
      break;
    case PL_INTEGER: {
      int64_t value = 0;
      if (PL_get_int64(t, &value)) {
        v.kind = QueryValue::Kind::integer;
        v.integer = value;
      } else {
        v.kind = QueryValue::Kind::compound;
        v.text = written(t);
      }
      break;
    }
    case PL_FLOAT:
      v.kind = QueryValue::Kind::floating;
      if (!PL_get_float(t, &v.floating)) v.text = written(t);
      break;
    case PL_LIST_PAIR: {
      term_t list = PL_copy_term_ref(t);
      term_t head = PL_new_term_ref();
      v.kind = QueryValue::Kind::list;
      while (PL_get_list(list, head, list)) v.items.push_back(query_value(head, used));
      if (!PL_get_nil(list)) {  // a partial list: show it as written
        v.kind = QueryValue::Kind::compound;
        v.items.clear();
        v.text = written(t);
      }
      break;
    }
    default:
      v.kind = QueryValue::Kind::compound;
      v.text = written(t);
  }
  charge(used, v);
  return v;
}

}  // namespace

Vocabulary Vocabulary::lookup() {
  const auto f = [](const char* name, std::size_t arity) { return PL_new_functor(PL_new_atom(name), arity); };
  Vocabulary v;
  v.context = f("context", 2);
  v.case_ = f("case", 3);
  v.element_fact = f("element", 8);
  v.decision_fact = f("decision", 7);
  v.element_grid_fact = f("element_grid", 3);
  v.evidence = f("evidence", 8);
  v.minus = f("-", 2);
  v.stretch = f("stretch", 4);
  v.file = f("file", 2);
  v.text = f("text", 2);
  v.observation = f("observation", 4);
  v.element = f("element", 3);
  v.object = f("object", 4);
  v.edge = f("edge", 4);
  v.decision = f("decision", 3);
  v.error = f("error", 1);
  v.ok = f("ok", 1);
  v.none = PL_new_atom("none");
  return v;
}

void validate_objects(const std::vector<ObjectFacts>& objects) {
  constexpr const char* kFunction = "set_floor_plan";
  std::set<std::string_view> ids;
  for (const auto& object : objects) {
    if (object.id.empty()) throw std::invalid_argument("set_floor_plan: an object id is empty");
    if (object.id == "none") {
      throw std::invalid_argument("set_floor_plan: object id 'none' is reserved (it means \"not in the plan\")");
    }
    if (!ids.insert(object.id).second) {
      throw std::invalid_argument("set_floor_plan: duplicate object id '" + object.id + "'");
    }
    for (const auto& edge : object.edges) {
      require_finite(edge.rho_m, kFunction, "an edge rho_m");
      require_finite(edge.phi_rad, kFunction, "an edge phi_rad");
      require_finite(edge.length_m, kFunction, "an edge length_m");
    }
  }
}

void put_objects(term_t list, const std::vector<ObjectFacts>& objects, const Vocabulary& v) {
  constexpr const char* kWhere = "set_floor_plan";
  PL_put_nil(list);
  term_t object_term = PL_new_term_ref();
  term_t fields = PL_new_term_refs(4);
  term_t item = PL_new_term_ref();
  term_t edge_fields = PL_new_term_refs(4);
  for (auto object = objects.rbegin(); object != objects.rend(); ++object) {
    put_atom(fields, object->id);
    put_atom(fields + 1, object->kind);
    put_atoms(fields + 2, object->attributes);
    PL_put_nil(fields + 3);
    for (auto edge = object->edges.rbegin(); edge != object->edges.rend(); ++edge) {
      put_atom(edge_fields, edge->id);
      put_float(edge_fields + 1, edge->rho_m);
      put_float(edge_fields + 2, edge->phi_rad);
      put_float(edge_fields + 3, edge->length_m);
      put_functor(item, v.edge, edge_fields, kWhere);
      cons(fields + 3, item);
    }
    put_functor(object_term, v.object, fields, kWhere);
    cons(list, object_term);
  }
}

void validate_query(const DecisionQuery& query) {
  constexpr const char* kFunction = "decide";
  require_finite(query.rho_m, kFunction, "rho_m");
  require_finite(query.phi_rad, kFunction, "phi_rad");
  require_finite(query.length_m, kFunction, "length_m");
  require_finite(query.mahalanobis_sq, kFunction, "mahalanobis_sq");
  if (query.mahalanobis_sq < 0) throw std::invalid_argument("decide: mahalanobis_sq is negative");
  if (query.object_id && !query.element_id) {
    throw std::invalid_argument("decide: object_id is set but element_id is not");
  }
  if (query.object_id && *query.object_id == "none") {
    throw std::invalid_argument("decide: object_id 'none' is reserved (use nullopt for \"not in the plan\")");
  }
}

void put_case(term_t observation, term_t match, term_t context, const DecisionQuery& query, const Vocabulary& v) {
  constexpr const char* kWhere = "decide";
  term_t fields = PL_new_term_refs(4);
  put_atom(fields, query.observer);
  put_float(fields + 1, query.rho_m);
  put_float(fields + 2, query.phi_rad);
  put_float(fields + 3, query.length_m);
  put_functor(observation, v.observation, fields, kWhere);
  if (query.element_id) {
    term_t parts = PL_new_term_refs(3);
    put_atom(parts, *query.element_id);
    put_optional_atom(parts + 1, query.object_id, v.none);
    put_float(parts + 2, query.mahalanobis_sq);
    put_functor(match, v.element, parts, kWhere);
  } else {
    PL_put_atom(match, v.none);
  }
  term_t context_parts = PL_new_term_refs(2);
  put_atom(context_parts, query.origin);
  put_atom(context_parts + 1, query.sensor.empty() ? std::string_view("unknown") : std::string_view(query.sensor));
  put_functor(context, v.context, context_parts, kWhere);
}

void put_cases(term_t list, const std::vector<DecisionQuery>& queries, const Vocabulary& v, const char* where) {
  PL_put_nil(list);
  term_t item = PL_new_term_ref();
  term_t parts = PL_new_term_refs(3);
  for (auto query = queries.rbegin(); query != queries.rend(); ++query) {
    put_case(parts, parts + 1, parts + 2, *query, v);
    put_functor(item, v.case_, parts, where);
    cons(list, item);
  }
}

void put_element_facts(term_t list, const std::vector<ElementFacts>& elements, const Vocabulary& v) {
  term_t item = PL_new_term_ref();
  PL_put_nil(list);
  for (auto e = elements.rbegin(); e != elements.rend(); ++e) {
    put_element_fact(item, *e, v);
    cons(list, item);
  }
}

void put_element_grid_facts(term_t list, const std::vector<ElementGridFacts>& facts, const Vocabulary& v) {
  constexpr const char* kWhere = "set_element_grid";
  term_t item = PL_new_term_ref();
  term_t a = PL_new_term_refs(3);
  PL_put_nil(list);
  for (auto f = facts.rbegin(); f != facts.rend(); ++f) {
    if (f->id.empty()) throw std::invalid_argument("set_element_grid: an element id is empty");
    require_finite(f->backed, kWhere, "backed");
    require_finite(f->contrary, kWhere, "contrary");
    put_atom(a, f->id);
    put_float(a + 1, f->backed);
    put_float(a + 2, f->contrary);
    put_functor(item, v.element_grid_fact, a, kWhere);
    cons(list, item);
  }
}

void put_edge_evidence_facts(term_t list, const std::vector<EdgeEvidenceFacts>& facts, const Vocabulary& v) {
  constexpr const char* kWhere = "set_edge_evidence";
  term_t item = PL_new_term_ref();
  term_t a = PL_new_term_refs(8);
  term_t pair = PL_new_term_ref();
  term_t ends = PL_new_term_refs(4);
  PL_put_nil(list);
  for (auto f = facts.rbegin(); f != facts.rend(); ++f) {
    if (f->object_id.empty() || f->edge_id.empty()) throw std::invalid_argument("set_edge_evidence: an id is empty");
    require_finite(f->backed, kWhere, "backed");
    require_finite(f->seen_through, kWhere, "seen_through");
    require_finite(f->observed, kWhere, "observed");
    put_atom(a, f->object_id);
    put_atom(a + 1, f->edge_id);
    put_float(a + 2, f->backed);
    put_float(a + 3, f->seen_through);
    put_float(a + 4, f->observed);
    PL_put_nil(a + 5);
    for (auto s = f->stretches.rbegin(); s != f->stretches.rend(); ++s) {
      require_finite(s->s0_m, kWhere, "stretch");
      require_finite(s->s1_m, kWhere, "stretch");
      if (s->beams_through < 0 || s->beams_ended < 0)
        throw std::invalid_argument("set_edge_evidence: a beam count is negative");
      put_float(ends, s->s0_m);
      put_float(ends + 1, s->s1_m);
      put_int64(ends + 2, s->beams_through, kWhere);
      put_int64(ends + 3, s->beams_ended, kWhere);
      put_functor(pair, v.stretch, ends, kWhere);
      cons(a + 5, pair);
    }
    if (f->beams_through < 0 || f->beams_ended < 0)
      throw std::invalid_argument("set_edge_evidence: a beam count is negative");
    put_int64(a + 6, f->beams_through, kWhere);
    put_int64(a + 7, f->beams_ended, kWhere);
    put_functor(item, v.evidence, a, kWhere);
    cons(list, item);
  }
}

std::vector<VerdictFacts> read_verdicts(term_t list) {
  std::vector<VerdictFacts> verdicts;
  term_t rest = PL_copy_term_ref(list);
  term_t head = PL_new_term_ref();
  term_t part = PL_new_term_ref();
  while (PL_get_list(rest, head, rest)) {
    VerdictFacts verdict;
    std::optional<std::string> texts[7];
    double ends[2] = {0, 0};
    bool ok = true;
    for (int i = 0; i < 7 && ok; ++i) {
      ok = PL_get_arg(i + 1, head, part);
      if (!ok) break;
      if (i == 3 || i == 4) {
        ok = PL_get_float(part, &ends[i - 3]) && std::isfinite(ends[i - 3]);
      } else {
        texts[i] = text_of(part);
        ok = texts[i].has_value();
      }
    }
    if (!ok) throw RuleError("plan_verdicts: malformed verdict " + written(head));
    verdict.object_id = std::move(*texts[0]);
    if (*texts[1] != "none") verdict.edge_id = std::move(*texts[1]);  // edge ids are "<object>/<k>"
    verdict.verdict = std::move(*texts[2]);
    verdict.s0_m = ends[0];
    verdict.s1_m = ends[1];
    verdict.rule = std::move(*texts[5]);
    verdict.explanation = std::move(*texts[6]);
    verdicts.push_back(std::move(verdict));
  }
  return verdicts;
}

void put_decision_facts(term_t list, const std::vector<DecisionFacts>& decisions, const Vocabulary& v) {
  constexpr const char* kWhere = "add_decisions";
  term_t item = PL_new_term_ref();
  term_t a = PL_new_term_refs(7);
  PL_put_nil(list);
  for (auto r = decisions.rbegin(); r != decisions.rend(); ++r) {
    require_finite(r->at_unix_s, kWhere, "at_unix_s");
    put_int64(a, r->seq, kWhere);
    put_atom(a + 1, r->action);
    put_atom(a + 2, r->rule);
    put_optional_atom(a + 3, r->element, v.none);
    put_optional_atom(a + 4, r->object, v.none);
    put_atom(a + 5, r->observer);
    put_float(a + 6, r->at_unix_s);
    put_functor(item, v.decision_fact, a, kWhere);
    cons(list, item);
  }
}

void put_atoms(term_t list, const std::vector<std::string>& atoms) {
  term_t item = PL_new_term_ref();
  PL_put_nil(list);
  for (auto atom = atoms.rbegin(); atom != atoms.rend(); ++atom) {
    put_atom(item, *atom);
    cons(list, item);
  }
}

void put_rule_files(term_t list, const std::filesystem::path& rules_dir, const std::vector<std::string>& paths,
                    const RuleText* candidate, const Vocabulary& v) {
  constexpr const char* kWhere = "rules";
  term_t item = PL_new_term_ref();
  term_t file_args = PL_new_term_refs(2);
  PL_put_nil(list);
  bool candidate_placed = false;
  auto put_candidate = [&] {
    put_atom(file_args, (rules_dir / candidate->name).string());
    put_string(file_args + 1, candidate->text, kWhere);
    put_functor(item, v.text, file_args, kWhere);
    cons(list, item);
  };
  // Built back to front: files stay sorted by name, the candidate in its place.
  for (auto path = paths.rbegin(); path != paths.rend(); ++path) {
    const std::string name = std::filesystem::path(*path).filename().string();
    if (candidate && !candidate_placed && candidate->name >= name) {
      candidate_placed = true;
      put_candidate();
      if (candidate->name == name) continue;
    }
    // Read through the absolute path: Prolog's idea of the working directory may differ.
    put_atom(file_args, *path);
    std::error_code ec;
    const auto absolute = std::filesystem::absolute(*path, ec);
    put_atom(file_args + 1, ec ? *path : absolute.string());
    put_functor(item, v.file, file_args, kWhere);
    cons(list, item);
  }
  if (candidate && !candidate_placed) put_candidate();
}

DecisionOrError read_decision(term_t result, const Vocabulary& v) {
  term_t part = PL_new_term_ref();
  if (PL_is_functor(result, v.decision)) {
    std::optional<std::string> texts[3];
    for (int i = 0; i < 3; ++i) {
      if (PL_get_arg(i + 1, result, part)) texts[i] = text_of(part);
    }
    if (texts[0] && texts[1] && texts[2]) {
      return {Decision{std::move(*texts[0]), std::move(*texts[1]), std::move(*texts[2]), false}, ""};
    }
    return {std::nullopt, "malformed decision " + written(result)};
  }
  if (PL_is_functor(result, v.error) && PL_get_arg(1, result, part)) return {std::nullopt, text_or_written(part)};
  return {std::nullopt, "malformed decision " + written(result)};
}

std::vector<std::string> read_texts(term_t list) {
  std::vector<std::string> texts;
  term_t rest = PL_copy_term_ref(list);
  term_t head = PL_new_term_ref();
  while (PL_get_list(rest, head, rest)) texts.push_back(text_or_written(head));
  return texts;
}

std::vector<PruneOrder> read_prune_orders(term_t list) {
  std::vector<PruneOrder> orders;
  term_t rest = PL_copy_term_ref(list);
  term_t head = PL_new_term_ref();
  term_t part = PL_new_term_ref();
  while (PL_get_list(rest, head, rest)) {
    std::optional<std::string> texts[3];
    for (int i = 0; i < 3; ++i) {
      if (PL_get_arg(i + 1, head, part)) texts[i] = text_of(part);
    }
    if (!texts[0] || !texts[1] || !texts[2]) throw RuleError("prune_orders: malformed order " + written(head));
    orders.push_back({std::move(*texts[0]), std::move(*texts[1]), std::move(*texts[2])});
  }
  return orders;
}

QueryResult read_query_answer(term_t result) {
  atom_t name = 0;
  std::size_t arity = 0;
  if (!PL_get_name_arity(result, &name, &arity)) throw RuleError("query: malformed answer " + written(result));
  const std::string kind = PL_atom_chars(name);
  term_t part = PL_new_term_ref();
  if (kind != "ok") {
    const std::string message = PL_get_arg(1, result, part) ? text_or_written(part) : written(result);
    const auto reason = kind == "syntax"   ? QueryError::Reason::syntax
                        : kind == "unsafe" ? QueryError::Reason::unsafe
                        : kind == "limit"  ? QueryError::Reason::limit
                                           : QueryError::Reason::failed;
    throw QueryError(reason, message);
  }
  QueryResult answer;
  term_t list = PL_new_term_ref();
  term_t head = PL_new_term_ref();
  if (!PL_get_arg(1, result, list)) throw RuleError("query: malformed answer");
  while (PL_get_list(list, head, list)) answer.variables.push_back(text_of(head).value_or("?"));
  if (!PL_get_arg(2, result, list)) throw RuleError("query: malformed answer");
  term_t row = PL_new_term_ref();
  std::size_t used = 0;
  while (PL_get_list(list, row, list)) {
    std::vector<QueryValue> values;
    while (PL_get_list(row, head, row)) values.push_back(query_value(head, used));
    answer.solutions.push_back(std::move(values));
  }
  int truncated = 0;
  if (PL_get_arg(3, result, part) && PL_get_bool(part, &truncated)) answer.truncated = truncated != 0;
  return answer;
}

}  // namespace wm::rules::internal
