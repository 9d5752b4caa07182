#include "rules/engine.h"

#include <SWI-Prolog.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <map>
#include <mutex>
#include <set>
#include <stdexcept>
#include <string>
#include <system_error>
#include <utility>

#include "rules/internal/conversions.h"
#include "rules/internal/prolog_api.h"
#include "rules/internal/runtime.h"
#include "rules/internal/text_checks.h"

// The engine's lifecycle (runtime, support module, attachment) and its public methods: each checks
// its arguments, builds the support module's arguments with internal/conversions.h, calls one entry
// point of engine_support.pl and reads the answer back. Status bookkeeping (files, hashes, last error,
// generation) lives here too.

namespace wm::rules {
namespace {

using internal::call_once;
using internal::call_or_throw;
using internal::Frame;
using internal::put_atom;
using internal::put_float;
using internal::put_int64;
using internal::require_attached;

// The knowledge bases of the Engines alive in this process: the SWI-Prolog runtime is per process, so which module
// holds which Engine's facts is a process-wide fact; this set is the only global state of the module.
struct LiveKnowledgeBases {
  std::mutex mutex;
  std::set<std::string> names;
};
LiveKnowledgeBases& live_knowledge_bases() {
  static LiveKnowledgeBases live;
  return live;
}

// A knowledge base's module name: "wm_kb", or "wm_kb_" and 1-48 of [a-z0-9_], so that no name an Engine takes can be a
// module of SWI-Prolog's or of the rules.
bool valid_knowledge_base(const std::string& name) {
  constexpr std::string_view kPrefix = "wm_kb";
  if (name == kPrefix) return true;
  if (name.size() < kPrefix.size() + 2 || name.size() > kPrefix.size() + 49 || name.compare(0, 6, "wm_kb_") != 0)
    return false;
  return std::all_of(name.begin() + 6, name.end(),
                     [](char c) { return (c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') || c == '_'; });
}

std::int64_t unix_now_s() {
  return std::chrono::duration_cast<std::chrono::seconds>(std::chrono::system_clock::now().time_since_epoch()).count();
}

// What decide() answers when the rules fail: adding keeps the observation and touches nothing else.
Decision fallback_decision(const std::string& error) {
  return Decision{"add", "fallback", "rules failed: " + error, true};
}

// "line\nline..." of a list of problem texts, or `otherwise` when there is none.
std::string joined_lines(const std::vector<std::string>& lines, const char* otherwise) {
  std::string message;
  for (const auto& line : lines) {
    if (!message.empty()) message += '\n';
    message += line;
  }
  return message.empty() ? otherwise : message;
}

// The support module's entry points (rules/internal/engine_support.pl), looked up once. Each takes the engine's
// knowledge base (a module name) before the arguments listed here.
struct EntryPoints {
  predicate_t init = nullptr;               // init
  predicate_t shutdown = nullptr;           // shutdown
  predicate_t set_floor_plan = nullptr;     // set_floor_plan(+Objects)
  predicate_t set_elements = nullptr;       // set_elements(+Elements)
  predicate_t update_elements = nullptr;    // update_elements(+Upserts, +RemovedIds)
  predicate_t add_decisions = nullptr;      // add_decisions(+Decisions, +KeepLast)
  predicate_t set_element_grid = nullptr;   // set_element_grid(+Facts)
  predicate_t set_edge_evidence = nullptr;  // set_edge_evidence(+Facts, +ReplaceAll)
  predicate_t verdicts = nullptr;           // verdicts(+Scope, +Max, +InfLimit, +TimeLimit, -Result)
  predicate_t decide = nullptr;             // decide(+Observation, +Match, +Context, +InfLimit, +TimeLimit, -Result)
  predicate_t decide_batch = nullptr;       // decide_batch(+Cases, +InfLimit, +TimeLimit, -Results)
  predicate_t reload = nullptr;             // reload(+Files, +RulesDir, +InfLimit, +TimeLimit, +Grace, -Result)
  predicate_t dry_run = nullptr;            // dry_run(+Files, +RulesDir, +Cases, +InfLimit, +TimeLimit, -Result)
  predicate_t prune = nullptr;              // prune(+Max, +InfLimit, +TimeLimit, -Result)
  predicate_t query = nullptr;              // query(+Text, +MaxSolutions, +InfLimit, +TimeLimit, -Result)

  static EntryPoints lookup() {
    const auto p = [](const char* name, int arity) { return PL_predicate(name, arity, internal::kSupportModuleName); };
    return {.init = p("init", 1),
            .shutdown = p("shutdown", 1),
            .set_floor_plan = p("set_floor_plan", 2),
            .set_elements = p("set_elements", 2),
            .update_elements = p("update_elements", 3),
            .add_decisions = p("add_decisions", 3),
            .set_element_grid = p("set_element_grid", 2),
            .set_edge_evidence = p("set_edge_evidence", 3),
            .verdicts = p("verdicts", 6),
            .decide = p("decide", 7),
            .decide_batch = p("decide_batch", 5),
            .reload = p("reload", 7),
            .dry_run = p("dry_run", 7),
            .prune = p("prune", 5),
            .query = p("query", 6)};
  }
};

}  // namespace

struct Engine::Impl {
  explicit Impl(const EngineOptions& o) : options(o) {}

  const EngineOptions options;
  bool attached_by_constructor = false;
  EntryPoints entry;
  internal::Vocabulary vocabulary;

  std::mutex reload_mutex;  // one reload at a time
  mutable std::mutex status_mutex;
  RulesStatus status{{}, "", 0};

  void set_last_error(std::string error) {
    std::lock_guard lock(status_mutex);
    status.last_error = std::move(error);
  }

  // The decision a decision/3 | error/1 result stands for; an error becomes the fallback and last_error.
  Decision decision_of(term_t result) {
    auto read = internal::read_decision(result, vocabulary);
    if (read.decision) return std::move(*read.decision);
    set_last_error(read.error);
    return fallback_decision(read.error);
  }

  // The arguments of an entry point: the knowledge base first, then `n` more, the first of which is returned;
  // `call` is set to the whole vector, to pass to the entry point.
  term_t kb_args(int n, term_t& call) const {
    call = PL_new_term_refs(n + 1);
    put_atom(call, options.knowledge_base);
    return call + 1;
  }

  // Puts the engine's inference and time limits as two consecutive arguments.
  void put_limits(term_t args, double time_limit_s, const char* where) const {
    put_int64(args, options.inference_limit, where);
    put_float(args + 1, time_limit_s);
  }

  // Every regular *.pl file directly in the rules directory, sorted by name (see EngineOptions).
  std::vector<std::string> rule_files() const;
};

namespace {

// The rule files directly in `dir` by name (see EngineOptions). A missing directory is an error unless
// `missing_is_empty`.
std::map<std::string, std::filesystem::path> rule_files_in(const std::filesystem::path& dir, bool missing_is_empty) {
  std::map<std::string, std::filesystem::path> found;
  std::error_code ec;
  if (missing_is_empty && !std::filesystem::exists(dir, ec)) return found;
  std::filesystem::directory_iterator it(dir, ec);
  if (ec) throw RuleError(dir.string() + ":0: cannot read the rules directory: " + ec.message());
  for (const auto& entry : it) {
    const std::string name = entry.path().filename().string();
    if (name.empty() || name.front() == '.' || entry.path().extension() != ".pl") continue;
    std::error_code type_ec;
    if (!entry.is_regular_file(type_ec)) continue;
    found.emplace(name, entry.path());
  }
  return found;
}

}  // namespace

std::vector<std::string> Engine::Impl::rule_files() const {
  auto files = rule_files_in(options.rules_dir, false);
  if (!options.map_rules_dir.empty())
    for (auto& [name, path] : rule_files_in(options.map_rules_dir, true)) files[name] = std::move(path);
  std::vector<std::string> paths;  // sorted by file name: the map's files in their places
  paths.reserve(files.size());
  for (const auto& [name, path] : files) paths.push_back(path.string());
  return paths;
}

Engine::Engine(const EngineOptions& options) {
  if (options.inference_limit <= 0) {
    throw std::invalid_argument("Engine: inference_limit must be > 0");
  }
  if (!std::isfinite(options.time_limit_s) || options.time_limit_s <= 0) {
    throw std::invalid_argument("Engine: time_limit_s must be finite and > 0");
  }
  if (!valid_knowledge_base(options.knowledge_base)) {
    throw std::invalid_argument("Engine: knowledge_base must be \"wm_kb\" or \"wm_kb_\" and 1-48 of [a-z0-9_] (got \"" +
                                options.knowledge_base + "\")");
  }
  {
    auto& live = live_knowledge_bases();
    std::lock_guard lock(live.mutex);
    if (!live.names.insert(options.knowledge_base).second) {
      throw RuleError("Engine: knowledge base " + options.knowledge_base + " belongs to another Engine");
    }
  }
  const auto release_name = [&options] {
    auto& live = live_knowledge_bases();
    std::lock_guard lock(live.mutex);
    live.names.erase(options.knowledge_base);
  };
  try {
    impl_ = std::make_unique<Impl>(options);
    internal::initialise_runtime();
    if (PL_thread_self() < 0) {
      if (PL_thread_attach_engine(nullptr) < 0) throw RuleError("Engine: cannot attach a Prolog engine");
      impl_->attached_by_constructor = true;
    }
    impl_->entry = EntryPoints::lookup();
    impl_->vocabulary = internal::Vocabulary::lookup();
    internal::load_support_module();
    {
      Frame frame;
      term_t call;
      impl_->kb_args(0, call);
      call_or_throw(impl_->entry.init, call, "Engine");
    }
    reload();
  } catch (...) {
    if (impl_ && impl_->attached_by_constructor) PL_thread_destroy_engine();
    release_name();
    throw;
  }
}

Engine::~Engine() {
  bool attached_here = false;
  if (PL_thread_self() < 0) attached_here = PL_thread_attach_engine(nullptr) >= 0;
  if (PL_thread_self() >= 0) {
    Frame frame;
    term_t call;
    impl_->kb_args(0, call);
    (void)call_once(impl_->entry.shutdown, call);
  }
  if (attached_here) PL_thread_destroy_engine();
  auto& live = live_knowledge_bases();
  std::lock_guard lock(live.mutex);
  live.names.erase(impl_->options.knowledge_base);
  // The thread keeps its Prolog engine while another Engine may still be used on it.
  if (impl_->attached_by_constructor && live.names.empty()) PL_thread_destroy_engine();
}

void Engine::set_floor_plan(const std::vector<ObjectFacts>& objects) {
  require_attached("set_floor_plan");
  internal::validate_objects(objects);
  Frame frame;
  term_t call;
  term_t list = impl_->kb_args(1, call);
  internal::put_objects(list, objects, impl_->vocabulary);
  call_or_throw(impl_->entry.set_floor_plan, call, "set_floor_plan");
}

Decision Engine::decide(const DecisionQuery& query) {
  require_attached("decide");
  internal::validate_query(query);
  Impl& d = *impl_;
  Frame frame;
  // decide(+Observation, +Match, +Context, +InferenceLimit, +TimeLimit, -Result)
  term_t call;
  term_t args = d.kb_args(6, call);
  internal::put_case(args, args + 1, args + 2, query, d.vocabulary);
  d.put_limits(args + 3, d.options.time_limit_s, "decide");
  if (auto call_error = call_once(d.entry.decide, call)) {
    d.set_last_error(*call_error);
    return fallback_decision(*call_error);
  }
  return d.decision_of(args + 5);
}

std::vector<Decision> Engine::decide_batch(const std::vector<DecisionQuery>& queries) {
  require_attached("decide_batch");
  for (const auto& query : queries) internal::validate_query(query);
  Impl& d = *impl_;
  Frame frame;
  // decide_batch(+Cases, +InferenceLimit, +TimeLimit, -Results)
  term_t call;
  term_t args = d.kb_args(4, call);
  internal::put_cases(args, queries, d.vocabulary, "decide_batch");
  // The whole batch may use the time of all its decisions.
  d.put_limits(args + 1, d.options.time_limit_s * static_cast<double>(std::max<std::size_t>(1, queries.size())),
               "decide_batch");
  std::vector<Decision> decisions;
  decisions.reserve(queries.size());
  if (auto call_error = call_once(d.entry.decide_batch, call)) {
    d.set_last_error(*call_error);
    decisions.assign(queries.size(), fallback_decision(*call_error));
    return decisions;
  }
  term_t list = PL_copy_term_ref(args + 3);
  term_t head = PL_new_term_ref();
  while (PL_get_list(list, head, list)) decisions.push_back(d.decision_of(head));
  if (decisions.size() != queries.size()) throw RuleError("decide_batch: wrong number of results");
  return decisions;
}

RulesStatus Engine::reload() {
  constexpr const char* kFunction = "reload";
  require_attached(kFunction);
  Impl& d = *impl_;
  std::lock_guard reload_lock(d.reload_mutex);
  try {
    const std::vector<std::string> paths = d.rule_files();
    if (paths.empty()) {
      throw RuleError(d.options.rules_dir.string() + ":0: no *.pl rule file in the rules directory");
    }
    for (const auto& path : paths) internal::check_rule_file_text(path);
    std::vector<std::string> hashes;
    {
      Frame frame;
      // reload(+Files, +RulesDir, +InferenceLimit, +TimeLimit, +GracePeriod, -Result)
      term_t call;
      term_t args = d.kb_args(6, call);
      internal::put_rule_files(args, d.options.rules_dir, paths, nullptr, d.vocabulary);
      put_atom(args + 1, d.options.rules_dir.string());
      d.put_limits(args + 2, d.options.time_limit_s, kFunction);
      // A retired rule module is freed once no decision can still be running in it.
      put_float(args + 4, 2 * d.options.time_limit_s + 1.0);
      call_or_throw(d.entry.reload, call, kFunction);

      term_t result = args + 5;  // ok(Hashes) | error(Problems)
      term_t list = PL_new_term_ref();
      if (!PL_get_arg(1, result, list)) throw RuleError("reload: malformed answer " + internal::written(result));
      std::vector<std::string> lines = internal::read_texts(list);
      if (!PL_is_functor(result, d.vocabulary.ok))
        throw RuleError(joined_lines(lines, "reload: the rules were rejected"));
      hashes = std::move(lines);
    }
    if (hashes.size() != paths.size()) throw RuleError("reload: wrong number of file hashes");
    const std::int64_t now = unix_now_s();
    std::lock_guard lock(d.status_mutex);
    d.status.files.clear();
    for (std::size_t i = 0; i < paths.size(); ++i) d.status.files.push_back({paths[i], hashes[i], now});
    d.status.last_error.clear();
    ++d.status.generation;
    return d.status;
  } catch (const RuleError& e) {
    d.set_last_error(e.what());
    throw;
  }
}

RulesStatus Engine::status() const {
  std::lock_guard lock(impl_->status_mutex);
  return impl_->status;
}

const std::filesystem::path& Engine::map_rules_dir() const { return impl_->options.map_rules_dir; }

void Engine::set_elements(const std::vector<ElementFacts>& elements) {
  require_attached("set_elements");
  Frame frame;
  term_t call;
  term_t list = impl_->kb_args(1, call);
  internal::put_element_facts(list, elements, impl_->vocabulary);
  call_or_throw(impl_->entry.set_elements, call, "set_elements");
}

void Engine::update_elements(const std::vector<ElementFacts>& upserts, const std::vector<std::string>& removed) {
  require_attached("update_elements");
  Frame frame;
  term_t call;
  term_t args = impl_->kb_args(2, call);  // update_elements(+Upserts, +RemovedIds)
  internal::put_element_facts(args, upserts, impl_->vocabulary);
  internal::put_atoms(args + 1, removed);
  call_or_throw(impl_->entry.update_elements, call, "update_elements");
}

void Engine::set_element_grid(const std::vector<ElementGridFacts>& facts) {
  require_attached("set_element_grid");
  Frame frame;
  term_t call;
  term_t list = impl_->kb_args(1, call);
  internal::put_element_grid_facts(list, facts, impl_->vocabulary);
  call_or_throw(impl_->entry.set_element_grid, call, "set_element_grid");
}

void Engine::set_edge_evidence(const std::vector<EdgeEvidenceFacts>& facts, bool replace_all) {
  require_attached("set_edge_evidence");
  Frame frame;
  term_t call;
  term_t args = impl_->kb_args(2, call);  // set_edge_evidence(+Facts, +ReplaceAll)
  internal::put_edge_evidence_facts(args, facts, impl_->vocabulary);
  internal::put_atom(args + 1, replace_all ? "true" : "false");
  call_or_throw(impl_->entry.set_edge_evidence, call, "set_edge_evidence");
}

std::vector<VerdictFacts> Engine::plan_verdicts(const std::optional<std::vector<EdgeKey>>& edges, std::size_t max) {
  constexpr const char* kFunction = "plan_verdicts";
  require_attached(kFunction);
  Impl& d = *impl_;
  Frame frame;
  // verdicts(+Scope, +Max, +InferenceLimit, +TimeLimit, -Result), Scope = all | edges([Object-Edge, ...])
  term_t call;
  term_t args = d.kb_args(5, call);
  if (!edges) {
    put_atom(args, "all");
  } else {
    term_t list = PL_new_term_ref();
    term_t item = PL_new_term_ref();
    term_t pair = PL_new_term_refs(2);
    PL_put_nil(list);
    for (auto e = edges->rbegin(); e != edges->rend(); ++e) {
      put_atom(pair, e->object_id);
      put_atom(pair + 1, e->edge_id);
      internal::put_functor(item, d.vocabulary.minus, pair, kFunction);
      internal::cons(list, item);
    }
    internal::put_functor(args, PL_new_functor(PL_new_atom("edges"), 1), list, kFunction);
  }
  put_int64(args + 1, static_cast<std::int64_t>(max), kFunction);
  d.put_limits(args + 2, d.options.time_limit_s, kFunction);
  call_or_throw(d.entry.verdicts, call, kFunction);
  term_t result = args + 4;  // ok(Verdicts) | error(Message)
  term_t part = PL_new_term_ref();
  if (PL_is_functor(result, d.vocabulary.error) && PL_get_arg(1, result, part)) {
    d.set_last_error(internal::text_or_written(part));
    return {};
  }
  if (!PL_get_arg(1, result, part)) throw RuleError("plan_verdicts: malformed answer " + internal::written(result));
  return internal::read_verdicts(part);
}

void Engine::add_decisions(const std::vector<DecisionFacts>& decisions, std::size_t keep_last) {
  require_attached("add_decisions");
  Frame frame;
  term_t call;
  term_t args = impl_->kb_args(2, call);  // add_decisions(+Decisions, +KeepLast)
  internal::put_decision_facts(args, decisions, impl_->vocabulary);
  put_int64(args + 1, static_cast<std::int64_t>(keep_last), "add_decisions");
  call_or_throw(impl_->entry.add_decisions, call, "add_decisions");
}

std::vector<PruneOrder> Engine::prune_orders(std::size_t max) {
  constexpr const char* kFunction = "prune_orders";
  require_attached(kFunction);
  Impl& d = *impl_;
  Frame frame;
  // prune(+Max, +InferenceLimit, +TimeLimit, -Result)
  term_t call;
  term_t args = d.kb_args(4, call);
  put_int64(args, static_cast<std::int64_t>(max), kFunction);
  d.put_limits(args + 1, d.options.time_limit_s, kFunction);
  call_or_throw(d.entry.prune, call, kFunction);
  term_t result = args + 3;  // ok(Orders) | error(Message)
  term_t part = PL_new_term_ref();
  if (PL_is_functor(result, d.vocabulary.error) && PL_get_arg(1, result, part)) {
    d.set_last_error(internal::text_or_written(part));
    return {};
  }
  if (!PL_get_arg(1, result, part)) throw RuleError("prune_orders: malformed answer " + internal::written(result));
  return internal::read_prune_orders(part);
}

QueryResult Engine::query(const std::string& goal, std::size_t max_solutions) {
  constexpr const char* kFunction = "query";
  require_attached(kFunction);
  if (const auto problem = internal::text_problem(goal)) {
    throw QueryError(QueryError::Reason::syntax, "query text with " + problem->where());
  }
  Impl& d = *impl_;
  Frame frame;
  // query(+Text, +MaxSolutions, +InferenceLimit, +TimeLimit, -Result)
  term_t call;
  term_t args = d.kb_args(5, call);
  internal::put_string(args, goal, kFunction);
  put_int64(args + 1, static_cast<std::int64_t>(max_solutions), kFunction);
  d.put_limits(args + 2, d.options.time_limit_s, kFunction);
  if (auto error = call_once(d.entry.query, call)) throw QueryError(QueryError::Reason::failed, *error);
  return internal::read_query_answer(args + 4);
}

std::vector<Decision> Engine::dry_run(const RuleText& candidate, const std::vector<DecisionQuery>& queries) {
  constexpr const char* kFunction = "dry_run";
  require_attached(kFunction);
  const auto name = std::filesystem::path(candidate.name);
  if (candidate.name.empty() || name.has_parent_path() || name.extension() != ".pl" || candidate.name.front() == '.') {
    throw std::invalid_argument("dry_run: the candidate needs a plain file name ending in .pl (got '" + candidate.name +
                                "')");
  }
  for (const auto& query : queries) internal::validate_query(query);
  internal::check_rule_text(candidate.name, candidate.text);
  Impl& d = *impl_;
  const std::vector<std::string> paths = d.rule_files();
  for (const auto& path : paths) {
    if (std::filesystem::path(path).filename() != candidate.name) internal::check_rule_file_text(path);
  }
  Frame frame;
  // dry_run(+Files, +RulesDir, +Cases, +InferenceLimit, +TimeLimit, -Result)
  term_t call;
  term_t args = d.kb_args(6, call);
  internal::put_rule_files(args, d.options.rules_dir, paths, &candidate, d.vocabulary);
  put_atom(args + 1, d.options.rules_dir.string());
  internal::put_cases(args + 2, queries, d.vocabulary, kFunction);
  d.put_limits(args + 3, d.options.time_limit_s, kFunction);
  call_or_throw(d.entry.dry_run, call, kFunction);
  term_t result = args + 5;  // ok(Results) | error(Problems)
  term_t list = PL_new_term_ref();
  if (!PL_get_arg(1, result, list)) throw RuleError("dry_run: malformed answer " + internal::written(result));
  if (!PL_is_functor(result, d.vocabulary.ok)) {
    throw RuleError(joined_lines(internal::read_texts(list), "dry_run: the candidate rules were rejected"));
  }
  std::vector<Decision> decisions;
  const std::string last_error = status().last_error;
  term_t head = PL_new_term_ref();
  while (PL_get_list(list, head, list)) decisions.push_back(d.decision_of(head));
  d.set_last_error(last_error);  // a candidate's failures are not the active rules' errors
  return decisions;
}

ThreadAttachment::ThreadAttachment(Engine& /*engine*/) {
  if (PL_thread_self() >= 0) return;
  if (PL_thread_attach_engine(nullptr) < 0) {
    throw RuleError("ThreadAttachment: cannot attach a Prolog engine to this thread");
  }
  attached_here_ = true;
}

ThreadAttachment::~ThreadAttachment() {
  if (attached_here_) PL_thread_destroy_engine();
}

}  // namespace wm::rules
