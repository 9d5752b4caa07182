/*  plunit tests for rule_checks.pl (module wm_rule_checks): what a rule text or a query may contain,
    and bounded printing of terms.

    Run:  swipl -g run_tests -t halt rules/internal/rule_checks.plt
    (ctest runs it as rules_checks_plunit.)

    Each test states values: what a check refuses and with which message, what it accepts, how far a
    term is cut.
*/
:- use_module(library(plunit)).
:- use_module(library(lists)).
:- use_module(library(apply)).

:- prolog_load_context(directory, Dir),
   directory_file_path(Dir, 'rule_checks.pl', File),
   use_module(File, []).

%!  deep(+Depth, -Term) is det.  f(f(...f(x)...)) nested Depth levels.
deep(0, x) :- !.
deep(N, f(T)) :- N1 is N - 1, deep(N1, T).

depth(T, 0) :- \+ compound(T), !.
depth(T, D) :- T =.. [_|Args], foldl([A, D0, D1]>>(depth(A, DA), D1 is max(D0, DA)), Args, 0, M), D is M + 1.

:- begin_tests(term_problem).

problem(Term, Message) :- wm_rule_checks:term_problem(Term, Message).

test(accepts_a_fact, [fail]) :- problem(wall(w1), _).
test(accepts_a_rule, [fail]) :- problem((a(X) :- b(X)), _).
test(accepts_a_grammar_rule, [fail]) :- problem((greeting --> [hello]), _).
test(accepts_use_module_of_a_safe_library, [fail]) :- problem((:- use_module(library(lists))), _).
test(accepts_dynamic_of_own_predicates, [fail]) :- problem((:- dynamic((seen/1, count//2))), _).

test(refuses_initialization, [M == "directive :-initialization main is not allowed in a rule file (rule files are loaded without running code; allowed: use_module/ensure_loaded of library(lists|apply|aggregate|pairs|yall|error|ordsets|assoc|rbtrees|option|solution_sequences|occurs|strings|dicts), and dynamic, discontiguous, multifile of the file's own predicates)"]) :-
    problem((:- initialization(main)), M).

test(refuses_an_unsafe_library, [true(sub_string(M, 0, _, _, "directive :-use_module(library(process)) is not allowed"))]) :-
    problem((:- use_module(library(process))), M).

test(refuses_a_clause_for_user, [M == "clauses for another module (user:...) are not allowed: rule files define predicates of the rule module only"]) :-
    problem(user:foo, M).

test(refuses_a_rule_for_user, [true(sub_string(M, 0, _, _, "clauses for another module (user:...)"))]) :-
    problem((user:foo :- true), M).

test(refuses_message_hook, [M == "message_hook/3 is a hook of Prolog itself; rule files may not define it"]) :-
    problem((message_hook(_, _, _) :- true), M).

test(refuses_term_expansion_as_dcg, [M == "term_expansion/2 is a hook of Prolog itself; rule files may not define it"]) :-
    problem((term_expansion --> []), M).

test(refuses_a_module_declaration, [M == "rule files are plain clauses: remove the module declaration (m)"]) :-
    problem((:- module(m, [])), M).

test(refuses_a_variable_directive, [M == "a directive may not be a variable"]) :-
    problem((:- _), M).

test(refuses_a_variable_clause, [M == "a clause may not be a variable"]) :-
    problem(_, M).

test(refuses_dynamic_of_another_module, [true(sub_string(M, 0, _, _, "directive :-dynamic user:foo/1"))]) :-
    problem((:- dynamic(user:foo/1)), M).

test(refuses_an_arity_above_64, [true(sub_string(M, 0, _, _, "directive :-dynamic p/65"))]) :-
    problem((:- dynamic(p/65)), M).

:- end_tests(term_problem).

:- begin_tests(bounded_term).

test(keeps_a_small_term, [B == f(a, [1, 2], "s")]) :-
    wm_rule_checks:bounded_term(f(a, [1, 2], "s"), B).

test(cuts_depth_at_64, [D == 64]) :-
    deep(1000, T),
    wm_rule_checks:bounded_term(T, B),
    depth(B, D),
    assertion(sub_term('...', B)).

test(cuts_a_long_list_after_1000_items, [N-Last == 1001-'...']) :-
    numlist(1, 5000, L),
    wm_rule_checks:bounded_term(L, B),
    length(B, N),
    last(B, Last).

test(term_text_of_a_deep_term_is_short, [true(Length < 1000)]) :-
    deep(100000, T),
    wm_rule_checks:term_text(T, Text),
    string_length(Text, Length).

test(term_text_quotes, [Text == "f('A b',\"s\")"]) :-
    wm_rule_checks:term_text(f('A b', "s"), Text).

:- end_tests(bounded_term).

:- begin_tests(unbounded_calls).

unbounded(Goal, Context) :- wm_rule_checks:unbounded_call(Goal, Context, _, _).

test(refuses_a_star_column_argument, [Why == "a format directive argument (*) above 1000 or taken from the arguments (*) could write without limit"]) :-
    wm_rule_checks:unbounded_call(format("~*c", [100, 0'x]), rule, Call, Why),
    assertion(Call == format("~*c", [100, 0'x])).

test(refuses_a_column_above_1000) :-
    unbounded(format(atom(_), "~1001|x", []), rule).

test(refuses_a_fill_character_with_a_large_column) :-
    unbounded((true, format("~`-t~5000|~n", [])), rule).

test(refuses_a_large_column_in_format_1) :-
    unbounded(format("~100000000|x"), rule).

test(accepts_a_column_of_1000, [fail]) :-
    unbounded(format("~1000|x"), rule).

test(accepts_an_escaped_tilde_before_a_star, [fail]) :-
    unbounded(format("~~*c", []), rule).

test(accepts_plain_directives, [fail]) :-
    unbounded(format("~w and ~a~n", [x, y]), query).

test(refuses_atom_building_in_a_query, [true(sub_string(Why, 0, _, _, "atom_concat/3 can build atoms"))]) :-
    wm_rule_checks:unbounded_call((X = a, atom_concat(X, X, _)), query, _, Why).

test(allows_atom_building_in_a_rule, [fail]) :-
    unbounded(atom_concat(a, b, _), rule).

test(finds_a_write_in_a_nested_goal, [Bad =@= assertz(seen(_))]) :-
    wm_rule_checks:forbidden_subgoal((member(X, [1]), \+ \+ (X > 0, assertz(seen(X)))), Bad).

test(finds_no_write_in_a_read_only_goal, [fail]) :-
    wm_rule_checks:forbidden_subgoal((member(X, [1]), X > 0), _).

:- end_tests(unbounded_calls).

:- begin_tests(messages).

test(type_error_is_printed_as_prolog_would, [true(sub_string(Text, _, _, _, "Type error"))]) :-
    wm_rule_checks:message_text(error(type_error(integer, a), _), Text).

test(unknown_term_is_written_quoted, [Text == "Unknown message: my_problem('X')"]) :-
    wm_rule_checks:message_text(my_problem('X'), Text).

:- end_tests(messages).

