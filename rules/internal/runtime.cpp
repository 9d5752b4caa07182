#include "rules/internal/runtime.h"

#include <SWI-Prolog.h>

#include <clocale>
#include <csignal>
#include <filesystem>
#include <iterator>
#include <mutex>
#include <string>
#include <string_view>
#include <system_error>

#include "rules/internal/engine_support_pl.h"  // generated from engine_support.pl
#include "rules/internal/prolog_api.h"
#include "rules/internal/rule_checks_pl.h"  // generated from rule_checks.pl
#include "rules/internal/text_checks.h"
#include "rules/types.h"

namespace wm::rules::internal {
namespace {

std::filesystem::path home_hint_argv0() {
  // PL_initialise derives the home from argv[0] when it can and otherwise falls back to the home
  // compiled into libswipl, which is right for the Debian package. The running executable is the
  // honest argv[0]; an executable without an attached saved state makes SWI use its boot file.
  std::error_code ec;
  auto self = std::filesystem::read_symlink("/proc/self/exe", ec);
  return ec ? std::filesystem::path("wmd") : self;
}

// Loads a module from its embedded text under `source_id` (shows in its messages; not a file on
// disk), then checks that `probe` (Module:Name/Arity) is defined.
void load_module_text(std::string_view text, const char* source_id, const char* probe) {
  const std::string what = std::string("Engine (loading ") + source_id + ")";
  Frame frame;
  term_t open_args = PL_new_term_refs(2);  // open_string(+Text, -Stream)
  put_string(open_args, text, what);
  call_or_throw(PL_predicate("open_string", 2, "system"), open_args, what.c_str());
  term_t stream = open_args + 1;

  term_t load_args = PL_new_term_refs(2);  // load_files(+Id, +[stream(Stream), silent(true)])
  put_atom(load_args, source_id);
  term_t option = PL_new_term_ref();
  PL_put_nil(load_args + 1);
  require_stack(PL_put_atom_chars(option, "true"), what);
  put_functor(option, PL_new_functor(PL_new_atom("silent"), 1), option, what);
  cons(load_args + 1, option);
  put_functor(option, PL_new_functor(PL_new_atom("stream"), 1), stream, what);
  cons(load_args + 1, option);
  auto load_error = call_once(PL_predicate("load_files", 2, "system"), load_args);
  (void)call_once(PL_predicate("close", 1, "system"), stream);
  if (load_error) throw RuleError(what + ": " + *load_error);
  term_t check = PL_new_term_ref();
  const std::string goal = std::string("current_predicate(") + probe + ")";
  if (!PL_chars_to_term(goal.c_str(), check) || call_once(PL_predicate("call", 1, "system"), check)) {
    throw RuleError(what + ": " + probe + " is missing");
  }
}

}  // namespace

void initialise_runtime() {
  if (PL_is_initialised(nullptr, nullptr)) return;
  static std::string argv0 = home_hint_argv0().string();  // PL_initialise keeps the argv pointers
  static char arg_quiet[] = "-q";
  static char arg_no_packs[] = "--no-packs";
  static char* argv[] = {argv0.data(), arg_quiet, arg_no_packs, nullptr};
  // SWI-Prolog's signal handling stays on: its alert signal lets call_with_time_limit/2 interrupt
  // blocking calls (sleep/1), and its SIGSEGV handler on an alternate stack turns a C-stack overflow
  // in Prolog's C code into resource_error(c_stack) instead of a crash. With --no-signals neither
  // works. The process-control signals stay the host's: their dispositions are restored. So does SIGALRM:
  // call_with_time_limit/2 does not use it (library(time) raises its own signal in the thread), and a
  // SIGALRM sent to the process became error(signal(alrm, 14)) raised inside whatever built-in was
  // running; SWI-Prolog 9.0.4 does not clear it there and aborts later on a corrupted stack (found by
  // fuzzing: libFuzzer's timeout timer is a SIGALRM).
  constexpr int kHostSignals[] = {SIGINT, SIGTERM, SIGHUP, SIGQUIT, SIGUSR1, SIGCHLD, SIGALRM};
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

void load_support_module() {
  // Once per process: loading the text again would wipe the dynamic state of the Engines that use it.
  static std::mutex mutex;
  static bool loaded = false;
  std::lock_guard lock(mutex);
  if (loaded) return;
  load_module_text(kRuleChecksText, "wm_rule_checks.pl", "wm_rule_checks:term_problem/2");
  load_module_text(kSupportModuleText, "wm_engine_support.pl", "wm_engine:reload/7");
  loaded = true;
}

}  // namespace wm::rules::internal
