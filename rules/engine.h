#pragma once

#include <cstdint>
#include <filesystem>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

namespace wm::rules {

/// Error from the knowledge base: a rule file that does not load (one "file:line: text" line per
/// problem), a Prolog exception, or misuse (e.g. a call from a thread without a Prolog engine).
/// what() is human readable.
class RuleError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

struct EngineOptions {
  /// Every regular file `*.pl` directly in it is loaded, sorted by name; `*.plt` and names starting
  /// with '.' (editor lock files) are ignored.
  std::filesystem::path rules_dir;
  /// Inferences allowed per decision (and per self-check case); > 0.
  std::int64_t inference_limit = 200000;
  /// Wall time allowed per decision (and per self-check case) [s]; finite, > 0.
  double time_limit_s = 1.0;
};

/// One a-priori object of the floor plan, as the rules see it (wm_kb:object/2, attribute/2, edge/5).
struct ObjectFacts {
  std::string id;    // unique, non-empty, not "none" (that atom means "not in the plan")
  std::string kind;  // e.g. "wall", "table"
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
  std::string source;  // who observed it
  double rho_m = 0, phi_rad = 0, length_m = 0;
  std::optional<std::string> element_id;  // matched element (nullopt = unmatched)
  std::optional<std::string> object_id;   // a-priori object of that element (nullopt = not in the plan)
  double mahalanobis_sq = 0;              // squared Mahalanobis distance of the match, >= 0
  /// Context the rules read with observation_origin/1 and observation_sensor/1.
  std::string origin = "client";  // client | scan | grid
  std::string sensor = "unknown"; // laser | sonar | ... | unknown
};

/// One observed map element (not in the plan), as the rules see it (wm_kb:element/8):
/// element(Id, Source, Observer, Rho, Phi, Length, Support, UpdatedAt).
struct ElementFacts {
  std::string id;        // e.g. "e12"
  std::string source;    // client | scan | grid
  std::string observer;  // e.g. "robot-1"
  double rho_m = 0, phi_rad = 0, length_m = 0;
  std::int64_t support = 1;        // observations fused into it
  double updated_at_unix_s = 0;    // wall-clock time of its last change [s]
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
  std::string text;            // atom/string text; compound: the term as writeq/1 prints it
  std::int64_t integer = 0;    // Kind::integer (integers beyond 64 bits come as Kind::compound text)
  double floating = 0;         // Kind::floating
  std::vector<QueryValue> items;  // Kind::list
};

struct QueryResult {
  std::vector<std::string> variables;                 // named variables of the goal, in order
  std::vector<std::vector<QueryValue>> solutions;     // one row per solution, values by variable
  bool truncated = false;                             // more solutions than asked for exist
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

struct Decision {
  std::string action;  // delete | merge | rigid_adjust | add | ... (whatever atom the rules answer)
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

/// The knowledge base: owns the process-wide SWI-Prolog runtime, the floor-plan facts and the active
/// rule set, and answers decisions.
///
/// Threads: every method must be called on a thread that has a Prolog engine: the thread that built
/// the Engine, or one holding a ThreadAttachment; otherwise it throws RuleError("... thread not
/// attached"). decide() may run on several threads at once, also during reload() and
/// set_floor_plan(): a decision sees either the old or the new rules and facts, never a mix.
///
/// The runtime is initialised by the first Engine and never torn down (SWI-Prolog cannot be
/// initialised twice in a process); only one Engine may exist at a time, a later one reuses the runtime.
class Engine {
 public:
  /// Initialises the SWI-Prolog runtime if needed and loads options.rules_dir atomically (see reload()).
  /// @throw RuleError when another Engine exists, the runtime does not start, or the rules do not load.
  /// @throw std::invalid_argument when inference_limit <= 0 or time_limit_s is not finite and > 0.
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

  /// Decides many queries in one Prolog call (one time limit around the batch, the inference limit per
  /// query); each result as decide() gives it, including fallbacks. Same exceptions as decide().
  std::vector<Decision> decide_batch(const std::vector<DecisionQuery>& queries);

  /// Replaces all wm_kb:element/8 facts. @throw std::invalid_argument for a non-finite number or an
  /// empty id; RuleError when the thread is not attached.
  void set_elements(const std::vector<ElementFacts>& elements);
  /// Inserts or replaces the given elements and removes the ids in `removed`, in one transaction.
  void update_elements(const std::vector<ElementFacts>& upserts, const std::vector<std::string>& removed);
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
