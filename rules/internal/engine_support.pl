:- module(wm_engine, []).
/*  engine_support.pl: the Prolog half of wm::rules::Engine: loading, checking and self-checking rule
    files, dispatch of decisions under limits, fact replacement, read-only queries.

    Not a rule file: users never edit it and the engine does not read it at run time. The build embeds
    this text into the library (rules/CMakeLists.txt generates a header from it), and the Engine loads
    it as source id "wm_engine_support.pl", after rule_checks.pl (module wm_rule_checks: what a rule
    text or query may contain, bounded printing), whose predicates it imports. engine_support.plt
    beside it holds its plunit tests.

    Entry points, all called from C++ and all catching every error they can report; each takes first
    the knowledge base it works on (Kb, a module: one per Engine, so one process can hold several
    maps, each with its facts and its active rules):
      init/1, set_floor_plan/2, set_elements/2, update_elements/3, set_element_grid/2,
      set_edge_evidence/3, verdicts/6,
      add_decisions/3, decide/7,
      decide_batch/5, reload/7, dry_run/7, prune/5, query/6, shutdown/1.
    C++ registers one foreign predicate in this module before loading it: text_nesting_exceeds/3
    (+Text, +Max, -Line), true when brackets nest deeper than Max outside quotes and comments.

    The sections follow a rule set's life: facts, decisions, loading aside, dry runs, prune, queries,
    safety of the loaded clauses, the load itself, self-check, activation. Some 630 lines: one module
    whose parts share the thread-local load state below (load_problem/1, source_path/2, collecting/0)
    and the message hook that fills it; the stateless checks live in rule_checks.pl. */
:- use_module(library(time), [call_with_time_limit/2]).
:- use_module(library(sha), [sha_hash/3, hash_atom/2]).
:- use_module(library(lists), [member/2, append/3]).
:- use_module(library(apply), [foldl/4, maplist/2, maplist/3]).
:- use_module(library(prolog_codewalk), [prolog_walk_code/1]).
:- use_module(library(error), [must_be/2]).
:- use_module(library(aggregate), [aggregate_all/3]).
:- import(wm_rule_checks:term_problem/2).
:- import(wm_rule_checks:unbounded_call/4).
:- import(wm_rule_checks:forbidden_subgoal/2).
:- import(wm_rule_checks:bounded_term/2).
:- import(wm_rule_checks:message_text/2).

:- dynamic active_rules/2.          % active_rules(Kb, Module): the module Kb's decide/5 is answered from
:- dynamic retired_rules/3.         % retired_rules(Kb, Module, RetiredAt [s]): freed after a grace period
:- thread_local collecting/0.       % this thread is loading rule files: capture its messages
:- thread_local load_problem/1.     % load_problem(String) "file:line: text"
:- thread_local source_path/2.      % source_path(SourceId, Path): source ids are unique per load

:- use_module(library(sandbox), [safe_goal/1]).
:- use_module(library(solution_sequences), [limit/2]).

%   A knowledge base's facts: the floor plan (object/2, attribute/2, edge/5); observed map elements and
%   recent decisions, kept in step with the map by the server (element/8, element_grid/3, decision/7);
%   what the grid says of the plan's edges, kept current at every grid check (edge_evidence/5,
%   edge_seen_through/6, edge_beams/4).
kb_fact(object/2).
kb_fact(attribute/2).
kb_fact(edge/5).
kb_fact(element/8).
kb_fact(element_grid/3).
kb_fact(decision/7).
kb_fact(edge_evidence/5).
kb_fact(edge_seen_through/6).
kb_fact(edge_beams/4).

%!  init(+Kb) is det.
%   Makes module Kb a knowledge base: its facts, empty; what the rules can ask about the observation being
%   decided (set per decision, backtrackable); the stretches seen through with the beams that passed only
%   (edge_seen_through/5, as rule files written before the beams that returned on a stretch were counted
%   ask for them). Without base(system), an undefined predicate in Kb or a rules module falls through to
%   `user`.
init(Kb) :-
    set_module(Kb:base(system)),
    forall(kb_fact(Name/Arity), dynamic(Kb:Name/Arity)),
    (   current_predicate(Kb:observation_origin/1)
    ->  true
    ;   compile_aux_clauses_in(Kb,
            [ (observation_origin(Origin) :-
                  ( nb_current(wm_context, context(O, _)) -> Origin = O ; Origin = unknown )),
              (observation_sensor(Sensor) :-
                  ( nb_current(wm_context, context(_, S)) -> Sensor = S ; Sensor = unknown )),
              (edge_seen_through(Object, Edge, S0, S1, Through) :-
                  edge_seen_through(Object, Edge, S0, S1, Through, _)) ])
    ),
    clear_facts(Kb).

%   Static clauses in module Kb (a rule may call them, never change them).
compile_aux_clauses_in(Kb, Clauses) :-
    forall(member(Clause, Clauses), assertz(Kb:Clause)),
    compile_predicates([Kb:observation_origin/1, Kb:observation_sensor/1, Kb:edge_seen_through/5]).

