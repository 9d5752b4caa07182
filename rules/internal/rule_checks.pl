:- module(wm_rule_checks,
          [ term_problem/2,       % +Term, -Message: what a rule file may not contain
            unbounded_call/4,     % +Goal, +Context, -Call, -Why: calls no time limit can stop
            forbidden_subgoal/2,  % +Goal, -Bad: database writes in a query
            bounded_term/2,       % +Term, -Bounded: a copy that prints safely
            term_text/2,          % +Term, -Text: writeq/1 text of the bounded term
            message_text/2        % +Term, -Text: the message Prolog would print, bounded
          ]).
/*  rule_checks.pl: what a rule text or a query may contain, and how terms leave the knowledge base as
    text. Pure predicates: no state, no database change; they only inspect terms.

    Part of wm::rules::Engine's support code, with engine_support.pl (module wm_engine, which imports
    these predicates and records what they find while a rule set loads). The build embeds this text
    into the library (rules/CMakeLists.txt), and the Engine loads it, as source id
    "wm_rule_checks.pl", before engine_support.pl. rule_checks.plt beside it holds its plunit tests.

    Why these checks exist: loading a rule file runs its directives and term expansion, so a rule text
    is read as terms and checked before it is loaded (term_problem/2); SWI-Prolog 9.0.4's time limit
    cannot interrupt C code that writes output of a size the arguments choose (format/2,3 column and
    fill arguments: unbounded_call/4); library(sandbox) accepts a plain assertz/1, so a read-only
    query is also checked for database writes (forbidden_subgoal/2); and SWI-Prolog writes and
    compares terms by C recursion, so a term nested some ten thousand levels deep can overflow the C
    stack of the thread that prints it (bounded_term/2). */
:- use_module(library(lists), [append/3]).

%!  message_text(+Term, -Text:string) is det.
%   The message SWI-Prolog would print for Term, without a location prefix, on one or more lines.
message_text(Term0, Text) :-
    %   A term built by a rule or a query can be nested deeper than the C stack can write.
    bounded_term(Term0, Term),
    (   Term = error(Formal, file(_, _, _, _)) -> Bare = error(Formal, _) ; Bare = Term ),
    (   catch('$messages':translate_message(Bare, Lines, []), _, fail),
        catch(with_output_to(string(S0), print_message_lines(current_output, '', Lines)), _, fail)
    ->  split_string(S0, "", " \n", [Text])
    ;   format(string(Text), "~q", [Term])
    ).

%!  bounded_term(+Term, -Bounded) is det.
%   A copy of Term that prints safely: compound terms nested deeper than max_term_depth/1 and list
%   elements beyond max_list_items/1 are replaced by '...'. SWI-Prolog writes (and compares) terms by C
%   recursion, so a term nested some ten thousand levels deep can overflow the C stack of the thread
%   that prints it; every term that leaves the knowledge base as text goes through this first.
bounded_term(Term, Bounded) :-
    max_term_depth(Depth),
    bounded_term(Term, Depth, Bounded).

max_term_depth(64).
max_list_items(1000).

bounded_term(T, _, T) :- \+ compound(T), !.
bounded_term(_, 0, '...') :- !.
bounded_term(T, D, B) :-
    D1 is D - 1,
    (   is_list_pair(T)
    ->  max_list_items(Max),
        bounded_list(T, Max, D1, B)
    ;   compound_name_arguments(T, Name, Args),
        bounded_args(Args, D1, BArgs),
        compound_name_arguments(B, Name, BArgs)
    ).

is_list_pair(T) :- compound(T), T = [_|_].

bounded_list(T, _, _, T) :- \+ is_list_pair(T), !.
bounded_list(_, 0, _, ['...']) :- !.
bounded_list([H|T], N, D, [BH|BT]) :-
    bounded_term(H, D, BH),
    N1 is N - 1,
    (   is_list_pair(T) -> bounded_list(T, N1, D, BT) ; bounded_term(T, D, BT) ).

bounded_args([], _, []).
bounded_args([A|As], D, [B|Bs]) :- bounded_term(A, D, B), bounded_args(As, D, Bs).

%!  term_text(+Term, -Text:string) is det.
%   Term as writeq/1 prints it, bounded (see bounded_term/2). Used by C++ for any term it shows.
term_text(Term, Text) :-
    bounded_term(Term, Bounded),
    format(string(Text), "~W", [Bounded, [quoted(true), portray(false), numbervars(true)]]).

