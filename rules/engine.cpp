#include "rules/engine.h"

#include <SWI-Prolog.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <clocale>
#include <cmath>
#include <mutex>
#include <set>
#include <string_view>
#include <system_error>
#include <utility>

#include "rules/internal/engine_support.h"

namespace wm::rules {
namespace {

// The SWI-Prolog runtime is per process and cannot be initialised twice, so "one Engine at a time"
// is a process-wide fact; this flag is the only global state of the module.
std::atomic<bool> engine_exists{false};

constexpr const char* kSupportModuleName = "wm_engine";

void require_attached(const char* function) {
  if (PL_thread_self() < 0) {
    throw RuleError(std::string(function) + ": thread not attached (use rules::ThreadAttachment)");
  }
}

std::int64_t unix_now_s() {
  return std::chrono::duration_cast<std::chrono::seconds>(
             std::chrono::system_clock::now().time_since_epoch())
      .count();
}

void require_finite(double value, const char* function, const char* what) {
  if (!std::isfinite(value)) {
    throw std::invalid_argument(std::string(function) + ": " + what + " is not finite");
  }
}

// RAII over a foreign frame: every term created inside is released at scope end.
class Frame {
 public:
  Frame() : fid_(PL_open_foreign_frame()) {
    if (fid_ == 0) throw RuleError("rules: cannot open a Prolog frame (out of stack?)");
  }
  ~Frame() { PL_discard_foreign_frame(fid_); }
  Frame(const Frame&) = delete;
  Frame& operator=(const Frame&) = delete;

 private:
  fid_t fid_;
};

// Releases the string buffers PL_get_nchars() pushes, whatever BUF_* flag is used: without it the
// buffer stack grows by one per call and SWI-Prolog aborts the process ("Too many stacked strings")
// after some thousand decisions.
class StringBufferMark {
 public:
  StringBufferMark() { PL_mark_string_buffers(&mark_); }
  ~StringBufferMark() { PL_release_string_buffers_from_mark(mark_); }
  StringBufferMark(const StringBufferMark&) = delete;
  StringBufferMark& operator=(const StringBufferMark&) = delete;

 private:
  buf_mark_t mark_;
};

// Text of an atom or string term (UTF-8); nullopt for any other term.
std::optional<std::string> text_of(term_t t) {
  StringBufferMark mark;
  std::size_t length = 0;
  char* chars = nullptr;
  if (!PL_get_nchars(t, &length, &chars, CVT_ATOM | CVT_STRING | REP_UTF8 | BUF_STACK)) {
    return std::nullopt;
  }
  return std::string(chars, length);
}

// Any term printed as writeq/1 would (used for exceptions, which should not happen: the support
// module catches what it can report).
std::string written(term_t t) {
  StringBufferMark mark;
  std::size_t length = 0;
  char* chars = nullptr;
  if (!PL_get_nchars(t, &length, &chars, CVT_WRITEQ | REP_UTF8 | BUF_STACK)) {
    return "<unprintable Prolog term>";
  }
  return std::string(chars, length);
}

void put_atom(term_t t, std::string_view text) {
  if (!PL_put_chars(t, PL_ATOM | REP_UTF8, text.size(), text.data())) {
    throw RuleError("rules: cannot create the atom '" + std::string(text) + "'");
  }
}

void put_float(term_t t, double value) {
  if (!PL_put_float(t, value)) throw RuleError("rules: cannot create a Prolog float");
}

// Conses `head` in front of the list `list` (in place).
void cons(term_t list, term_t head) {
  if (!PL_cons_list(list, head, list)) throw RuleError("rules: cannot build a Prolog list (out of stack?)");
}

// Calls pred(args...) once. Returns the error text when it fails or raises, nullopt on success; the
// bindings stay readable until the enclosing Frame ends.
std::optional<std::string> call_once(predicate_t pred, term_t args) {
  qid_t qid = PL_open_query(nullptr, PL_Q_CATCH_EXCEPTION | PL_Q_NODEBUG, pred, args);
  if (qid == 0) return std::string("cannot open a Prolog query");
  std::optional<std::string> error;
  if (!PL_next_solution(qid)) {
    // PL_exception(qid) is only valid until the query is cut or closed.
    term_t exception = PL_exception(qid);
    error = exception != 0 ? "Prolog exception: " + written(exception) : std::string("goal failed");
  }
  PL_cut_query(qid);
  return error;
}

std::filesystem::path home_hint_argv0() {
  // PL_initialise derives the home from argv[0] when it can and otherwise falls back to the home
  // compiled into libswipl, which is right for the Debian package. The running executable is the
  // honest argv[0]; an executable without an attached saved state makes SWI use its boot file.
  std::error_code ec;
  auto self = std::filesystem::read_symlink("/proc/self/exe", ec);
  return ec ? std::filesystem::path("wmd") : self;
}

void initialise_runtime() {
  if (PL_is_initialised(nullptr, nullptr)) return;
  static std::string argv0 = home_hint_argv0().string();  // PL_initialise keeps the argv pointers
  static char arg_no_signals[] = "--no-signals";
  static char arg_quiet[] = "-q";
  static char arg_no_packs[] = "--no-packs";
  static char* argv[] = {argv0.data(), arg_no_signals, arg_quiet, arg_no_packs, nullptr};
  // PL_initialise switches LC_NUMERIC to the environment's: keep "C" so that numbers print with '.'
  // everywhere in the process (JSON, SQLite) and in Prolog's format/2.
  std::setlocale(LC_NUMERIC, "C");
  const int ok = PL_initialise(4, argv);
  std::setlocale(LC_NUMERIC, "C");
  if (!ok) throw RuleError("Engine: the SWI-Prolog runtime did not start");
}

}  // namespace

struct Engine::Impl {
  explicit Impl(const EngineOptions& o) : options(o) {}

