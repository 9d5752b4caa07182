#pragma once

#include <cstdint>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "rules/types.h"

namespace wm::rules {

struct EngineOptions {
  /// Every regular file `*.pl` directly in it is loaded, sorted by name; `*.plt` and names starting
  /// with '.' (editor lock files) are ignored.
  std::filesystem::path rules_dir;
  /// Inferences allowed per decision (and per self-check case); > 0.
  std::int64_t inference_limit = 200000;
  /// Wall time allowed per decision (and per self-check case) [s]; finite, > 0.
  double time_limit_s = 1.0;
  /// The Prolog module that holds this engine's facts, and that its rules see: "wm_kb", or "wm_kb_" and 1-48 of
  /// [a-z0-9_]. Engines with different knowledge bases live side by side in one process (one per map), each with
  /// its own facts and active rules; two with the same one cannot.
  std::string knowledge_base = "wm_kb";
  /// One map's own rule files (empty: none): every regular `*.pl` file directly in it is loaded with the shared
  /// ones, and one named like a shared file replaces it (a map with glass walls swaps one file). The whole set is
  /// loaded sorted by name. The directory may not exist (yet): then the shared files alone.
  std::filesystem::path map_rules_dir{};
};

/// The knowledge base: owns the process-wide SWI-Prolog runtime, the floor-plan facts and the active
/// rule set, and answers decisions.
///
/// Threads: every method must be called on a thread that has a Prolog engine: the thread that built
/// the Engine, or one holding a ThreadAttachment; otherwise it throws RuleError("... thread not
/// attached"). decide() may run on several threads at once, also during reload() and
/// set_floor_plan(): a decision sees either the old or the new rules and facts, never a mix.
///
/// The runtime is initialised by the first Engine and never torn down (SWI-Prolog cannot be
/// initialised twice in a process); later Engines share it. Engines with different knowledge bases
/// (EngineOptions::knowledge_base) may exist at once: each has its own facts and active rules.
class Engine {
 public:
  /// Initialises the SWI-Prolog runtime if needed and loads options.rules_dir atomically (see reload()).
  /// @throw RuleError when another Engine has the same knowledge base, the runtime does not start, or the rules do
  /// not load.
  /// @throw std::invalid_argument when inference_limit <= 0, time_limit_s is not finite and > 0, or the knowledge
  /// base's name is not one an Engine may take.
  explicit Engine(const EngineOptions& options);
  ~Engine();
  Engine(const Engine&) = delete;
  Engine& operator=(const Engine&) = delete;

  /// Replaces all wm_kb facts by these objects in one transaction (all or nothing).
  /// @throw std::invalid_argument for an empty, duplicate or "none" object id or a non-finite edge number.
  /// @throw RuleError when Prolog refuses the facts or the thread is not attached.
  void set_floor_plan(const std::vector<ObjectFacts>& objects);

  /// Asks the active rules for a decision (first solution), under the inference and time limits.
  /// Never throws for rule problems: a rule that fails, throws, loops (limit hit) or answers an action
  /// that is not an atom gives the fallback decision {action "add", rule "fallback", explanation
  /// "rules failed: <error>", fallback = true}; adding keeps the observation and touches no existing
  /// element or CAD object. The error is also kept in status().last_error.
  /// @throw std::invalid_argument for a non-finite number, a negative mahalanobis_sq, an object_id
  ///        without element_id, or object_id "none".
  /// @throw RuleError when the thread is not attached.
  Decision decide(const DecisionQuery& query);

  /// Loads every rule file into a fresh Prolog module aside (base module `system`, wm_kb as default
  /// import), collecting errors AND warnings; self-checks that the files define decide/5 and that it
  /// answers an atom action for each canonical case (matched solid, matched element not in the plan,
  /// matched not_deformable, unmatched) on temporary facts that nobody else sees; then makes the new
  /// module active. On any problem the previous rules stay active.
  /// @throw RuleError with one "file:line: message" line per problem, or when the thread is not attached.
  RulesStatus reload();