clear_facts(Kb) :-
    retractall(Kb:object(_, _)),
    retractall(Kb:attribute(_, _)),
    retractall(Kb:edge(_, _, _, _, _)).

%!  set_elements(+Kb, +Elements) is det.
%   Replaces every element/8 fact. Elements: list of element(Id, Origin, Observer, Rho, Phi, Length,
%   Support, UpdatedAt).
set_elements(Kb, Elements) :-
    must_be(list, Elements),
    transaction(( retractall(Kb:element(_, _, _, _, _, _, _, _)),
                  retractall(Kb:element_grid(_, _, _)),
                  forall(member(E, Elements), assertz(Kb:E)) )).

%!  update_elements(+Kb, +Upserts, +RemovedIds) is det.
update_elements(Kb, Upserts, Removed) :-
    transaction(( forall(member(element(Id, _, _, _, _, _, _, _), Upserts),
                         ( retractall(Kb:element(Id, _, _, _, _, _, _, _)),
                           retractall(Kb:element_grid(Id, _, _)) )),
                  forall(member(Id, Removed),
                         ( retractall(Kb:element(Id, _, _, _, _, _, _, _)),
                           retractall(Kb:element_grid(Id, _, _)) )),
                  forall(member(E, Upserts), assertz(Kb:E)) )).

%!  set_element_grid(+Kb, +Facts) is det.
%   Inserts or replaces element_grid(Id, Backed, Contrary) facts: what the grid said of each element at its
%   last check (an element that changes loses its fact in update_elements/2).
set_element_grid(Kb, Facts) :-
    must_be(list, Facts),
    transaction(( forall(member(element_grid(Id, _, _), Facts), retractall(Kb:element_grid(Id, _, _))),
                  forall(member(F, Facts), assertz(Kb:F)) )).

%!  set_edge_evidence(+Kb, +Facts, +ReplaceAll) is det.
%   Facts: list of evidence(Object, Edge, Backed, SeenThrough, Observed, Stretches, Through, Ended), Stretches a
%   list of stretch(S0, S1, Through, Ended). Replaces the edge_evidence/5, edge_seen_through/6 and edge_beams/4
%   facts of those edges (of every edge first when ReplaceAll is true), in one transaction.
set_edge_evidence(Kb, Facts, ReplaceAll) :-
    must_be(list, Facts),
    transaction(( (   ReplaceAll == true
                  ->  retractall(Kb:edge_evidence(_, _, _, _, _)),
                      retractall(Kb:edge_seen_through(_, _, _, _, _, _)),
                      retractall(Kb:edge_beams(_, _, _, _))
                  ;   true
                  ),
                  forall(member(evidence(O, E, _, _, _, _, _, _), Facts),
                         ( retractall(Kb:edge_evidence(O, E, _, _, _)),
                           retractall(Kb:edge_seen_through(O, E, _, _, _, _)),
                           retractall(Kb:edge_beams(O, E, _, _)) )),
                  forall(member(evidence(O, E, B, S, Obs, Stretches, Through, Ended), Facts),
                         ( assertz(Kb:edge_evidence(O, E, B, S, Obs)),
                           assertz(Kb:edge_beams(O, E, Through, Ended)),
                           forall(member(stretch(S0, S1, Through1, Ended1), Stretches),
                                  assertz(Kb:edge_seen_through(O, E, S0, S1, Through1, Ended1))) )) )).

%!  add_decisions(+Kb, +Decisions, +KeepLast) is det.
%   Appends decision/7 facts and forgets all but the KeepLast newest (the full log is in SQLite).
add_decisions(Kb, Decisions, KeepLast) :-
    forall(member(D, Decisions), assertz(Kb:D)),
    flag(wm_decision_facts(Kb), N0, N0),
    length(Decisions, Added),
    Excess is N0 + Added - KeepLast,
    forget_oldest_decisions(Kb, Excess),
    flag(wm_decision_facts(Kb), _, min(N0 + Added, KeepLast)).

forget_oldest_decisions(_, N) :- N =< 0, !.
forget_oldest_decisions(Kb, N) :-
    (   retract(Kb:decision(_, _, _, _, _, _, _)) -> N1 is N - 1, forget_oldest_decisions(Kb, N1) ; true ).

%!  set_floor_plan(+Kb, +Objects) is det.
%   Objects: list of object(Id, Kind, Attributes, Edges), Edges: list of edge(Id, Rho, Phi, Length).
%   All facts are replaced in one transaction: other threads see the old or the new plan, never half.
set_floor_plan(Kb, Objects) :-
    must_be(list, Objects),
    transaction(( clear_facts(Kb),
                  forall(member(Object, Objects), assert_object(Kb, Object)) )).

assert_object(Kb, object(Id, Kind, Attributes, Edges)) :-
    assertz(Kb:object(Id, Kind)),
    sort(Attributes, Unique),
    forall(member(A, Unique), assertz(Kb:attribute(Id, A))),
    forall(member(edge(E, Rho, Phi, Length), Edges),
           assertz(Kb:edge(Id, E, Rho, Phi, Length))).

