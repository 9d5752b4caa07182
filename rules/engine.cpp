#include "rules/engine.h"

#include <SWI-Prolog.h>

#include <algorithm>
#include <cctype>
#include <csignal>
#include <iterator>
#include <atomic>
#include <chrono>
#include <clocale>
#include <fstream>
#include <sstream>
#include <cmath>
#include <mutex>
#include <set>
#include <string_view>
#include <system_error>
#include <utility>

#include "common/utf8.h"
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

// Any term printed as writeq/1 would, bounded by wm_engine:term_text/2: PL_get_nchars(CVT_WRITEQ)
// writes by C recursion, and a term a rule or query built ten thousand levels deep overflows the
// thread's C stack there.
std::string written(term_t t) {
  const fid_t frame = PL_open_foreign_frame();
  if (frame == 0) return "<unprintable Prolog term>";
  std::string text = "<unprintable Prolog term>";
  term_t args = PL_new_term_refs(2);
  if (PL_put_term(args, t) &&
      PL_call_predicate(nullptr, PL_Q_NODEBUG | PL_Q_CATCH_EXCEPTION, PL_predicate("term_text", 2, "wm_engine"), args)) {
    if (auto chars = text_of(args + 1)) text = std::move(*chars);
  }
  PL_discard_foreign_frame(frame);
  return text;
}

// True when brackets ( [ { in `text` nest deeper than `max` outside quotes, character literals
// (0'c) and comments; `line` is where. The reader and the writer of SWI-Prolog recurse in C for
// each level, so the depth is refused before the text is parsed.
bool nesting_exceeds(std::string_view text, int max, int& line) {
  int depth = 0;
  line = 1;
  for (std::size_t i = 0; i < text.size(); ++i) {
    const char c = text[i];
    if (c == '\n') {
      ++line;
    } else if (c == '%') {
      while (i + 1 < text.size() && text[i + 1] != '\n') ++i;
    } else if (c == '/' && i + 1 < text.size() && text[i + 1] == '*') {
      for (i += 2; i + 1 < text.size() && !(text[i] == '*' && text[i + 1] == '/'); ++i) line += text[i] == '\n';
      ++i;
    } else if (c == '0' && i + 1 < text.size() && text[i + 1] == '\'' &&
               (i == 0 || !(std::isalnum(static_cast<unsigned char>(text[i - 1])) || text[i - 1] == '_'))) {
      i += 2;  // 0'c: skip the character, an escape's backslash or a doubled quote with it
      if (i < text.size() && (text[i] == '\\' || (text[i] == '\'' && i + 1 < text.size() && text[i + 1] == '\''))) ++i;
    } else if (c == '\'' || c == '"' || c == '`') {
      for (++i; i < text.size(); ++i) {
        if (text[i] == '\\') {
          ++i;
        } else if (text[i] == c) {
          if (i + 1 < text.size() && text[i + 1] == c) ++i;  // a doubled quote stands for itself
          else break;
        } else if (text[i] == '\n') {
          ++line;
        }
      }
    } else if (c == '(' || c == '[' || c == '{') {
      if (++depth > max) return true;
    } else if (c == ')' || c == ']' || c == '}') {
      depth = std::max(0, depth - 1);
    }
  }
  return false;
}