  RulesStatus status() const;

  /// The map's own rules directory (EngineOptions::map_rules_dir; empty when none).
  const std::filesystem::path& map_rules_dir() const;

  /// Decides many queries in one Prolog call (one time limit around the batch, the inference limit per
  /// query); each result as decide() gives it, including fallbacks. Same exceptions as decide().
  std::vector<Decision> decide_batch(const std::vector<DecisionQuery>& queries);

  /// Replaces all wm_kb:element/8 facts. @throw std::invalid_argument for a non-finite number or an
  /// empty id; RuleError when the thread is not attached.
  void set_elements(const std::vector<ElementFacts>& elements);
  /// Inserts or replaces the given elements and removes the ids in `removed`, in one transaction.
  void update_elements(const std::vector<ElementFacts>& upserts, const std::vector<std::string>& removed);
  /// Inserts or replaces wm_kb:element_grid/3 facts (one per id). update_elements and set_elements drop them for
  /// the elements they touch. @throw std::invalid_argument for a non-finite share or an empty id.
  void set_element_grid(const std::vector<ElementGridFacts>& facts);
  /// Inserts or replaces the edge_evidence/5 and edge_seen_through/6 facts of the given edges (all of them first
  /// when `replace_all`). @throw std::invalid_argument for an empty id, a non-finite share or stretch.
  void set_edge_evidence(const std::vector<EdgeEvidenceFacts>& facts, bool replace_all);
  /// Asks the active rules for their verdicts on the plan from the evidence facts (at most `max`), under the
  /// limits: for each edge with evidence (of `edges`, or all when nullopt), verdict_override/5 (first answer) or
  /// else every answer of edge_verdict/5; then object_verdict/4 of every object (of those edges' objects). Answers
  /// `kept` are dropped. A failing rule gives an empty list and sets status().last_error.
  std::vector<VerdictFacts> plan_verdicts(const std::optional<std::vector<EdgeKey>>& edges, std::size_t max);
  /// Appends decision/7 facts, keeping only the `keep_last` newest in the knowledge base.
  void add_decisions(const std::vector<DecisionFacts>& decisions, std::size_t keep_last);

  /// Asks the active rules' prune/3 (if any clause exists) for at most `max` elements to remove,
  /// under the limits. A failing rule gives an empty list and sets status().last_error.
  std::vector<PruneOrder> prune_orders(std::size_t max);

  /// Runs a read-only goal (Prolog text, e.g. "attribute(O, solid)") against the knowledge base: the
  /// facts and the active rules. Checked with library(sandbox) and refused when it writes to the
  /// database; run inside snapshot/1 under the inference and time limits.
  /// @throw QueryError (syntax, unsafe, limit, failed); RuleError when the thread is not attached.
  QueryResult query(const std::string& goal, std::size_t max_solutions);

  /// Loads the current rule files, with `candidate` replacing (or adding) the file of its name, aside;
  /// decides every query with them; frees them. The active rules, facts and map are untouched.
  /// @throw RuleError with "file:line: message" lines when the candidate set does not load or fails the
  ///        self-check (like reload()).
  std::vector<Decision> dry_run(const RuleText& candidate, const std::vector<DecisionQuery>& queries);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// RAII: attaches a Prolog engine to the calling thread if it has none (PL_thread_attach_engine) and
/// destroys it at scope end (~95 µs for the pair: keep one per long-lived thread). Needed on every
/// thread other than the one that built the Engine before it calls into the Engine. Must not outlive
/// the Engine.
class ThreadAttachment {
 public:
  /// @throw RuleError when no engine can be attached.
  explicit ThreadAttachment(Engine& engine);
  ~ThreadAttachment();
  ThreadAttachment(const ThreadAttachment&) = delete;
  ThreadAttachment& operator=(const ThreadAttachment&) = delete;

 private:
  bool attached_here_ = false;  // false when the thread already had an engine
};

}  // namespace wm::rules
