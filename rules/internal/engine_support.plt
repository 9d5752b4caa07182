/*  plunit tests for engine_support.pl, the Prolog half of rules::Engine (module wm_engine).

    Run:  swipl -g run_tests -t halt rules/internal/engine_support.plt
    (ctest runs it as rules_support_plunit.)

    The modules are loaded from their files here, rule_checks.pl first as the Engine does; the Engine
    loads the same texts embedded in the library. The Engine registers one foreign predicate in
    wm_engine, text_nesting_exceeds/3; a Prolog stand-in below counts brackets the same way for plain
    texts (the C++ counter itself, with quotes, comments and 0'c literals, is tested through the
    Engine in tests/rules/engine_security_test.cpp).

    Each test states values: what a check refuses and with which message, what it accepts, what a
    decision, query or reload answers. The stateless checks have their own tests in rule_checks.plt.
*/
:- use_module(library(plunit)).
:- use_module(library(lists)).
:- use_module(library(apply)).

:- prolog_load_context(directory, Dir),
   forall(member(Name, ['rule_checks.pl', 'engine_support.pl']),   % the order the Engine loads them in
          ( directory_file_path(Dir, Name, File), use_module(File, []) )),
   assertz(test_dir(Dir)).

%   Stand-in for the foreign predicate: depth of ( [ { in Text, ignoring quotes and comments.
wm_engine:text_nesting_exceeds(Text, Max, Line) :-
    string_codes(Text, Codes),
    nesting(Codes, 0, Max, 1, Line).

nesting([C|Cs], Depth, Max, Line0, Line) :-
    (   memberchk(C, `([{`)
    ->  Depth1 is Depth + 1,
        (   Depth1 > Max -> Line = Line0 ; nesting(Cs, Depth1, Max, Line0, Line) )
    ;   memberchk(C, `)]}`)
    ->  Depth1 is max(0, Depth - 1), nesting(Cs, Depth1, Max, Line0, Line)
    ;   C == 0'\n
    ->  Line1 is Line0 + 1, nesting(Cs, Depth, Max, Line1, Line)
    ;   nesting(Cs, Depth, Max, Line0, Line)
    ).

:- wm_engine:init(wm_kb).

%!  rule_text_problems(+Text, -Problems:list(string)) is det.
%   The problems check_rule_text/3 records for Text as file t.pl (empty when accepted).
rule_text_problems(Text, Problems) :-
    retractall(wm_engine:load_problem(_)),
    wm_engine:check_rule_text('t.pl', Text, wm_support_test_rules),
    findall(P, wm_engine:load_problem(P), Problems),
    retractall(wm_engine:load_problem(_)).

%   (wm_engine:query/6 and the other entry points expect an unbound result argument: they test it with
%   nonvar/1 on the way. Tests bind the result after the call.)

%!  refused_with(+Text, +Part) is semidet.
%   Text gives exactly one problem, on t.pl, whose message contains Part.
refused_with(Text, Part) :-
    rule_text_problems(Text, [Problem]),
    string_concat("t.pl:", _, Problem),
    once(sub_string(Problem, _, _, _, Part)).

%!  starts(+String, +Prefix) is semidet.
starts(String, Prefix) :- string_concat(Prefix, _, String).

shipped_rule_file(Path) :-
    test_dir(Dir),
    member(Rel, ['../prolog/world_model.pl', '../examples/glass.pl', '../examples/movable.pl',
                 '../examples/prune_unconfirmed.pl']),
    directory_file_path(Dir, Rel, Path).

%!  deep(+Depth, -Term) is det.  f(f(...f(x)...)) nested Depth levels.
deep(0, x) :- !.
deep(N, f(T)) :- N1 is N - 1, deep(N1, T).

depth(T, 0) :- \+ compound(T), !.
depth(T, D) :- T =.. [_|Args], foldl([A, D0, D1]>>(depth(A, DA), D1 is max(D0, DA)), Args, 0, M), D is M + 1.

%   A rule set given as texts, decided with generous limits.
load_rules(Texts) :-
    findall(text(Name, Text), member(Name-Text, Texts), Files),
    wm_engine:reload(wm_kb, Files, test_rules, 100000, 5.0, 0.0, Result),
    assertion(Result = ok(_)).

minimal_rules("decide(_, none, add, unmatched, \"nothing matched\").
decide(_, element(_, _, _), delete, matched, \"it is there\").
").

decide(Observation, Match, Result) :-
    wm_engine:decide(wm_kb, Observation, Match, context(client, lidar), 100000, 5.0, Result).

:- begin_tests(check_rule_text).

test(accepts_the_shipped_rules, [forall(shipped_rule_file(Path)), Problems == []]) :-
    read_file_to_string(Path, Text, [encoding(utf8)]),
    rule_text_problems(Text, Problems).

test(accepts_allowed_directives, [Problems == []]) :-
    rule_text_problems(":- use_module(library(lists)).
:- use_module(library(apply), [maplist/3]).
:- ensure_loaded(library(pairs)).
:- dynamic seen/1.
:- discontiguous((a/1, b//2)).
:- multifile [c/0].
:- encoding(utf8).
a(1).
", Problems).

test(refuses_a_directive_outside_the_allow_list) :-
    refused_with(":- initialization(halt).\n", "t.pl:1: directive :-initialization halt is not allowed in a rule file").

test(refuses_a_library_outside_the_allow_list) :-
    refused_with(":- use_module(library(process)).\n", "is not allowed in a rule file").

test(refuses_loading_a_file) :-
    refused_with(":- use_module('/etc/passwd').\n", "is not allowed in a rule file").

test(refuses_a_query_directive) :-
    refused_with("?- shell(ls).\n", "t.pl:1: directive :-shell(ls) is not allowed in a rule file").

test(refuses_dynamic_of_another_module) :-
    refused_with(":- dynamic user:foo/1.\n", "is not allowed in a rule file").

test(refuses_a_clause_for_user) :-
    refused_with("user:foo.\n", "clauses for another module (user:...) are not allowed").

test(refuses_a_rule_for_another_module) :-
    refused_with("lists:append(_, _, _) :- true.\n", "clauses for another module (lists:...)").

test(refuses_term_expansion) :-
    refused_with("term_expansion(X, X).\n", "term_expansion/2 is a hook of Prolog itself").

test(refuses_goal_expansion_as_dcg_head) :-
    refused_with("goal_expansion --> [].\n", "goal_expansion/2 is a hook of Prolog itself").

test(refuses_a_module_declaration) :-
    refused_with(":- module(mine, []).\n", "remove the module declaration (mine)").

test(refuses_a_variable_clause) :-
    refused_with("X :- X = 1.\n", "a clause head may not be a variable").

test(reports_a_syntax_error_with_its_line) :-
    rule_text_problems("a(1).\nb(2).\nc(3 .\n", [P]),
    starts(P, "t.pl:3:").

test(reports_every_problem_in_order) :-
    rule_text_problems("user:a.\nb.\n:- initialization(x).\n", [P1, P2]),
    starts(P1, "t.pl:1:"),
    starts(P2, "t.pl:3:").

test(refuses_nesting_deeper_than_200_levels) :-
    length(Open, 201), maplist(=(0'(), Open),
    string_codes(Deep, Open),
    string_concat("a(", Deep, Text),
    refused_with(Text, "brackets nested deeper than 200 levels").

:- end_tests(check_rule_text).

:- begin_tests(decisions, [cleanup(wm_engine:shutdown(wm_kb))]).

test(reload_answers_one_hash_per_file, [setup(minimal_rules(R))]) :-
    wm_engine:reload(wm_kb, [text('a.pl', R)], test_rules, 100000, 5.0, 0.0, Result),
    Result = ok([Hash]),
    atom_length(Hash, 64).

test(decides_from_the_active_rules, [Results == [decision(add, "unmatched", "nothing matched"),
                                                 decision(delete, "matched", "it is there")]]) :-
    minimal_rules(R),
    load_rules(['a.pl'-R]),
    decide(observation(r1, 1.0, 0.0, 2.0), none, R1),
    decide(observation(r1, 1.0, 0.0, 2.0), element(e1, none, 0.5), R2),
    Results = [R1, R2].

test(a_looping_rule_hits_the_inference_limit) :-
    load_rules(['a.pl'-"decide(_, none, add, r, \"x\").
decide(O, element(E, X, M), A, R, W) :- E == loop, !, decide(O, element(E, X, M), A, R, W).
decide(_, element(_, _, _), delete, r, \"x\").
"]),
    decide(observation(r1, 1.0, 0.0, 2.0), element(loop, none, 0.5), error(Msg)),
    starts(Msg, "inference limit of 100,000 exceeded").

test(an_action_that_is_not_an_atom_is_an_error,
     [Result == error("decide/5 answered an action that is not an atom: \"add\"")]) :-
    wm_engine:answer_result(answer("add", r, x), 100000, 5.0, Result).

test(rules_answering_a_string_action_fail_the_self_check, [N == 4]) :-
    wm_engine:reload(wm_kb, [text('a.pl', "decide(_, _, \"add\", r, x).")], test_rules, 100000, 5.0, 0.0,
                     error(Problems)),
    length(Problems, N),
    forall(member(P, Problems),
           ( starts(P, "a.pl:1: self-check '"),
             sub_string(P, _, _, 0, "decide/5 answered an action that is not an atom: \"add\"") )).

test(a_failing_rule_is_an_error, [Result == error("no rule applies (decide/5 failed)")]) :-
    load_rules(['a.pl'-"decide(_, none, add, r, x).
decide(_, element(_, _, _), delete, r, x)."]),
    decide(observation(r1, 1.0, 0.0, 2.0), other, Result).

test(batch_answers_each_case, [Results == [decision(add, "unmatched", "nothing matched"),
                                           error("no rule applies (decide/5 failed)")]]) :-
    minimal_rules(R),
    load_rules(['a.pl'-R]),
    wm_engine:decide_batch(wm_kb, [case(observation(r1, 1.0, 0.0, 2.0), none, context(client, lidar)),
                            case(observation(r1, 1.0, 0.0, 2.0), other, context(client, lidar))],
                           100000, 5.0, Results).

test(the_context_is_visible_to_rules, [Result == decision(add, "ctx", "scan/sonar")]) :-
    load_rules(['a.pl'-"decide(_, _, add, ctx, X) :- observation_origin(O), observation_sensor(S),
    format(string(X), \"~w/~w\", [O, S])."]),
    wm_engine:decide(wm_kb, observation(r1, 1.0, 0.0, 2.0), none, context(scan, sonar), 100000, 5.0, Result).

test(a_rejected_reload_keeps_the_active_rules, [Answer == decision(add, "unmatched", "nothing matched")]) :-
    minimal_rules(R),
    load_rules(['a.pl'-R]),
    wm_engine:reload(wm_kb, [text('b.pl', "decide(_, _, add, r, x) :- .")], test_rules, 100000, 5.0, 0.0, Result),
    assertion(( Result = error([P|_]), starts(P, "b.pl:1:") )),
    decide(observation(r1, 1.0, 0.0, 2.0), none, Answer).

test(rules_without_decide_fail_the_self_check, [Result == error(["test_rules: no rule file defines decide/5"])]) :-
    wm_engine:reload(wm_kb, [text('a.pl', "helper(1).")], test_rules, 100000, 5.0, 0.0, Result).

test(rules_that_fail_a_canonical_case_are_refused, [true(sub_string(P, _, _, _, "self-check 'unmatched'"))]) :-
    wm_engine:reload(wm_kb, [text('a.pl', "decide(_, element(_, _, _), delete, r, x).")],
                     test_rules, 100000, 5.0, 0.0, error([P])).

test(a_call_to_an_undefined_predicate_is_refused,
     [true(sub_string(P, _, _, _, "a.pl:1: decide/5 calls the undefined predicate hepler/0"))]) :-
    wm_engine:reload(wm_kb, [text('a.pl', "decide(_, _, add, r, x) :- hepler.")], test_rules, 100000, 5.0, 0.0,
                     error([P|_])).

test(a_rule_that_writes_files_is_refused, [true(sub_string(P, _, _, _, "can reach a call that rules may not make"))]) :-
    wm_engine:reload(wm_kb, [text('a.pl', "decide(_, _, add, r, x) :- open('/tmp/x', write, S), close(S).")],
                     test_rules, 100000, 5.0, 0.0, error(Problems)),
    member(P, Problems).

test(a_format_with_a_term_for_its_format_is_refused_without_reaching_the_sandbox,
     [true(sub_string(P, _, _, _, "a format must be text"))]) :-
    wm_engine:reload(wm_kb, [text('a.pl', "decide(_, _, add, r, E) :- format(string(E), x).")],
                     test_rules, 100000, 5.0, 0.0, error([P])).

%   library(sandbox) of SWI-Prolog 9.0.4 never returns on format/2 with a term for its format.
test(the_sandbox_check_stops_at_its_time_limit, [true(sub_atom(F, _, _, _, "did not finish within"))]) :-
    get_time(T0),
    wm_engine:sandbox_refusal(format(atom(_), x), 0.3, format(F, [0.3])),
    get_time(T1),
    assertion(T1 - T0 < 5).

test(the_sandbox_check_passes_a_safe_goal, [fail]) :-
    wm_engine:sandbox_refusal(format(string(_), "~w", [x]), 5.0, _).

test(a_singleton_warning_refuses_the_rules, [true(sub_string(P, _, _, _, "Singleton"))]) :-
    wm_engine:reload(wm_kb, [text('a.pl', "decide(O, _, add, r, x).")], test_rules, 100000, 5.0, 0.0,
                     error(Problems)),
    member(P, Problems).

test(dry_run_decides_with_the_candidate_only, [Dry-Active == [decision(merge, "cand", "x")]-decision(add, "unmatched", "nothing matched")]) :-
    minimal_rules(R),
    load_rules(['a.pl'-R]),
    wm_engine:dry_run(wm_kb, [text('a.pl', "decide(_, _, merge, cand, x).")], test_rules,
                      [case(observation(r1, 1.0, 0.0, 2.0), none, context(client, lidar))], 100000, 5.0,
                      ok(Dry)),
    decide(observation(r1, 1.0, 0.0, 2.0), none, Active).

:- end_tests(decisions).

:- begin_tests(facts, [cleanup(wm_engine:shutdown(wm_kb))]).

test(set_floor_plan_replaces_all_facts, [Facts == [object(t1, table), attribute(t1, not_deformable),
                                                   edge(t1, t1_e0, 1.0, 0.5, 0.8)]]) :-
    wm_engine:set_floor_plan(wm_kb, [object(w1, wall, [solid], [edge(w1_e0, 2.0, 0.0, 4.0)])]),
    wm_engine:set_floor_plan(wm_kb, [object(t1, table, [not_deformable, not_deformable],
                                     [edge(t1_e0, 1.0, 0.5, 0.8)])]),
    findall(F, ( member(F, [object(_, _), attribute(_, _), edge(_, _, _, _, _)]), wm_kb:F ), Facts).

test(add_decisions_keeps_the_newest, [Seqs == [3, 4]]) :-
    Ds = [decision(1, delete, r, e1, w1, robot, 1.0), decision(2, add, r, none, none, robot, 2.0)],
    wm_engine:add_decisions(wm_kb, Ds, 2),
    wm_engine:add_decisions(wm_kb, [decision(3, merge, r, e2, none, robot, 3.0),
                             decision(4, add, r, none, none, robot, 4.0)], 2),
    findall(S, wm_kb:decision(S, _, _, _, _, _, _), Seqs).

test(update_elements_upserts_and_removes, [Ids-Support == [e2, e3]-5]) :-
    wm_engine:set_elements(wm_kb, [element(e1, client, r, 1.0, 0.0, 1.0, 1, 0.0),
                            element(e2, client, r, 1.0, 0.0, 1.0, 1, 0.0)]),
    wm_engine:update_elements(wm_kb, [element(e2, client, r, 1.0, 0.0, 1.0, 5, 0.0),
                               element(e3, scan, r, 2.0, 0.0, 1.0, 1, 0.0)], [e1]),
    findall(Id, wm_kb:element(Id, _, _, _, _, _, _, _), Ids0),
    msort(Ids0, Ids),
    wm_kb:element(e2, _, _, _, _, _, Support, _).

:- end_tests(facts).

:- begin_tests(queries, [setup(( minimal_rules(R), load_rules(['a.pl'-R]),
                                 wm_engine:set_floor_plan(wm_kb, [object(w1, wall, [solid], [])]) )),
                         cleanup(wm_engine:shutdown(wm_kb))]).

query(Text, Result) :- wm_engine:query(wm_kb, Text, 10, 100000, 5.0, Result).

test(answers_bindings_in_order, [Result == ok(["O", "K"], [[w1, wall]], false)]) :-
    query("object(O, K)", Result).

test(truncates_at_max_solutions, [Result == ok(["X"], [[1], [2]], true)]) :-
    wm_engine:query(wm_kb, "between(1, 5, X)", 2, 100000, 5.0, Result).

test(refuses_a_write, [Result == unsafe("assertz(object(x,wall)) changes the knowledge base; queries are read-only")]) :-
    query("assertz(object(x, wall))", Result).

test(refuses_atom_building) :-
    query("atom_concat(a, b, X)", Result),
    Result = unsafe(Msg),
    starts(Msg, "atom_concat(a,b,_"),
    once(sub_string(Msg, _, _, _, "atom_concat/3 can build atoms twice as long")).

test(refuses_a_sandbox_violation) :-
    query("shell(ls)", Result),
    Result = unsafe(Msg),
    starts(Msg, "refused by the sandbox").

test(refuses_brackets_nested_deeper_than_200_levels,
     [Result == syntax("brackets nested deeper than 200 levels (line 1); queries are limited to that")]) :-
    length(Open, 201), maplist(=(0'[), Open),
    string_codes(Text, Open),
    query(Text, Result).

test(reports_a_syntax_error, [Result = syntax(_)]) :-
    query("object(O,", Result).

test(refuses_a_variable_goal, [Result == syntax("the query is a variable, not a goal")]) :-
    query("G", Result).

test(stops_a_loop_at_the_inference_limit, [Result == limit("inference limit of 100,000 exceeded")]) :-
    query("repeat, fail", Result).

test(bounds_a_deep_answer, [D == 64]) :-
    query("length(L, 100), foldl([_, A, f(A)]>>true, L, x, T)", Result),
    Result = ok(["L", "A", "T"], [[_, _, T]], false),
    depth(T, D).

:- end_tests(queries).