%!  decide(+Kb, +Observation, +Match, +Context, +InferenceLimit, +TimeLimit, -Result) is det.
%   Context = context(Origin, Sensor), what observation_origin/1 and observation_sensor/1 answer.
%   Result = decision(Action:atom, Rule:string, Explanation:string) | error(Message:string).
decide(Kb, Observation, Match, Context, InferenceLimit, TimeLimit, Result) :-
    reset_inference_limit,
    b_setval(wm_context, Context),
    (   active_rules(Kb, M)
    ->  run_decide(M, Observation, Match, InferenceLimit, TimeLimit, Result)
    ;   Result = error("no rules are active")
    ).

%   A time-limit exception that arrives while call_with_inference_limit/3 restores the previous limit
%   can leave the thread's limit set, and a later call then stops with inference_limit_exceeded
%   (seen once in a few hundred test runs). Entry points from C++ never run inside a limit, so each
%   starts from "no limit" (the internal value of SWI-Prolog 9; the reset is skipped if it changes).
reset_inference_limit :-
    (   catch(system:'$inference_limit_false'(9223372036854775807), _, fail) -> true ; true ).

%!  decide_batch(+Kb, +Cases, +InferenceLimit, +TimeLimit, -Results) is det.
%   Cases: list of case(Observation, Match, Context); one time limit around the whole batch (it costs
%   more than a decision), the inference limit per case.
decide_batch(Kb, Cases, InferenceLimit, TimeLimit, Results) :-
    reset_inference_limit,
    (   active_rules(Kb, M)
    ->  catch(call_with_time_limit(TimeLimit, decide_cases(Cases, M, InferenceLimit, Results)),
              E, ( message_text(E, Text), length(Cases, N), length(Results, N),
                   format(string(Msg), "batch stopped: ~w", [Text]),
                   maplist(=(error(Msg)), Results) ))
    ;   length(Cases, N), length(Results, N), maplist(=(error("no rules are active")), Results)
    ).

decide_cases([], _, _, []).
decide_cases([case(Observation, Match, Context)|Cases], M, InferenceLimit, [Result|Results]) :-
    b_setval(wm_context, Context),
    (   catch(limited_decide(M, Observation, Match, InferenceLimit, Answer), E, Answer = exception(E))
    ->  true
    ;   Answer = failed
    ),
    answer_result(Answer, InferenceLimit, 0, Result),
    decide_cases(Cases, M, InferenceLimit, Results).

run_decide(M, Observation, Match, InferenceLimit, TimeLimit, Result) :-
    catch(call_with_time_limit(TimeLimit,
                               limited_decide(M, Observation, Match, InferenceLimit, Answer)),
          E, Answer = exception(E)),
    answer_result(Answer, InferenceLimit, TimeLimit, Result).

limited_decide(M, Observation, Match, InferenceLimit, Answer) :-
    call_with_inference_limit(M:decide(Observation, Match, Action, Rule, Explanation),
                              InferenceLimit, Status),
    !,
    (   Status == inference_limit_exceeded
    ->  Answer = inference_limit
    ;   Answer = answer(Action, Rule, Explanation)
    ).
limited_decide(_, _, _, _, failed).

answer_result(answer(Action, Rule, Explanation), _, _, Result) :- !,
    (   \+ atom(Action)
    ->  format(string(Msg), "decide/5 answered an action that is not an atom: ~q", [Action]),
        Result = error(Msg)
    ;   \+ ( atom(Rule) ; string(Rule) )
    ->  format(string(Msg), "decide/5 answered a rule name that is not an atom: ~q", [Rule]),
        Result = error(Msg)
    ;   var(Explanation)
    ->  Result = error("decide/5 left the explanation unbound")
    ;   atom_string(Rule, RuleString),
        explanation_string(Explanation, ExplanationString),
        Result = decision(Action, RuleString, ExplanationString)
    ).
answer_result(failed, _, _, error("no rule applies (decide/5 failed)")) :- !.
answer_result(inference_limit, Limit, _, error(Msg)) :- !,
    format(string(Msg), "inference limit of ~D exceeded (does a rule loop?)", [Limit]).
answer_result(exception(E), _, TimeLimit, error(Msg)) :-
    (   time_limit_error(E)
    ->  format(string(Msg), "time limit of ~w s exceeded (does a rule loop or block?)", [TimeLimit])
    ;   message_text(E, Text),
        format(string(Msg), "decide/5 raised: ~w", [Text])
    ).

time_limit_error(E) :- E == time_limit_exceeded, !.
time_limit_error(time_limit_exceeded(_)).

explanation_string(E, S) :- catch(text_to_string(E, S), _, fail), !.
explanation_string(E, S) :- format(string(S), "~W", [E, [quoted(true), max_depth(20)]]).


