#pragma once

// Thin helpers over SWI-Prolog's C API for rules::Engine: RAII over frames and string buffers,
// reading and building terms, calling a predicate once. Internal to rules/ (the public headers carry
// no Prolog type). Every function here must run on a thread with an attached Prolog engine, and every
// term it takes or returns belongs to that thread.
//
// Errors: a failure to build a term means the Prolog stacks are exhausted (or a text is refused, for
// atoms); it throws rules::RuleError naming the caller's `where`.

#include <SWI-Prolog.h>

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>

namespace wm::rules::internal {

/// Name of the support module (rules/internal/engine_support.pl) that holds every entry point C++ calls.
inline constexpr const char* kSupportModuleName = "wm_engine";
/// Name of the module of rule and query checks and bounded printing (rules/internal/rule_checks.pl).
inline constexpr const char* kRuleChecksModuleName = "wm_rule_checks";

/// @throw RuleError("<function>: thread not attached ...") when the calling thread has no Prolog engine.
void require_attached(const char* function);

/// @throw RuleError("<where>: out of Prolog stack") when `ok` is false: the one check after every C API
/// call that builds a term (PL_cons_functor_v, PL_put_int64, PL_cons_list, ...).
void require_stack(int ok, std::string_view where);

/// RAII over a foreign frame: every term created inside is released at scope end.
class Frame {
 public:
  /// @throw RuleError when no frame can be opened (out of stack).
  Frame();
  ~Frame();
  Frame(const Frame&) = delete;
  Frame& operator=(const Frame&) = delete;

 private:
  fid_t fid_;
};

/// Releases the string buffers PL_get_nchars() pushes, whatever BUF_* flag is used: without it the
/// buffer stack grows by one per call and SWI-Prolog aborts the process ("Too many stacked strings")
/// after some thousand decisions.
class StringBufferMark {
 public:
  StringBufferMark() { PL_mark_string_buffers(&mark_); }
  ~StringBufferMark() { PL_release_string_buffers_from_mark(mark_); }
  StringBufferMark(const StringBufferMark&) = delete;
  StringBufferMark& operator=(const StringBufferMark&) = delete;

 private:
  buf_mark_t mark_;
};

/// Text of an atom or string term (UTF-8); nullopt for any other term.
std::optional<std::string> text_of(term_t t);

/// Any term as writeq/1 prints it, bounded by wm_rule_checks:term_text/2 (depth 64, 1000 list items):
/// PL_get_nchars(CVT_WRITEQ) writes by C recursion, and a term a rule or query built ten thousand
/// levels deep overflows the thread's C stack there. "<unprintable Prolog term>" when that fails.
std::string written(term_t t);

/// Text of an atom or string term, else the term as written().
std::string text_or_written(term_t t);

/// Puts an atom with the UTF-8 `text`. @throw RuleError("rules: cannot create the atom '...'").
void put_atom(term_t t, std::string_view text);
/// Puts a string with the UTF-8 `text`. @throw RuleError("<where>: out of Prolog stack").
void put_string(term_t t, std::string_view text, std::string_view where);
void put_float(term_t t, double value);
void put_int64(term_t t, std::int64_t value, std::string_view where);
/// Puts `name`(args...) with the arity of `f`. @throw RuleError("<where>: out of Prolog stack").
void put_functor(term_t t, functor_t f, term_t args, std::string_view where);
/// Conses `head` in front of the list `list` (in place). @throw RuleError when out of stack.
void cons(term_t list, term_t head);

/// Calls pred(args...) once. Returns the error text when it fails or raises, nullopt on success; the
/// bindings stay readable until the enclosing Frame ends.
std::optional<std::string> call_once(predicate_t pred, term_t args);

/// call_once(), throwing RuleError("<function>: <error>") on failure or exception.
void call_or_throw(predicate_t pred, term_t args, const char* function);

}  // namespace wm::rules::internal