  const EngineOptions options;
  bool attached_by_constructor = false;

  predicate_t pred_init = nullptr;
  predicate_t pred_set_floor_plan = nullptr;
  predicate_t pred_decide = nullptr;
  predicate_t pred_reload = nullptr;
  predicate_t pred_shutdown = nullptr;
  functor_t f_observation = 0;
  functor_t f_element = 0;
  functor_t f_object = 0;
  functor_t f_edge = 0;
  functor_t f_decision = 0;
  functor_t f_error = 0;
  functor_t f_ok = 0;
  atom_t a_none = 0;

  std::mutex reload_mutex;  // one reload at a time
  mutable std::mutex status_mutex;
  RulesStatus status{{}, "", 0};

  void set_last_error(std::string error) {
    std::lock_guard lock(status_mutex);
    status.last_error = std::move(error);
  }

  void load_support_module();
  void call_or_throw(predicate_t pred, term_t args, const char* function);
  std::vector<std::string> rule_files() const;
};

// Loads the wm_engine support module from its text. Loading it again (a later Engine in the same
// process) replaces it and resets its state.
void Engine::Impl::load_support_module() {
  constexpr const char* kWhat = "Engine (loading the support module)";
  Frame frame;
  term_t open_args = PL_new_term_refs(2);  // open_string(+Text, -Stream)
  if (!PL_put_chars(open_args, PL_STRING | REP_UTF8, static_cast<std::size_t>(-1), internal::kSupportModule)) {
    throw RuleError(std::string(kWhat) + ": cannot create the text");
  }
  call_or_throw(PL_predicate("open_string", 2, "system"), open_args, kWhat);
  term_t stream = open_args + 1;

  term_t load_args = PL_new_term_refs(2);  // load_files(+Id, +[stream(Stream), silent(true)])
  put_atom(load_args, internal::kSupportModuleSourceId);
  term_t option = PL_new_term_ref();
  PL_put_nil(load_args + 1);
  if (!PL_put_atom_chars(option, "true") ||
      !PL_cons_functor(option, PL_new_functor(PL_new_atom("silent"), 1), option)) {
    throw RuleError(std::string(kWhat) + ": out of Prolog stack");
  }
  cons(load_args + 1, option);
  if (!PL_cons_functor(option, PL_new_functor(PL_new_atom("stream"), 1), stream)) {
    throw RuleError(std::string(kWhat) + ": out of Prolog stack");
  }
  cons(load_args + 1, option);
  auto load_error = call_once(PL_predicate("load_files", 2, "system"), load_args);
  (void)call_once(PL_predicate("close", 1, "system"), stream);
  if (load_error) throw RuleError(std::string(kWhat) + ": " + *load_error);
  term_t check = PL_new_term_ref();
  if (!PL_chars_to_term("current_predicate(wm_engine:reload/6)", check) ||
      call_once(PL_predicate("call", 1, "system"), check)) {
    throw RuleError(std::string(kWhat) + ": wm_engine:reload/6 is missing");
  }
}

void Engine::Impl::call_or_throw(predicate_t pred, term_t args, const char* function) {
  if (auto error = call_once(pred, args)) throw RuleError(std::string(function) + ": " + *error);
}

std::vector<std::string> Engine::Impl::rule_files() const {
  std::error_code ec;
  std::vector<std::string> names;
  std::filesystem::directory_iterator it(options.rules_dir, ec);
  if (ec) {
    throw RuleError(options.rules_dir.string() + ":0: cannot read the rules directory: " + ec.message());
  }
  for (const auto& entry : it) {
    const std::string name = entry.path().filename().string();
    if (name.empty() || name.front() == '.' || entry.path().extension() != ".pl") continue;
    std::error_code type_ec;
    if (!entry.is_regular_file(type_ec)) continue;
    names.push_back(name);
  }
  std::sort(names.begin(), names.end());
  std::vector<std::string> paths;
  paths.reserve(names.size());
  for (const auto& name : names) paths.push_back((options.rules_dir / name).string());
  return paths;
}

Engine::Engine(const EngineOptions& options) {
  if (options.inference_limit <= 0) {
    throw std::invalid_argument("Engine: inference_limit must be > 0");
  }
  if (!std::isfinite(options.time_limit_s) || options.time_limit_s <= 0) {
    throw std::invalid_argument("Engine: time_limit_s must be finite and > 0");
  }
  bool expected = false;
  if (!engine_exists.compare_exchange_strong(expected, true)) {
    throw RuleError("Engine: another Engine already owns the SWI-Prolog runtime of this process");
  }
  try {
    impl_ = std::make_unique<Impl>(options);
    initialise_runtime();
    if (PL_thread_self() < 0) {
      if (PL_thread_attach_engine(nullptr) < 0) throw RuleError("Engine: cannot attach a Prolog engine");
      impl_->attached_by_constructor = true;
    }
    Impl& d = *impl_;
    d.pred_init = PL_predicate("init", 0, kSupportModuleName);
    d.pred_set_floor_plan = PL_predicate("set_floor_plan", 1, kSupportModuleName);
    d.pred_decide = PL_predicate("decide", 5, kSupportModuleName);
    d.pred_reload = PL_predicate("reload", 6, kSupportModuleName);
    d.pred_shutdown = PL_predicate("shutdown", 0, kSupportModuleName);
    d.f_observation = PL_new_functor(PL_new_atom("observation"), 4);
    d.f_element = PL_new_functor(PL_new_atom("element"), 3);
    d.f_object = PL_new_functor(PL_new_atom("object"), 4);
    d.f_edge = PL_new_functor(PL_new_atom("edge"), 4);
    d.f_decision = PL_new_functor(PL_new_atom("decision"), 3);
    d.f_error = PL_new_functor(PL_new_atom("error"), 1);
    d.f_ok = PL_new_functor(PL_new_atom("ok"), 1);
    d.a_none = PL_new_atom("none");
    d.load_support_module();
    {
      Frame frame;
      d.call_or_throw(d.pred_init, PL_new_term_refs(0), "Engine");
    }
    reload();
  } catch (...) {
    if (impl_ && impl_->attached_by_constructor) PL_thread_destroy_engine();
    engine_exists.store(false);
    throw;
  }
}

Engine::~Engine() {
  bool attached_here = false;
  if (PL_thread_self() < 0) attached_here = PL_thread_attach_engine(nullptr) >= 0;
  if (PL_thread_self() >= 0) {
    Frame frame;
    (void)call_once(impl_->pred_shutdown, PL_new_term_refs(0));
  }
  if (attached_here) PL_thread_destroy_engine();
  if (impl_->attached_by_constructor) PL_thread_destroy_engine();
  engine_exists.store(false);
}

void Engine::set_floor_plan(const std::vector<ObjectFacts>& objects) {
  constexpr const char* kFunction = "set_floor_plan";
  require_attached(kFunction);
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
  const Impl& d = *impl_;
  Frame frame;
  term_t list = PL_new_term_ref();
  PL_put_nil(list);
  term_t object_term = PL_new_term_ref();
  term_t fields = PL_new_term_refs(4);
  term_t item = PL_new_term_ref();
  term_t edge_fields = PL_new_term_refs(4);
  for (auto object = objects.rbegin(); object != objects.rend(); ++object) {
    put_atom(fields, object->id);
    put_atom(fields + 1, object->kind);
    PL_put_nil(fields + 2);
    for (auto attribute = object->attributes.rbegin(); attribute != object->attributes.rend(); ++attribute) {
      put_atom(item, *attribute);
      cons(fields + 2, item);
    }
    PL_put_nil(fields + 3);
    for (auto edge = object->edges.rbegin(); edge != object->edges.rend(); ++edge) {
      put_atom(edge_fields, edge->id);
      put_float(edge_fields + 1, edge->rho_m);
      put_float(edge_fields + 2, edge->phi_rad);
      put_float(edge_fields + 3, edge->length_m);
      if (!PL_cons_functor_v(item, d.f_edge, edge_fields)) throw RuleError("set_floor_plan: out of Prolog stack");
      cons(fields + 3, item);
    }
    if (!PL_cons_functor_v(object_term, d.f_object, fields)) throw RuleError("set_floor_plan: out of Prolog stack");
    cons(list, object_term);
  }
  impl_->call_or_throw(d.pred_set_floor_plan, list, kFunction);
}

Decision Engine::decide(const DecisionQuery& query) {
  constexpr const char* kFunction = "decide";
  require_attached(kFunction);
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

  Impl& d = *impl_;
  std::string error;
  {
    Frame frame;
    // decide(+Observation, +Match, +InferenceLimit, +TimeLimit, -Result)
    term_t args = PL_new_term_refs(5);
    term_t fields = PL_new_term_refs(4);
    put_atom(fields, query.source);
    put_float(fields + 1, query.rho_m);
    put_float(fields + 2, query.phi_rad);
    put_float(fields + 3, query.length_m);
    if (!PL_cons_functor_v(args, d.f_observation, fields)) throw RuleError("decide: out of Prolog stack");
    if (query.element_id) {
      term_t match = PL_new_term_refs(3);
      put_atom(match, *query.element_id);
      if (query.object_id) {
        put_atom(match + 1, *query.object_id);
      } else {
        PL_put_atom(match + 1, d.a_none);
      }
      put_float(match + 2, query.mahalanobis_sq);
      if (!PL_cons_functor_v(args + 1, d.f_element, match)) throw RuleError("decide: out of Prolog stack");
    } else {
      PL_put_atom(args + 1, d.a_none);
    }
    if (!PL_put_int64(args + 2, d.options.inference_limit)) throw RuleError("decide: out of Prolog stack");
    put_float(args + 3, d.options.time_limit_s);

    if (auto call_error = call_once(d.pred_decide, args)) {
      error = *call_error;
    } else {
      term_t result = args + 4;
      term_t part = PL_new_term_ref();
      if (PL_is_functor(result, d.f_decision)) {
        Decision decision;
        std::optional<std::string> texts[3];
        for (int i = 0; i < 3; ++i) {
          if (PL_get_arg(i + 1, result, part)) texts[i] = text_of(part);
        }
        if (texts[0] && texts[1] && texts[2]) {
          decision.action = std::move(*texts[0]);
          decision.rule = std::move(*texts[1]);
          decision.explanation = std::move(*texts[2]);
          return decision;
        }
        error = "malformed decision " + written(result);
      } else if (PL_is_functor(result, d.f_error) && PL_get_arg(1, result, part)) {
        error = text_of(part).value_or(written(part));
      } else {
        error = "malformed decision " + written(result);
      }
    }
  }
  d.set_last_error(error);
  return Decision{"add", "fallback", "rules failed: " + error, true};
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
    std::vector<std::string> hashes;
    {
      Frame frame;
      // reload(+Files, +RulesDir, +InferenceLimit, +TimeLimit, +GracePeriod, -Result)
      term_t args = PL_new_term_refs(6);
      term_t item = PL_new_term_ref();
      PL_put_nil(args);
      term_t file_args = PL_new_term_refs(2);
      const functor_t f_file = PL_new_functor(PL_new_atom("file"), 2);
      for (auto path = paths.rbegin(); path != paths.rend(); ++path) {
        // Read through the absolute path: Prolog's idea of the working directory may differ.
        put_atom(file_args, *path);
        std::error_code ec;
        const auto absolute = std::filesystem::absolute(*path, ec);
        put_atom(file_args + 1, ec ? *path : absolute.string());
        if (!PL_cons_functor_v(item, f_file, file_args)) throw RuleError("reload: out of Prolog stack");
        cons(args, item);
      }
      put_atom(args + 1, d.options.rules_dir.string());
      if (!PL_put_int64(args + 2, d.options.inference_limit)) throw RuleError("reload: out of Prolog stack");
      put_float(args + 3, d.options.time_limit_s);
      // A retired rule module is freed once no decision can still be running in it.
      put_float(args + 4, 2 * d.options.time_limit_s + 1.0);
      d.call_or_throw(d.pred_reload, args, kFunction);

      term_t result = args + 5;
      term_t list = PL_new_term_ref();
      term_t head = PL_new_term_ref();
      if (!PL_get_arg(1, result, list)) throw RuleError("reload: malformed answer " + written(result));
      std::vector<std::string> lines;
      while (PL_get_list(list, head, list)) {
        lines.push_back(text_of(head).value_or(written(head)));
      }
      if (PL_is_functor(result, d.f_ok)) {
        hashes = std::move(lines);
      } else {
        std::string message;
        for (const auto& line : lines) message += (message.empty() ? "" : "\n") + line;
        throw RuleError(message.empty() ? "reload: the rules were rejected" : message);
      }
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
