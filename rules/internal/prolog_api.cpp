#include "rules/internal/prolog_api.h"

#include <utility>

#include "rules/types.h"

namespace wm::rules::internal {

void require_attached(const char* function) {
  if (PL_thread_self() < 0) {
    throw RuleError(std::string(function) + ": thread not attached (use rules::ThreadAttachment)");
  }
}

void require_stack(int ok, std::string_view where) {
  if (!ok) throw RuleError(std::string(where) + ": out of Prolog stack");
}

Frame::Frame() : fid_(PL_open_foreign_frame()) {
  if (fid_ == 0) throw RuleError("rules: cannot open a Prolog frame (out of stack?)");
}

Frame::~Frame() { PL_discard_foreign_frame(fid_); }

std::optional<std::string> text_of(term_t t) {
  StringBufferMark mark;
  std::size_t length = 0;
  char* chars = nullptr;
  if (!PL_get_nchars(t, &length, &chars, CVT_ATOM | CVT_STRING | REP_UTF8 | BUF_STACK)) {
    return std::nullopt;
  }
  return std::string(chars, length);
}

std::string written(term_t t) {
  const fid_t frame = PL_open_foreign_frame();
  if (frame == 0) return "<unprintable Prolog term>";
  std::string text = "<unprintable Prolog term>";
  term_t args = PL_new_term_refs(2);  // term_text(+Term, -Text)
  if (PL_put_term(args, t) && PL_call_predicate(nullptr, PL_Q_NODEBUG | PL_Q_CATCH_EXCEPTION,
                                                PL_predicate("term_text", 2, kRuleChecksModuleName), args)) {
    if (auto chars = text_of(args + 1)) text = std::move(*chars);
  }
  PL_discard_foreign_frame(frame);
  return text;
}

std::string text_or_written(term_t t) {
  if (auto text = text_of(t)) return std::move(*text);
  return written(t);
}

void put_atom(term_t t, std::string_view text) {
  if (!PL_put_chars(t, PL_ATOM | REP_UTF8, text.size(), text.data())) {
    throw RuleError("rules: cannot create the atom '" + std::string(text) + "'");
  }
}

void put_string(term_t t, std::string_view text, std::string_view where) {
  require_stack(PL_put_chars(t, PL_STRING | REP_UTF8, text.size(), text.data()), where);
}

void put_float(term_t t, double value) {
  if (!PL_put_float(t, value)) throw RuleError("rules: cannot create a Prolog float");
}

void put_int64(term_t t, std::int64_t value, std::string_view where) { require_stack(PL_put_int64(t, value), where); }

void put_functor(term_t t, functor_t f, term_t args, std::string_view where) {
  require_stack(PL_cons_functor_v(t, f, args), where);
}

void cons(term_t list, term_t head) {
  if (!PL_cons_list(list, head, list)) throw RuleError("rules: cannot build a Prolog list (out of stack?)");
}

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

void call_or_throw(predicate_t pred, term_t args, const char* function) {
  if (auto error = call_once(pred, args)) throw RuleError(std::string(function) + ": " + *error);
}

}  // namespace wm::rules::internal