// wm_engine:text_nesting_exceeds(+Text, +Max, -Line): see nesting_exceeds(). Never throws.
foreign_t pl_text_nesting_exceeds(term_t text, term_t max, term_t line) {
  try {
    auto chars = text_of(text);
    int limit = 0;
    if (!chars || !PL_get_integer(max, &limit)) return false;
    int at = 0;
    return nesting_exceeds(*chars, limit, at) && PL_unify_integer(line, at);
  } catch (...) {
    return false;
  }
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

// Where `text` stops being well-formed UTF-8 without NUL bytes, if it does. SWI-Prolog's reader
// misbehaves on malformed UTF-8 (a heap use-after-free found by fuzzing), so no text reaches it unchecked.
struct TextProblem {
  std::size_t line = 0, byte = 0;
  std::string what;  // "not UTF-8" | "a NUL byte"

  std::string where() const { return "byte " + std::to_string(byte) + ": " + what; }
};

std::optional<TextProblem> text_problem(std::string_view text) {
  std::size_t at = text.find('\0');
  std::string what = "a NUL byte";
  if (const auto bad = common::invalid_utf8_offset(text); bad && *bad < at) {
    at = *bad;
    what = "not UTF-8";
  }
  if (at == std::string_view::npos) return std::nullopt;
  const auto newlines = std::count(text.begin(), text.begin() + static_cast<std::ptrdiff_t>(at), '\n');
  return TextProblem{1 + static_cast<std::size_t>(newlines), at, what};
}

// Refuses a rule text the reader must not see, as "name:line: ..." like every load problem.
void check_rule_text(const std::string& name, std::string_view text) {
  if (const auto problem = text_problem(text)) {
    throw RuleError(name + ":" + std::to_string(problem->line) + ": rule text with " + problem->where());
  }
}

void check_rule_file_text(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream text;
  text << in.rdbuf();
  check_rule_text(path, text.str());
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
  static char arg_quiet[] = "-q";
  static char arg_no_packs[] = "--no-packs";
  static char* argv[] = {argv0.data(), arg_quiet, arg_no_packs, nullptr};
  // SWI-Prolog's signal handling stays on: its alert signal lets call_with_time_limit/2 interrupt
  // blocking calls (sleep/1), and its SIGSEGV handler on an alternate stack turns a C-stack overflow
  // in Prolog's C code into resource_error(c_stack) instead of a crash. With --no-signals neither
  // works. The process-control signals stay the host's: their dispositions are restored.
  constexpr int kHostSignals[] = {SIGINT, SIGTERM, SIGHUP, SIGQUIT, SIGUSR1, SIGCHLD};
  struct sigaction saved[std::size(kHostSignals)];
  for (std::size_t i = 0; i < std::size(kHostSignals); ++i) sigaction(kHostSignals[i], nullptr, &saved[i]);
  // PL_initialise switches LC_NUMERIC to the environment's: keep "C" so that numbers print with '.'
  // everywhere in the process (JSON, SQLite) and in Prolog's format/2.
  std::setlocale(LC_NUMERIC, "C");
  const int ok = PL_initialise(3, argv);
  std::setlocale(LC_NUMERIC, "C");
  for (std::size_t i = 0; i < std::size(kHostSignals); ++i) sigaction(kHostSignals[i], &saved[i], nullptr);
  if (!ok) throw RuleError("Engine: the SWI-Prolog runtime did not start");
  if (!PL_register_foreign_in_module(kSupportModuleName, "text_nesting_exceeds", 3,
                                     reinterpret_cast<pl_function_t>(pl_text_nesting_exceeds), 0)) {
    throw RuleError("Engine: cannot register text_nesting_exceeds/3");
  }
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
  predicate_t pred_decide_context = nullptr;
  predicate_t pred_decide_batch = nullptr;
  predicate_t pred_set_elements = nullptr;
  predicate_t pred_update_elements = nullptr;
  predicate_t pred_add_decisions = nullptr;
  predicate_t pred_prune = nullptr;
  predicate_t pred_query = nullptr;
  predicate_t pred_dry_run = nullptr;
  functor_t f_context = 0;
  functor_t f_case = 0;
  functor_t f_element_fact = 0;
  functor_t f_decision_fact = 0;
  functor_t f_file = 0;
  functor_t f_text = 0;
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
  void put_rule_files(term_t list, const std::vector<std::string>& paths, const RuleText* candidate) const;
  void put_case(term_t observation, term_t match, term_t context, const DecisionQuery& query) const;
  Decision read_result(term_t result);
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
    d.pred_decide_context = PL_predicate("decide", 6, kSupportModuleName);
    d.pred_decide_batch = PL_predicate("decide_batch", 4, kSupportModuleName);
    d.pred_set_elements = PL_predicate("set_elements", 1, kSupportModuleName);
    d.pred_update_elements = PL_predicate("update_elements", 2, kSupportModuleName);
    d.pred_add_decisions = PL_predicate("add_decisions", 2, kSupportModuleName);
    d.pred_prune = PL_predicate("prune", 4, kSupportModuleName);
    d.pred_query = PL_predicate("query", 5, kSupportModuleName);
    d.pred_dry_run = PL_predicate("dry_run", 6, kSupportModuleName);
    d.f_context = PL_new_functor(PL_new_atom("context"), 2);
    d.f_case = PL_new_functor(PL_new_atom("case"), 3);
    d.f_element_fact = PL_new_functor(PL_new_atom("element"), 8);
    d.f_decision_fact = PL_new_functor(PL_new_atom("decision"), 7);
    d.f_file = PL_new_functor(PL_new_atom("file"), 2);
    d.f_text = PL_new_functor(PL_new_atom("text"), 2);
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

namespace {

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

}  // namespace

void Engine::Impl::put_case(term_t observation, term_t match, term_t context, const DecisionQuery& query) const {
  term_t fields = PL_new_term_refs(4);
  put_atom(fields, query.source);
  put_float(fields + 1, query.rho_m);
  put_float(fields + 2, query.phi_rad);
  put_float(fields + 3, query.length_m);
  if (!PL_cons_functor_v(observation, f_observation, fields)) throw RuleError("decide: out of Prolog stack");
  if (query.element_id) {
    term_t parts = PL_new_term_refs(3);
    put_atom(parts, *query.element_id);
    if (query.object_id) {
      put_atom(parts + 1, *query.object_id);
    } else {
      PL_put_atom(parts + 1, a_none);
    }
    put_float(parts + 2, query.mahalanobis_sq);
    if (!PL_cons_functor_v(match, f_element, parts)) throw RuleError("decide: out of Prolog stack");
  } else {
    PL_put_atom(match, a_none);
  }
  term_t context_parts = PL_new_term_refs(2);
  put_atom(context_parts, query.origin);
  put_atom(context_parts + 1, query.sensor.empty() ? std::string_view("unknown") : std::string_view(query.sensor));
  if (!PL_cons_functor_v(context, f_context, context_parts)) throw RuleError("decide: out of Prolog stack");
}

// A decision(Action, Rule, Explanation) or error(Message) term; errors become the fallback decision.
Decision Engine::Impl::read_result(term_t result) {
  std::string error;
  term_t part = PL_new_term_ref();
  if (PL_is_functor(result, f_decision)) {
    std::optional<std::string> texts[3];
    for (int i = 0; i < 3; ++i) {
      if (PL_get_arg(i + 1, result, part)) texts[i] = text_of(part);
    }
    if (texts[0] && texts[1] && texts[2]) {
      return Decision{std::move(*texts[0]), std::move(*texts[1]), std::move(*texts[2]), false};
    }
    error = "malformed decision " + written(result);
  } else if (PL_is_functor(result, f_error) && PL_get_arg(1, result, part)) {
    error = text_of(part).value_or(written(part));
  } else {
    error = "malformed decision " + written(result);
  }
  set_last_error(error);
  return Decision{"add", "fallback", "rules failed: " + error, true};
}

Decision Engine::decide(const DecisionQuery& query) {
  require_attached("decide");
  validate_query(query);
  Impl& d = *impl_;
  Frame frame;
  // decide(+Observation, +Match, +Context, +InferenceLimit, +TimeLimit, -Result)
  term_t args = PL_new_term_refs(6);
  d.put_case(args, args + 1, args + 2, query);
  if (!PL_put_int64(args + 3, d.options.inference_limit)) throw RuleError("decide: out of Prolog stack");
  put_float(args + 4, d.options.time_limit_s);
  if (auto call_error = call_once(d.pred_decide_context, args)) {
    d.set_last_error(*call_error);
    return Decision{"add", "fallback", "rules failed: " + *call_error, true};
  }
  return d.read_result(args + 5);
}

std::vector<Decision> Engine::decide_batch(const std::vector<DecisionQuery>& queries) {
  require_attached("decide_batch");
  for (const auto& query : queries) validate_query(query);
  Impl& d = *impl_;
  Frame frame;
  // decide_batch(+Cases, +InferenceLimit, +TimeLimit, -Results)
  term_t args = PL_new_term_refs(4);
  PL_put_nil(args);
  term_t item = PL_new_term_ref();
  term_t parts = PL_new_term_refs(3);
  for (auto query = queries.rbegin(); query != queries.rend(); ++query) {
    d.put_case(parts, parts + 1, parts + 2, *query);
    if (!PL_cons_functor_v(item, d.f_case, parts)) throw RuleError("decide_batch: out of Prolog stack");
    cons(args, item);
  }
  if (!PL_put_int64(args + 1, d.options.inference_limit)) throw RuleError("decide_batch: out of Prolog stack");
  // The whole batch may use the time of all its decisions.
  put_float(args + 2, d.options.time_limit_s * static_cast<double>(std::max<std::size_t>(1, queries.size())));
  std::vector<Decision> decisions;
  decisions.reserve(queries.size());
  if (auto call_error = call_once(d.pred_decide_batch, args)) {
    d.set_last_error(*call_error);
    for (std::size_t i = 0; i < queries.size(); ++i)
      decisions.push_back(Decision{"add", "fallback", "rules failed: " + *call_error, true});
    return decisions;
  }
  term_t list = PL_copy_term_ref(args + 3);
  term_t head = PL_new_term_ref();
  while (PL_get_list(list, head, list)) decisions.push_back(d.read_result(head));
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
    for (const auto& path : paths) check_rule_file_text(path);
    std::vector<std::string> hashes;
    {
      Frame frame;
      // reload(+Files, +RulesDir, +InferenceLimit, +TimeLimit, +GracePeriod, -Result)
      term_t args = PL_new_term_refs(6);
      d.put_rule_files(args, paths, nullptr);
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
        for (const auto& line : lines) {
          if (!message.empty()) message += '\n';
          message += line;
        }
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

void Engine::Impl::put_rule_files(term_t list, const std::vector<std::string>& paths, const RuleText* candidate) const {
  term_t item = PL_new_term_ref();
  term_t file_args = PL_new_term_refs(2);
  PL_put_nil(list);
  std::vector<std::string> names;
  bool candidate_placed = false;
  auto put_candidate = [&] {
    put_atom(file_args, (options.rules_dir / candidate->name).string());
    if (!PL_put_chars(file_args + 1, PL_STRING | REP_UTF8, candidate->text.size(), candidate->text.data()) ||
        !PL_cons_functor_v(item, f_text, file_args)) {
      throw RuleError("rules: out of Prolog stack");
    }
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
    if (!PL_cons_functor_v(item, f_file, file_args)) throw RuleError("rules: out of Prolog stack");
    cons(list, item);
  }
  if (candidate && !candidate_placed) put_candidate();
}

namespace {

void put_optional_atom(term_t t, const std::optional<std::string>& text, atom_t none) {
  if (text) {
    put_atom(t, *text);
  } else {
    PL_put_atom(t, none);
  }
}

// Text an answer may carry in total [bytes]; beyond it the query fails with a limit error.
constexpr std::size_t kMaxAnswerTextBytes = std::size_t{8} << 20;

void charge(std::size_t& used, const QueryValue& v) {
  used += v.text.size() + 16;
  if (used > kMaxAnswerTextBytes) {
    throw QueryError(QueryError::Reason::limit, "the answer is larger than " + std::to_string(kMaxAnswerTextBytes >> 20) +
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
      v.text = text_of(t).value_or(written(t));
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

void put_element_fact(term_t t, functor_t f, const ElementFacts& e) {
  if (e.id.empty()) throw std::invalid_argument("set_elements: an element id is empty");
  require_finite(e.rho_m, "set_elements", "rho_m");
  require_finite(e.phi_rad, "set_elements", "phi_rad");
  require_finite(e.length_m, "set_elements", "length_m");
  require_finite(e.updated_at_unix_s, "set_elements", "updated_at_unix_s");
  term_t a = PL_new_term_refs(8);
  put_atom(a, e.id);
  put_atom(a + 1, e.source);
  put_atom(a + 2, e.observer);
  put_float(a + 3, e.rho_m);
  put_float(a + 4, e.phi_rad);
  put_float(a + 5, e.length_m);
  if (!PL_put_int64(a + 6, e.support)) throw RuleError("set_elements: out of Prolog stack");
  put_float(a + 7, e.updated_at_unix_s);
  if (!PL_cons_functor_v(t, f, a)) throw RuleError("set_elements: out of Prolog stack");
}

}  // namespace

void Engine::set_elements(const std::vector<ElementFacts>& elements) {
  require_attached("set_elements");
  Impl& d = *impl_;
  Frame frame;
  term_t list = PL_new_term_ref();
  term_t item = PL_new_term_ref();
  PL_put_nil(list);
  for (auto e = elements.rbegin(); e != elements.rend(); ++e) {
    put_element_fact(item, d.f_element_fact, *e);
    cons(list, item);
  }
  d.call_or_throw(d.pred_set_elements, list, "set_elements");
}

void Engine::update_elements(const std::vector<ElementFacts>& upserts, const std::vector<std::string>& removed) {
  require_attached("update_elements");
  Impl& d = *impl_;
  Frame frame;
  term_t args = PL_new_term_refs(2);
  term_t item = PL_new_term_ref();
  PL_put_nil(args);
  for (auto e = upserts.rbegin(); e != upserts.rend(); ++e) {
    put_element_fact(item, d.f_element_fact, *e);
    cons(args, item);
  }
  PL_put_nil(args + 1);
  for (auto id = removed.rbegin(); id != removed.rend(); ++id) {
    put_atom(item, *id);
    cons(args + 1, item);
  }
  d.call_or_throw(d.pred_update_elements, args, "update_elements");
}

void Engine::add_decisions(const std::vector<DecisionFacts>& decisions, std::size_t keep_last) {
  require_attached("add_decisions");
  Impl& d = *impl_;
  Frame frame;
  term_t args = PL_new_term_refs(2);
  term_t item = PL_new_term_ref();
  term_t a = PL_new_term_refs(7);
  PL_put_nil(args);
  for (auto r = decisions.rbegin(); r != decisions.rend(); ++r) {
    require_finite(r->at_unix_s, "add_decisions", "at_unix_s");
    if (!PL_put_int64(a, r->seq)) throw RuleError("add_decisions: out of Prolog stack");
    put_atom(a + 1, r->action);
    put_atom(a + 2, r->rule);
    put_optional_atom(a + 3, r->element, d.a_none);
    put_optional_atom(a + 4, r->object, d.a_none);
    put_atom(a + 5, r->observer);
    put_float(a + 6, r->at_unix_s);
    if (!PL_cons_functor_v(item, d.f_decision_fact, a)) throw RuleError("add_decisions: out of Prolog stack");
    cons(args, item);
  }
  if (!PL_put_int64(args + 1, static_cast<std::int64_t>(keep_last))) throw RuleError("add_decisions: out of Prolog stack");
  d.call_or_throw(d.pred_add_decisions, args, "add_decisions");
}

std::vector<PruneOrder> Engine::prune_orders(std::size_t max) {
  require_attached("prune_orders");
  Impl& d = *impl_;
  Frame frame;
  // prune(+Max, +InferenceLimit, +TimeLimit, -Result)
  term_t args = PL_new_term_refs(4);
  if (!PL_put_int64(args, static_cast<std::int64_t>(max)) || !PL_put_int64(args + 1, d.options.inference_limit)) {
    throw RuleError("prune_orders: out of Prolog stack");
  }
  put_float(args + 2, d.options.time_limit_s);
  d.call_or_throw(d.pred_prune, args, "prune_orders");
  term_t result = args + 3;
  term_t part = PL_new_term_ref();
  if (PL_is_functor(result, d.f_error) && PL_get_arg(1, result, part)) {
    d.set_last_error(text_of(part).value_or(written(part)));
    return {};
  }
  std::vector<PruneOrder> orders;
  term_t list = PL_new_term_ref();
  term_t head = PL_new_term_ref();
  if (!PL_get_arg(1, result, list)) throw RuleError("prune_orders: malformed answer " + written(result));
  while (PL_get_list(list, head, list)) {
    PruneOrder order;
    std::optional<std::string> texts[3];
    for (int i = 0; i < 3; ++i) {
      if (PL_get_arg(i + 1, head, part)) texts[i] = text_of(part);
    }
    if (!texts[0] || !texts[1] || !texts[2]) throw RuleError("prune_orders: malformed order " + written(head));
    orders.push_back({std::move(*texts[0]), std::move(*texts[1]), std::move(*texts[2])});
  }
  return orders;
}

QueryResult Engine::query(const std::string& goal, std::size_t max_solutions) {
  require_attached("query");
  if (const auto problem = text_problem(goal)) {
    throw QueryError(QueryError::Reason::syntax, "query text with " + problem->where());
  }
  Impl& d = *impl_;
  Frame frame;
  // query(+Text, +MaxSolutions, +InferenceLimit, +TimeLimit, -Result)
  term_t args = PL_new_term_refs(5);
  if (!PL_put_chars(args, PL_STRING | REP_UTF8, goal.size(), goal.data()) ||
      !PL_put_int64(args + 1, static_cast<std::int64_t>(max_solutions)) ||
      !PL_put_int64(args + 2, d.options.inference_limit)) {
    throw RuleError("query: out of Prolog stack");
  }
  put_float(args + 3, d.options.time_limit_s);
  if (auto error = call_once(d.pred_query, args)) throw QueryError(QueryError::Reason::failed, *error);
  term_t result = args + 4;
  atom_t name = 0;
  std::size_t arity = 0;
  if (!PL_get_name_arity(result, &name, &arity)) throw RuleError("query: malformed answer " + written(result));
  const std::string kind = PL_atom_chars(name);
  term_t part = PL_new_term_ref();
  if (kind != "ok") {
    const std::string message = PL_get_arg(1, result, part) ? text_of(part).value_or(written(part)) : written(result);
    const auto reason = kind == "syntax" ? QueryError::Reason::syntax
                        : kind == "unsafe" ? QueryError::Reason::unsafe
                        : kind == "limit" ? QueryError::Reason::limit
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

std::vector<Decision> Engine::dry_run(const RuleText& candidate, const std::vector<DecisionQuery>& queries) {
  require_attached("dry_run");
  const auto name = std::filesystem::path(candidate.name);
  if (candidate.name.empty() || name.has_parent_path() || name.extension() != ".pl" || candidate.name.front() == '.') {
    throw std::invalid_argument("dry_run: the candidate needs a plain file name ending in .pl (got '" + candidate.name + "')");
  }
  for (const auto& query : queries) validate_query(query);
  check_rule_text(candidate.name, candidate.text);
  Impl& d = *impl_;
  const std::vector<std::string> paths = d.rule_files();
  for (const auto& path : paths) {
    if (std::filesystem::path(path).filename() != candidate.name) check_rule_file_text(path);
  }
  Frame frame;
  // dry_run(+Files, +RulesDir, +Cases, +InferenceLimit, +TimeLimit, -Result)
  term_t args = PL_new_term_refs(6);
  d.put_rule_files(args, paths, &candidate);
  put_atom(args + 1, d.options.rules_dir.string());
  PL_put_nil(args + 2);
  term_t item = PL_new_term_ref();
  term_t parts = PL_new_term_refs(3);
  for (auto query = queries.rbegin(); query != queries.rend(); ++query) {
    d.put_case(parts, parts + 1, parts + 2, *query);
    if (!PL_cons_functor_v(item, d.f_case, parts)) throw RuleError("dry_run: out of Prolog stack");
    cons(args + 2, item);
  }
  if (!PL_put_int64(args + 3, d.options.inference_limit)) throw RuleError("dry_run: out of Prolog stack");
  put_float(args + 4, d.options.time_limit_s);
  d.call_or_throw(d.pred_dry_run, args, "dry_run");
  term_t result = args + 5;
  term_t list = PL_new_term_ref();
  term_t head = PL_new_term_ref();
  if (!PL_get_arg(1, result, list)) throw RuleError("dry_run: malformed answer " + written(result));
  if (!PL_is_functor(result, d.f_ok)) {
    std::string message;
    while (PL_get_list(list, head, list)) {
      if (!message.empty()) message += '\n';
      message += text_of(head).value_or(written(head));
    }
    throw RuleError(message.empty() ? "dry_run: the candidate rules were rejected" : message);
  }
  std::vector<Decision> decisions;
  const std::string last_error = status().last_error;
  while (PL_get_list(list, head, list)) decisions.push_back(d.read_result(head));
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