%!  reload(+Kb, +Files, +RulesDir, +InferenceLimit, +TimeLimit, +GracePeriod, -Result) is det.
%   Loads Files, a list of file(Path, AbsolutePath) (Path is shown in messages), into a fresh module
%   that sees Kb's facts, self-checks it and makes it Kb's active rules.
%   Result = ok(Hashes) with Hashes a list of sha256 hex atoms in the order of Files,
%          | error(Problems), a non-empty list of strings "file:line: text"; then nothing changed.
reload(Kb, Files, RulesDir, InferenceLimit, TimeLimit, GracePeriod, Result) :-
    reset_inference_limit,
    load_aside(Kb, Files, RulesDir, InferenceLimit, TimeLimit, M, Hashes, Problems),
    (   Problems == []
    ->  activate(Kb, M, GracePeriod),
        Result = ok(Hashes)
    ;   free_module(M),
        Result = error(Problems)
    ).

%!  load_aside(+Kb, +Files, +RulesDir, +InferenceLimit, +TimeLimit, -Module, -Hashes, -Problems) is det.
%   Loads Files into a fresh module whose facts are Kb's and self-checks it; nothing else changes. Files: file(Path,
%   AbsolutePath) read from disk, or text(Path, Text) given in memory (a dry-run candidate).
load_aside(Kb, Files, RulesDir, InferenceLimit, TimeLimit, M, Hashes, Problems) :-
    flag(wm_rules_counter, N, N+1),
    format(atom(M), "wm_rules_~d", [N]),
    set_module(M:base(system)),
    add_import_module(M, Kb, start),
    declare_hooks(M),
    retractall(load_problem(_)),
    retractall(source_path(_, _)),
    setup_call_cleanup(assertz(collecting),
                       load_all(Files, M, N, Hashes),
                       retractall(collecting)),
    (   \+ load_problem(_)
    ->  check_undefined_calls(M)
    ;   true
    ),
    (   \+ load_problem(_)
    ->  check_rules_safe(M)          % before the self-check runs any rule
    ;   true
    ),
    findall(P, load_problem(P), LoadProblems),
    (   LoadProblems == []
    ->  self_check(Kb, M, RulesDir, InferenceLimit, TimeLimit, Problems)
    ;   Problems = LoadProblems
    ),
    retractall(load_problem(_)).

%   Extension points any rule file may add clauses to, whatever the order the files load in:
%   override/5 (tried by the shipped decide/5 before its own rules) and prune/3 (asked after each
%   update which observed elements to remove).
declare_hooks(M) :-
    forall(member(Name/Arity, [override/5, prune/3, verdict_override/5, edge_verdict/5, object_verdict/4]),
           ( dynamic(M:Name/Arity), multifile(M:Name/Arity), discontiguous(M:Name/Arity) )).

%!  dry_run(+Kb, +Files, +RulesDir, +Cases, +InferenceLimit, +TimeLimit, -Result) is det.
%   Loads Files aside like reload/6, answers every case(Observation, Match, Context) with them, and
%   frees them again: the active rules and the facts are untouched.
%   Result = ok(Results) (decide_batch/4 results) | error(Problems).
dry_run(Kb, Files, RulesDir, Cases, InferenceLimit, TimeLimit, Result) :-
    %   The candidate text is untrusted: this thread gets the small stack of queries.
    reset_inference_limit,
    query_stack_limit(StackLimit),
    set_prolog_flag(stack_limit, StackLimit),
    load_aside(Kb, Files, RulesDir, InferenceLimit, TimeLimit, M, _, Problems),
    (   Problems == []
    ->  length(Cases, N),
        max_dry_run_time_s(MaxTotal),
        BatchLimit is min(MaxTotal, TimeLimit * max(1, N)),
        catch(call_with_time_limit(BatchLimit,
                                   snapshot(decide_each(Cases, M, InferenceLimit, TimeLimit, Results))),
              E, ( message_text(E, Text), format(string(Msg), "dry run stopped: ~w", [Text]),
                   length(Results, N), maplist(=(error(Msg)), Results) )),
        Result = ok(Results)
    ;   Result = error(Problems)
    ),
    free_module(M).

max_dry_run_time_s(30).

%   Like decide_cases/4, with the time limit per case (a candidate may block in each case).
decide_each([], _, _, _, []).
decide_each([case(Observation, Match, Context)|Cases], M, InferenceLimit, TimeLimit, [Result|Results]) :-
    b_setval(wm_context, Context),
    run_decide(M, Observation, Match, InferenceLimit, TimeLimit, Result),
    decide_each(Cases, M, InferenceLimit, TimeLimit, Results).

%   Stack (global + local + trail) of a thread running queries or dry runs [bytes]. It also bounds
%   what no time limit can interrupt: SWI-Prolog refuses a bignum result larger than the stack
%   before computing it, and lists or strings built by a query.
query_stack_limit(16000000).

%   Cells of a query's answer (after bounded_term/2), ~8 bytes each.
max_answer_cells(1000000).

