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
