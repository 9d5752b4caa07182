#include "rules/internal/runtime.h"

#include <SWI-Prolog.h>

#include <clocale>
#include <csignal>
#include <filesystem>
#include <iterator>
#include <string>
#include <system_error>

#include "rules/internal/engine_support_pl.h"  // generated from engine_support.pl
#include "rules/internal/prolog_api.h"
#include "rules/internal/text_checks.h"
#include "rules/types.h"

namespace wm::rules::internal {
namespace {

// Source id the support module is loaded under (shows in its messages); not a file on disk.
constexpr const char* kSupportModuleSourceId = "wm_engine_support.pl";

std::filesystem::path home_hint_argv0() {
  // PL_initialise derives the home from argv[0] when it can and otherwise falls back to the home
  // compiled into libswipl, which is right for the Debian package. The running executable is the
  // honest argv[0]; an executable without an attached saved state makes SWI use its boot file.
  std::error_code ec;
  auto self = std::filesystem::read_symlink("/proc/self/exe", ec);
  return ec ? std::filesystem::path("wmd") : self;
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

void load_support_module() {
  constexpr const char* kWhat = "Engine (loading the support module)";
  Frame frame;
  term_t open_args = PL_new_term_refs(2);  // open_string(+Text, -Stream)
  put_string(open_args, kSupportModuleText, kWhat);
  call_or_throw(PL_predicate("open_string", 2, "system"), open_args, kWhat);
  term_t stream = open_args + 1;

  term_t load_args = PL_new_term_refs(2);  // load_files(+Id, +[stream(Stream), silent(true)])
  put_atom(load_args, kSupportModuleSourceId);
  term_t option = PL_new_term_ref();
  PL_put_nil(load_args + 1);
  require_stack(PL_put_atom_chars(option, "true"), kWhat);
  put_functor(option, PL_new_functor(PL_new_atom("silent"), 1), option, kWhat);
  cons(load_args + 1, option);
  put_functor(option, PL_new_functor(PL_new_atom("stream"), 1), stream, kWhat);
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

}  // namespace wm::rules::internal