%!  unbounded_call(+Goal, +Context, -Call, -Why) is semidet.
%   Call is a subterm of Goal that no time limit can interrupt once it runs (C code producing output
%   of a size the arguments choose) or, in a query (Context = query), that builds atoms, which no
%   stack limit bounds. Checked on the text of queries and on every clause of a rule set.
unbounded_call(Goal, Context, Call, Why) :-
    subterm_where(unbounded_in(Context), Goal, Call, Why).

unbounded_in(Context, Call, Why) :-
    compound(Call),
    unbounded(Call, Context, Why).

unbounded(format(F), _, Why) :- format_unbounded(F, Why).
unbounded(format(F, _), _, Why) :- format_unbounded(F, Why).
unbounded(format(_, F, _), _, Why) :- format_unbounded(F, Why).
unbounded(sformat(_, F, _), _, Why) :- format_unbounded(F, Why).
unbounded(sformat(_, F), _, Why) :- format_unbounded(F, Why).
unbounded(Call, query, Why) :-
    atom_doubling(Call),
    functor(Call, Name, Arity),
    format(string(Why), "~w can build atoms twice as long as its inputs, and atoms are not bounded \c
                         by a query's stack limit; use strings (string_concat/3, \c
                         format(string(S), ...))", [Name/Arity]).

atom_doubling(atom_concat(_, _, _)).
atom_doubling(atomic_list_concat(_, _)).
atom_doubling(atomic_list_concat(_, _, _)).
atom_doubling(term_to_atom(_, _)).
atom_doubling(format(Sink, _, _)) :- nonvar(Sink), Sink = atom(_).
atom_doubling(with_output_to(Sink, _)) :- nonvar(Sink), Sink = atom(_).

%   A format text whose column, fill or precision argument exceeds max_format_argument/1, or that
%   takes one from the arguments (*): format/2,3 would write that many characters in C.
%   A format that is not text (a compound, a number) is not looked into by format/2,3 the way text is:
%   format(member(X, [a]), atom(X)) ran past every time limit in SWI-Prolog 9.0.4 (found by fuzz_query).
format_unbounded(F, Why) :-
    nonvar(F), \+ atom(F), \+ string(F), \+ is_list(F),
    !,
    format(string(Why), "a format must be text (an atom, a string or a code list), not ~q", [F]).