%!  prune(+Kb, +Max, +InferenceLimit, +TimeLimit, -Result) is det.
%   Asks the active rules' prune/3 which elements to remove.
%   Result = ok(List of prune(ElementId, Rule, Explanation)) | error(Message).
prune(Kb, Max, InferenceLimit, TimeLimit, Result) :-
    reset_inference_limit,
    (   active_rules(Kb, M)
    ->  catch(call_with_time_limit(TimeLimit,
                  call_with_inference_limit(
                      findall(prune(E, R, X), limit(Max, prune_answer(M, E, R, X)), Orders),
                      InferenceLimit, Status)),
              Error, true),
        (   nonvar(Error)
        ->  message_text(Error, Text), format(string(Msg), "prune/3 raised: ~w", [Text]),
            Result = error(Msg)
        ;   Status == inference_limit_exceeded
        ->  format(string(Msg), "prune/3: inference limit of ~D exceeded", [InferenceLimit]),
            Result = error(Msg)
        ;   Result = ok(Orders)
        )
    ;   Result = ok([])
    ).

prune_answer(M, E, R, X) :-
    M:prune(E, R0, X0),
    atom(E),
    atom_string(R0, R),
    explanation_string(X0, X).

%!  verdicts(+Kb, +Scope, +Max, +InferenceLimit, +TimeLimit, -Result) is det.
%   Asks the active rules what the evidence says of the plan. Scope = all | edges(List of Object-Edge):
%   for each edge in scope with an edge_evidence/5 fact, the first answer of verdict_override/5 if it has
%   one, else every answer of edge_verdict/5; then object_verdict/4 for every object in scope (all, or
%   those of the edges). Verdict `kept` is no verdict (an override that keeps a glass wall).
%   Result = ok(List of verdict(Object, Edge, Verdict, S0, S1, Rule, Explanation)) | error(Message), Edge
%   `none` for an object's verdict, [S0, S1] the stretch of the edge [m] (partly_missing(S0, S1) answers
%   give theirs; other edge verdicts cover the whole edge).
verdicts(Kb, Scope, Max, InferenceLimit, TimeLimit, Result) :-
    reset_inference_limit,
    (   active_rules(Kb, M)
    ->  catch(call_with_time_limit(TimeLimit,
                  call_with_inference_limit(
                      findall(V, limit(Max, verdict_answer(Kb, M, Scope, V)), Verdicts),
                      InferenceLimit, Status)),
              Error, true),
        (   nonvar(Error)
        ->  message_text(Error, Text), format(string(Msg), "verdicts raised: ~w", [Text]),
            Result = error(Msg)
        ;   Status == inference_limit_exceeded
        ->  format(string(Msg), "verdicts: inference limit of ~D exceeded", [InferenceLimit]),
            Result = error(Msg)
        ;   Result = ok(Verdicts)
        )
    ;   Result = ok([])
    ).

verdict_answer(Kb, M, Scope, verdict(O, E, V, S0, S1, R, X)) :-
    scope_edge(Kb, Scope, O, E),
    (   M:verdict_override(O, E, V0, R0, X0)
    ->  true
    ;   M:edge_verdict(O, E, V0, R0, X0)
    ),
    V0 \== kept,
    edge_stretch(Kb, O, E, V0, V, S0, S1),
    atom_string(R0, R),
    explanation_string(X0, X).
verdict_answer(Kb, M, Scope, verdict(O, none, V, 0.0, 0.0, R, X)) :-
    scope_object(Kb, Scope, O),
    M:object_verdict(O, V0, R0, X0),
    V0 \== kept,
    atom(V0),
    V = V0,
    atom_string(R0, R),
    explanation_string(X0, X).

scope_edge(Kb, all, O, E) :- Kb:edge_evidence(O, E, _, _, _).
scope_edge(Kb, edges(List), O, E) :- member(O-E, List), Kb:edge_evidence(O, E, _, _, _).

scope_object(Kb, all, O) :- Kb:object(O, _).
scope_object(_, edges(List), O) :- setof(O1, E^member(O1-E, List), Objects), member(O, Objects).

edge_stretch(_, _, _, partly_missing(A, B), partly_missing, S0, S1) :-
    !,
    S0 is float(A),
    S1 is float(B).
edge_stretch(Kb, O, E, V, V, 0.0, S1) :-
    atom(V),
    (   Kb:edge(O, E, _, _, Length) -> S1 is float(Length) ; S1 = 0.0 ).

