/*  plunit tests for the example extensions, loaded with the shipped world_model.pl the way
    rules::Engine loads a rules directory (one fresh module, base `system`, facts from `wm_kb`, the
    override/5 and prune/3 hooks declared before any file).

    Run:  swipl -g run_tests -t halt rules/examples/examples.plt
*/
:- use_module(library(plunit)).
:- use_module(library(lists)).

:- dynamic wm_kb:object/2, wm_kb:attribute/2, wm_kb:edge/5, wm_kb:element/8, wm_kb:decision/7,
           wm_kb:edge_evidence/5, wm_kb:edge_seen_through/6, wm_kb:edge_beams/4.
:- set_module(wm_kb:base(system)).
wm_kb:edge_seen_through(O, E, S0, S1, Through) :- wm_kb:edge_seen_through(O, E, S0, S1, Through, _).
%   The engine sets the context per decision; here a global variable stands in for it.
wm_kb:observation_sensor(S) :- nb_current(test_sensor, S0) -> S = S0 ; S = unknown.
wm_kb:observation_origin(client).

:- prolog_load_context(directory, Dir),
   M = wm_examples_under_test,
   set_module(M:base(system)),
   add_import_module(M, wm_kb, start),
   forall(member(P, [override/5, prune/3, verdict_override/5, edge_verdict/5, object_verdict/4]),
          (dynamic(M:P), multifile(M:P), discontiguous(M:P))),
   atom_concat(Dir, '/../prolog/world_model.pl', Core),
   forall(member(F, ['glass.pl', 'movable.pl', 'prune_unconfirmed.pl']),
          ( directory_file_path(Dir, F, Path), load_files(M:Path, []) )),
   load_files(M:Core, []).

with_facts(Facts, Goal) :-
    setup_call_cleanup(set_facts(Facts), once(Goal), set_facts([])).

set_facts(Facts) :-
    retractall(wm_kb:object(_, _)),
    retractall(wm_kb:attribute(_, _)),
    retractall(wm_kb:edge(_, _, _, _, _)),
    retractall(wm_kb:element(_, _, _, _, _, _, _, _)),
    retractall(wm_kb:edge_evidence(_, _, _, _, _)),
    retractall(wm_kb:edge_beams(_, _, _, _)),
    forall(member(F, Facts), assertz(wm_kb:F)).

plan([ object(g1, wall), attribute(g1, solid), attribute(g1, glass),
       object(w1, wall), attribute(w1, solid),
       object(d1, door), attribute(d1, movable) ]).

decide(Sensor, Match, Action-Rule) :-
    plan(Facts),
    b_setval(test_sensor, Sensor),
    with_facts(Facts, wm_examples_under_test:decide(observation(r1, 2.0, 0.0, 3.5), Match, Action, Rule, _)).

:- begin_tests(examples).

test(laser_on_glass_is_ignored, [R == ignore-glass_ignored]) :-
    decide(laser, element('g1/0', g1, 0.3), R).

test(sonar_on_glass_falls_through_to_solid, [R == delete-solid_confirmed]) :-
    decide(sonar, element('g1/0', g1, 0.3), R).

test(glass_wall_seen_through_is_kept, [V-R == kept-glass_kept]) :-
    plan(P),
    with_facts([edge(g1, 'g1/0', 2.0, 0.0, 4.0), edge_evidence(g1, 'g1/0', 0.0, 1.0, 1.0)|P],
               wm_examples_under_test:verdict_override(g1, 'g1/0', V, R, _)).

test(plain_wall_seen_through_is_still_missing, [V == missing]) :-
    plan(P),
    with_facts([edge(w1, 'w1/0', 2.0, 0.0, 4.0), edge_evidence(w1, 'w1/0', 0.0, 1.0, 1.0), edge_beams(w1, 'w1/0', 90, 0)|P],
               ( \+ wm_examples_under_test:verdict_override(w1, 'w1/0', _, _, _),
                 wm_examples_under_test:edge_verdict(w1, 'w1/0', V, _, _) )).

test(laser_on_plain_wall_is_still_confirmed, [R == delete-solid_confirmed]) :-
    decide(laser, element('w1/0', w1, 0.3), R).

test(door_is_merged_not_deleted, [R == merge-movable_merged]) :-
    decide(laser, element('d1/0', d1, 0.3), R).

test(core_rules_unchanged_for_unmatched, [R == add-unmatched_added]) :-
    decide(laser, none, R).

test(old_single_observation_is_pruned, [Es == [e1]]) :-
    get_time(Now), Old is Now - 3600, Recent is Now - 10,
    with_facts([ element(e1, scan, r1, 1.0, 0.0, 2.0, 1, Old),
                 element(e2, scan, r1, 1.0, 0.0, 2.0, 1, Recent),
                 element(e3, scan, r1, 1.0, 0.0, 2.0, 5, Old) ],
               findall(E, wm_examples_under_test:prune(E, unconfirmed_pruned, _), Es)).

test(prune_explanation_names_the_element) :-
    get_time(Now), Old is Now - 3600,
    with_facts([element(e1, scan, r1, 1.0, 0.0, 2.0, 1, Old)],
               wm_examples_under_test:prune(e1, _, Explanation)),
    once(sub_string(Explanation, _, _, _, "e1")).

:- end_tests(examples).