format_unbounded(F, Why) :-
    (   atom(F) -> atom_codes(F, Codes)
    ;   string(F) -> string_codes(F, Codes)
    ;   is_list(F), F = [C|_], integer(C) -> Codes = F
    ),
    max_format_argument(Max),
    format_directive_argument(Codes, Argument),
    (   Argument == (*) ; integer(Argument), Argument > Max ),
    !,
    format(string(Why), "a format directive argument (~w) above ~d or taken from the arguments \c
                         (*) could write without limit", [Argument, Max]).

max_format_argument(1000).

format_directive_argument([0'~|Codes], Argument) :-
    directive_argument(Codes, Argument, _).
format_directive_argument([0'~, 0'~|Codes], Argument) :- !,
    format_directive_argument(Codes, Argument).
format_directive_argument([_|Codes], Argument) :-
    format_directive_argument(Codes, Argument).

directive_argument([0'`, _|Codes], Argument, Rest) :- !,        % ~`ct: a fill character
    directive_argument(Codes, Argument, Rest).
directive_argument([0'*|Rest], (*), Rest) :- !.
directive_argument([D|Codes], Argument, Rest) :-
    code_type(D, digit(W)),
    digits(Codes, W, Argument, Rest).

digits([D|Codes], N0, N, Rest) :-
    code_type(D, digit(W)), !,
    N1 is N0 * 10 + W,
    digits(Codes, N1, N, Rest).
digits(Rest, N, N, Rest).

%   Database writes the sandbox lets through (it accepts assertz/1 on the calling module).
forbidden_subgoal(Goal, Bad) :-
    subterm_where(forbidden_call, Goal, Bad, _).

forbidden_call(Goal, Name/Arity) :-
    ( Goal = _:G -> true ; G = Goal ),
    callable(G),
    functor(G, Name, Arity),
    forbidden(Name, Arity).

%!  subterm_where(:Test, +Term, -Sub, -Info) is semidet.
%   Sub is the first callable subterm of Term (itself included, depth first) for which
%   call(Test, Sub, Info) is true. A deterministic walk over an agenda: sub_term/2 leaves a choice
%   point per level and takes quadratic time (and a deep stack) on a chain like 1+1+...+1.
subterm_where(Test, Term, Sub, Info) :-
    subterm_in([Term], Test, Sub, Info).

subterm_in([T|Ts], Test, Sub, Info) :-
    (   callable(T), call(Test, T, Info0)
    ->  Sub = T, Info = Info0
    ;   compound(T)
    ->  compound_name_arguments(T, _, Args),
        append(Args, Ts, Agenda),
        subterm_in(Agenda, Test, Sub, Info)
    ;   subterm_in(Ts, Test, Sub, Info)
    ).

forbidden(Name, _) :-
    memberchk(Name, [assert, asserta, assertz, retract, retractall, abolish, erase, recorda, recordz,
                     flag, nb_setval, b_setval, set_prolog_flag, dynamic, multifile, discontiguous,
                     compile_predicates, garbage_collect_clauses, transaction, snapshot]).

%!  term_problem(+Term, -Message:string) is semidet.
%   True when Term, read from a rule file, may not stand there; Message says why. A rule file holds
%   clauses of the rule module and the directives allowed_directive/1 lists: no other directive, no
%   clause for another module (user:foo.), no clause for a hook of Prolog itself. A bad head that
%   Prolog itself refuses is left to load_files/2 to report.
term_problem(Term, Message) :-
    var(Term), !,
    Message = "a clause may not be a variable".
term_problem((:- Directive), Message) :- !,
    directive_problem(Directive, Message).
term_problem((?- Directive), Message) :- !,
    directive_problem(Directive, Message).
term_problem((Head --> _), Message) :- !,
    head_problem(Head, 2, Message).
term_problem((Head :- _), Message) :- !,
    head_problem(Head, 0, Message).
term_problem(Head, Message) :-
    head_problem(Head, 0, Message).

directive_problem(Directive, Message) :-
    (   var(Directive)
    ->  Message = "a directive may not be a variable"
    ;   Directive = module(Other, _)
    ->  format(string(Message), "rule files are plain clauses: remove the module declaration (~q)", [Other])
    ;   allowed_directive(Directive)
    ->  fail
    ;   bounded_term(Directive, Shown),
        safe_libraries(Libraries),
        atomic_list_concat(Libraries, '|', Names),
        format(string(Message),
               "directive ~q is not allowed in a rule file (rule files are loaded without running \c
                code; allowed: use_module/ensure_loaded of library(~w), and dynamic, discontiguous, \c
                multifile of the file's own predicates)", [(:- Shown), Names])
    ).

allowed_directive(use_module(library(L))) :- safe_library(L).
allowed_directive(use_module(library(L), Imports)) :- safe_library(L), is_list(Imports).
allowed_directive(ensure_loaded(library(L))) :- safe_library(L).
allowed_directive(dynamic(PIs)) :- local_indicators(PIs).
allowed_directive(discontiguous(PIs)) :- local_indicators(PIs).
allowed_directive(multifile(PIs)) :- local_indicators(PIs).
allowed_directive(encoding(utf8)).

safe_libraries([lists, apply, aggregate, pairs, yall, error, ordsets, assoc, rbtrees, option,
                solution_sequences, occurs, strings, dicts]).

safe_library(L) :- atom(L), safe_libraries(Ls), memberchk(L, Ls).

local_indicators(PIs) :- var(PIs), !, fail.
local_indicators((A, B)) :- !, local_indicators(A), local_indicators(B).
local_indicators([]) :- !.
local_indicators([PI|PIs]) :- !, local_indicators(PI), local_indicators(PIs).
local_indicators(Name/Arity) :- !, atom(Name), integer(Arity), between(0, 64, Arity).
local_indicators(Name//Arity) :- atom(Name), integer(Arity), between(0, 62, Arity).

head_problem(Head, Extra, Message) :-
    (   var(Head)
    ->  Message = "a clause head may not be a variable"
    ;   Head = Module:_
    ->  bounded_term(Module, Shown),
        format(string(Message),
               "clauses for another module (~q:...) are not allowed: rule files define \c
                predicates of the rule module only", [Shown])
    ;   callable(Head),
        functor(Head, Name, Arity0),
        Arity is Arity0 + Extra,
        reserved_head(Name/Arity)
    ->  format(string(Message), "~q is a hook of Prolog itself; rule files may not define it", [Name/Arity])
    ).

%   Hooks Prolog calls on its own while loading or printing: defining them would run code.
reserved_head(term_expansion/2).
reserved_head(term_expansion/4).
reserved_head(goal_expansion/2).
reserved_head(goal_expansion/4).
reserved_head(message_hook/3).
reserved_head(portray/1).
reserved_head(prolog_load_file/2).
reserved_head(exception/3).