%!  query(+Kb, +Text, +MaxSolutions, +InferenceLimit, +TimeLimit, -Result) is det.
%   Runs a read-only goal given as text against knowledge base Kb (its active rules module, which
%   sees the facts). Result = ok(Names, Rows, Truncated) with Rows a list of lists of values in the
%   order of Names | syntax(Message) | unsafe(Message) | limit(Message) | error(Message).
query(Kb, Text, MaxSolutions, InferenceLimit, TimeLimit, Result) :-
    (   active_rules(Kb, M) -> true ; M = Kb ),
    reset_inference_limit,
    query_stack_limit(StackLimit),
    set_prolog_flag(stack_limit, StackLimit),
    max_text_nesting(MaxNesting),
    (   text_nesting_exceeds(Text, MaxNesting, Line)
    ->  format(string(Msg), "brackets nested deeper than ~d levels (line ~d); queries are limited \c
                             to that", [MaxNesting, Line]),
        Result = syntax(Msg)
    ;   catch(term_string(Goal, Text, [variable_names(Bindings), module(M)]), E,
              ( message_text(E, Msg), Result = syntax(Msg) ))
    ->  (   nonvar(Result)
        ->  true
        ;   var(Goal)
        ->  Result = syntax("the query is a variable, not a goal")
        ;   run_query(M, Goal, Bindings, MaxSolutions, InferenceLimit, TimeLimit, Result)
        )
    ;   Result = syntax("the query text is not a term")
    ).

run_query(M, Goal, Bindings, MaxSolutions, InferenceLimit, TimeLimit, Result) :-
    (   forbidden_subgoal(Goal, Bad0)
    ->  bounded_term(Bad0, Bad),
        format(string(Msg), "~q changes the knowledge base; queries are read-only", [Bad]),
        Result = unsafe(Msg)
    ;   unbounded_call(Goal, query, Bad0, Why)
    ->  bounded_term(Bad0, Bad),
        format(string(Msg), "~q is refused: ~w", [Bad, Why]),
        Result = unsafe(Msg)
    ;   sandbox_refusal(M:Goal, TimeLimit, E)
    ->  message_text(E, Msg0),
        format(string(Msg), "refused by the sandbox: ~w", [Msg0]),
        Result = unsafe(Msg)
    ;   maplist(binding_name_var, Bindings, Names, Vars),
        Max1 is MaxSolutions + 1,
        %  snapshot/1 discards any database change a called rule might still make.
        catch(call_with_time_limit(TimeLimit,
                  call_with_inference_limit(
                      snapshot(findall(Vars, limit(Max1, M:Goal), Rows0)),
                      InferenceLimit, Status)),
              E2, true),
        (   nonvar(E2)
        ->  (   time_limit_error(E2)
            ->  format(string(Msg), "time limit of ~w s exceeded", [TimeLimit]), Result = limit(Msg)
            ;   E2 = error(resource_error(c_stack), _)
            ->  Result = limit("the query ran out of C stack (a term nested too deeply to write \c
                                 or read)")
            ;   E2 = error(resource_error(Resource), _)
            ->  query_stack_limit(StackLimit),
                format(string(Msg), "the query ran out of ~w (a query may use ~D bytes of stack)",
                       [Resource, StackLimit]),
                Result = limit(Msg)
            ;   message_text(E2, Msg0), format(string(Msg), "the query raised: ~w", [Msg0]),
                Result = error(Msg)
            )
        ;   Status == inference_limit_exceeded
        ->  format(string(Msg), "inference limit of ~D exceeded", [InferenceLimit]), Result = limit(Msg)
        ;   length(Rows0, Count),
            (   Count > MaxSolutions
            ->  length(Rows1, MaxSolutions), append(Rows1, _, Rows0), Truncated = true
            ;   Rows1 = Rows0, Truncated = false
            ),
            %  Values are shown bounded (deep terms would overflow the C stack when written); a
            %  wide answer can take long to copy, so that runs under the time limit too.
            max_answer_cells(MaxCells),
            (   catch(call_with_time_limit(TimeLimit,
                                           ( maplist(maplist(bounded_term), Rows1, Rows),
                                             term_size(Rows, Cells) )),
                      _, fail),
                Cells =< MaxCells
            ->  Result = ok(Names, Rows, Truncated)
            ;   format(string(Msg), "the answer is too large (more than ~D cells or ~w s to copy): \c
                                     ask for fewer solutions or smaller values", [MaxCells, TimeLimit]),
                Result = limit(Msg)
            )
        )
    ).


%!  check_rules_safe(+Module) is det.
%   Records a load_problem/1 unless everything decide/5 and prune/3 can call is safe to run: no
%   file, process, thread, flag or cross-module database access (library(sandbox)), and no call
%   that no time limit can interrupt (unbounded_call/4).
check_rules_safe(M) :-
    forall(( current_predicate(M:Name/Arity),
             functor(Head, Name, Arity),
             predicate_property(M:Head, implementation_module(M)),
             clause(M:Head, Body, Ref),
             unbounded_call(Body, rule, Call0, Why) ),
           ( clause_location(Ref, Path, Line),
             bounded_term(Call0, Call),
             format(string(P), "~w:~w: ~q is refused: ~w", [Path, Line, Call, Why]),
             assertz(load_problem(P)) )),
    %   The sandbox walks the same bodies and can hang on what unbounded_call/4 refused: only when none.
    (   load_problem(_)
    ->  true
    ;   check_rules_sandbox(M)
    ).

check_rules_sandbox(M) :-
    forall(( member(Name/Arity, [decide/5, prune/3]),
             current_predicate(M:Name/Arity),
             functor(Head, Name, Arity),
             max_safety_check_time_s(Limit),
             sandbox_refusal(M:Head, Limit, E) ),
           ( entry_location(M, Head, Location),
             message_text(E, Text),
             format(string(P), "~w: ~w can reach a call that rules may not make: ~w",
                    [Location, Name/Arity, Text]),
             assertz(load_problem(P)) )).

%!  sandbox_refusal(+Goal, +TimeLimit, -Error) is semidet.
%   True when library(sandbox) refuses Goal, with Error its reason, or cannot decide within TimeLimit
%   seconds: in SWI-Prolog 9.0.4 its check of format/2 whose format is a term (format(atom(A), x), a
%   mistake for format/3) never returns, so the check runs under a time limit like everything else.
sandbox_refusal(Goal, TimeLimit, Error) :-
    catch(call_with_time_limit(TimeLimit, safe_goal(Goal)), E, true),
    nonvar(E),
    (   time_limit_error(E)
    ->  Error = format("the safety check did not finish within ~w s (does a format/2 call take a \c
                        term such as atom(A) for its format? That is format/3's first argument)",
                       [TimeLimit])
    ;   Error = E
    ).

%   Time the safety check of a rule set may take [s]; the shipped rules take milliseconds.
max_safety_check_time_s(5).

clause_location(Ref, Path, Line) :-
    (   clause_property(Ref, file(Id)), clause_property(Ref, line_count(Line))
    ->  ( source_path(Id, Path) -> true ; Path = Id )
    ;   Path = '?', Line = 0
    ).

entry_location(M, Head, Location) :-
    (   predicate_property(M:Head, file(Id)),
        predicate_property(M:Head, line_count(Line))
    ->  ( source_path(Id, Path) -> true ; Path = Id ),
        format(string(Location), "~w:~w", [Path, Line])
    ;   functor(Head, Name, Arity),
        format(string(Location), "~w", [Name/Arity])
    ).

binding_name_var(Name = Var, NameString, Var) :- atom_string(Name, NameString).


load_all([], _, _, []).
load_all([File|Files], M, N, [Hash|Hashes]) :-
    load_one(File, M, N, Hash),
    load_all(Files, M, N, Hashes).

load_one(file(Path, AbsolutePath), M, N, Hash) :- !,
    catch(read_file_to_string(AbsolutePath, Text, [encoding(utf8)]), E,
          ( problem_at(Path, 0, E), Text = "" )),
    load_one(text(Path, Text), M, N, Hash).
load_one(text(Path, Text), M, N, Hash) :-
    format(atom(Id), "~w#~d", [Path, N]),
    assertz(source_path(Id, Path)),
    catch(( sha_hash(Text, Digest, [algorithm(sha256), encoding(utf8)]),
            hash_atom(Digest, Hash),
            %   Loading runs directives and term expansion: the text is read as terms and checked
            %   first, and loaded only when nothing in it can act beyond defining rules.
            aggregate_all(count, load_problem(_), Before),
            check_rule_text(Path, Text, M),
            aggregate_all(count, load_problem(_), After),
            (   After =:= Before
            ->  max_load_time_s(LoadLimit),
                setup_call_cleanup(open_string(Text, Stream),
                                   call_with_time_limit(LoadLimit, load_files(M:Id, [stream(Stream)])),
                                   close(Stream))
            ;   true
            )
          ),
          E,
          problem_at(Path, 0, E)),
    (   var(Hash) -> Hash = '' ; true ).

max_load_time_s(10).

%!  check_rule_text(+Path, +Text, +Module) is det.
%   Reads Text as terms without running any of them and records a load_problem/1 for everything a
%   rule file may not contain: text nested too deeply to read safely, a syntax error, a directive
%   that is not on the allow-list, a clause for another module or for a hook of Prolog itself.
check_rule_text(Path, Text, M) :-
    max_text_nesting(MaxNesting),
    (   text_nesting_exceeds(Text, MaxNesting, Line)
    ->  format(string(P), "~w:~w: brackets nested deeper than ~d levels; rule files and queries \c
                           are limited to that", [Path, Line, MaxNesting]),
        assertz(load_problem(P))
    ;   setup_call_cleanup(open_string(Text, Stream),
                           check_terms(Stream, Path, M),
                           close(Stream))
    ).

max_text_nesting(200).

check_terms(Stream, Path, M) :-
    repeat,
    (   catch(read_term(Stream, Term, [module(M), term_position(Pos), syntax_errors(error)]),
              E, true)
    ->  true
    ;   Term = end_of_file
    ),
    (   nonvar(E)
    ->  syntax_error_line(E, Line),
        problem_at(Path, Line, E),
        fail                            % read_term skipped the bad clause: go on with the next
    ;   Term == end_of_file
    ->  !
    ;   stream_position_data(line_count, Pos, Line),
        (   term_problem(Term, Text)
        ->  format(string(P), "~w:~w: ~w", [Path, Line, Text]),
            assertz(load_problem(P))
        ;   true
        ),
        fail
    ).

syntax_error_line(error(_, stream(_, Line, _, _)), Line) :- integer(Line), !.
syntax_error_line(error(_, string(_, _)), 0) :- !.
syntax_error_line(_, 0).


problem_at(File, Line, Term) :-
    message_text(Term, Text0),
    findall(Id-Path, source_path(Id, Path), SourceIds),
    foldl(source_id_to_path, SourceIds, Text0, Text),
    format(string(P), "~w:~w: ~w", [File, Line, Text]),
    assertz(load_problem(P)).

%   Messages name the unique source ids ("path#N"); users know the path.
source_id_to_path(Id-Path, Text0, Text) :-
    atomic_list_concat(Parts, Id, Text0),
    atomic_list_concat(Parts, Path, Atom),
    atom_string(Atom, Text).

:- multifile user:message_hook/3.
user:message_hook(Term, Kind, _Lines) :-
    ( Kind == error ; Kind == warning ),
    collecting,
    message_location(Term, File, Line),
    problem_at(File, Line, Term).

message_location(Term, Path, Line) :-
    (   Term = error(_, file(Id, Line, _, _))
    ->  true
    ;   source_location(Id, Line)
    ->  true
    ;   Id = '?', Line = 0
    ),
    (   source_path(Id, Path) -> true ; Path = Id ).

%   A call to a predicate that neither the rule files, the facts, `system` nor the autoloadable
%   libraries define is a typo that would otherwise only show as fallback decisions.
check_undefined_calls(M) :-
    catch(prolog_walk_code([ module(M), undefined(trace), on_trace(undefined_call(M)),
                             infer_meta_predicates(false) ]),
          E, problem_at('?', 0, E)).

undefined_call(M, Callee, Caller, Location) :-
    (   Location = clause(Ref),
        clause_property(Ref, file(Id)),
        clause_property(Ref, line_count(Line))
    ->  ( source_path(Id, Path) -> true ; Path = Id )
    ;   Path = '?', Line = 0
    ),
    unqualified(M, Callee, CalleePI),
    unqualified(M, Caller, CallerPI),
    format(string(P), "~w:~w: ~q calls the undefined predicate ~q", [Path, Line, CallerPI, CalleePI]),
    assertz(load_problem(P)).

unqualified(M, M:Head, Name/Arity) :- !, functor(Head, Name, Arity).
unqualified(_, Q:Head, Q:Name/Arity) :- callable(Head), !, functor(Head, Name, Arity).
unqualified(_, Goal, Goal).

%   The canonical cases every rule set must answer with an atom action.
canonical_case('matched solid',
               observation(self_check, 2.0, 0.0, 4.0), element(wm_check_e1, wm_check_wall, 0.5)).
canonical_case('matched element not in the plan',
               observation(self_check, 2.0, 0.0, 4.0), element(wm_check_e2, none, 0.5)).
canonical_case('matched not_deformable',
               observation(self_check, 1.0, 1.5707963267948966, 0.8), element(wm_check_e3, wm_check_table, 0.5)).
canonical_case('unmatched',
               observation(self_check, 3.0, 3.141592653589793, 1.0), none).

canonical_facts(Kb) :-
    set_floor_plan(Kb, [ object(wm_check_wall, wall, [solid], [edge(wm_check_e1, 2.0, 0.0, 4.0)]),
                     object(wm_check_table, table, [not_deformable],
                            [edge(wm_check_e3, 1.0, 1.5707963267948966, 0.8)]) ]).

self_check(Kb, M, RulesDir, InferenceLimit, TimeLimit, Problems) :-
    (   \+ defines_decide(M)
    ->  format(string(P), "~w: no rule file defines decide/5", [RulesDir]),
        Problems = [P]
    ;   decide_location(M, Location),
        snapshot(( canonical_facts(Kb),
                   findall(P, ( canonical_case(Name, Observation, Match),
                                run_decide(M, Observation, Match, InferenceLimit, TimeLimit, Result),
                                Result = error(Msg),
                                format(string(P), "~w: self-check '~w' (~q, ~q): ~w",
                                       [Location, Name, Observation, Match, Msg]) ),
                           Problems) ))
    ).

defines_decide(M) :-
    current_predicate(M:decide/5),
    \+ predicate_property(M:decide(_, _, _, _, _), imported_from(_)).

decide_location(M, Location) :-
    entry_location(M, decide(_, _, _, _, _), Location).

activate(Kb, M, GracePeriod) :-
    get_time(Now),
    forall(active_rules(Kb, Old), assertz(retired_rules(Kb, Old, Now))),
    transaction(( retractall(active_rules(Kb, _)), assertz(active_rules(Kb, M)) )),
    free_retired(Kb, Now, GracePeriod).

%   A retired module is freed only when no decision can still run in it (one started before the
%   switch ends within the time limit).
free_retired(Kb, Now, GracePeriod) :-
    forall(( retired_rules(Kb, Old, At), Now - At > GracePeriod ),
           ( free_module(Old), retractall(retired_rules(Kb, Old, _)) )).

free_module(M) :-
    forall(( current_predicate(M:Name/Arity),
             functor(Head, Name, Arity),
             predicate_property(M:Head, implementation_module(M)) ),
           catch(abolish(M:Name/Arity), _, true)).

%!  shutdown(+Kb) is det.
%   Frees Kb's rule modules and empties its facts.
shutdown(Kb) :-
    forall(active_rules(Kb, M), free_module(M)),
    forall(retired_rules(Kb, M, _), free_module(M)),
    retractall(active_rules(Kb, _)),
    retractall(retired_rules(Kb, _, _)),
    forall(kb_fact(Name/Arity), ( functor(Head, Name, Arity), retractall(Kb:Head) )),
    flag(wm_decision_facts(Kb), _, 0).
