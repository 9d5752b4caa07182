/*  plunit tests for world_model.pl.

    Run:  swipl -g run_tests -t halt rules/prolog/world_model.plt

    world_model.pl is loaded the way rules::Engine loads it: into a fresh module whose base module is
    `system` and whose default import module is `wm_kb`, the facts module defined below. Each test
    installs its own facts with with_facts/2.
*/
:- use_module(library(plunit)).
:- use_module(library(lists)).

%   The test-facts module: the same dynamic facts the C++ engine asserts from the floor plan.
:- dynamic wm_kb:object/2, wm_kb:attribute/2, wm_kb:edge/5, wm_kb:element/8, wm_kb:decision/7,
           wm_kb:observation_origin/1, wm_kb:element_grid/3, wm_kb:edge_evidence/5, wm_kb:edge_seen_through/6,
           wm_kb:edge_beams/4.
:- set_module(wm_kb:base(system)).
wm_kb:edge_seen_through(O, E, S0, S1, Through) :- wm_kb:edge_seen_through(O, E, S0, S1, Through, _).

:- prolog_load_context(directory, Dir),
   directory_file_path(Dir, 'world_model.pl', File),
   set_module(wm_rules_under_test:base(system)),
   add_import_module(wm_rules_under_test, wm_kb, start),
   load_files(wm_rules_under_test:File, []).

%!  with_facts(+Facts, :Goal) is semidet.
%   Runs Goal with exactly Facts (object/2, attribute/2, edge/5 terms) in wm_kb.
with_facts(Facts, Goal) :-
    setup_call_cleanup(set_facts(Facts), once(Goal), set_facts([])).

set_facts(Facts) :-
    retractall(wm_kb:object(_, _)),
    retractall(wm_kb:attribute(_, _)),
    retractall(wm_kb:edge(_, _, _, _, _)),
    retractall(wm_kb:element(_, _, _, _, _, _, _, _)),
    retractall(wm_kb:element_grid(_, _, _)),
    retractall(wm_kb:edge_evidence(_, _, _, _, _)),
    retractall(wm_kb:edge_beams(_, _, _, _)),
    retractall(wm_kb:edge_seen_through(_, _, _, _, _, _)),
    forall(member(F, Facts), assertz(wm_kb:F)).

plan([ object(w1, wall), attribute(w1, solid), edge(w1, w1_e0, 2.0, 0.0, 4.0),
       object(t1, table), attribute(t1, not_deformable), edge(t1, t1_e0, 1.0, 1.5707963, 0.8),
       object(d1, door), edge(d1, d1_e0, 3.0, 0.0, 0.9),
       object(x1, cupboard), attribute(x1, solid), attribute(x1, not_deformable)
     ]).

%   decide(+Match, -Action, -Rule, -Explanation) with the standard plan and a lidar observation.
decide(Match, Action, Rule, Explanation) :-
    plan(Facts),
    with_facts(Facts,
               wm_rules_under_test:decide(observation(lidar, 2.0, 0.0, 3.5), Match,
                                          Action, Rule, Explanation)).

:- begin_tests(world_model).

test(solid_object_is_deleted_and_confirmed, [Action-Rule == delete-solid_confirmed]) :-
    decide(element(e7, w1, 0.25), Action, Rule, _).

test(element_not_in_plan_is_merged, [Action-Rule == merge-unknown_element_merged]) :-
    decide(element(e8, none, 1.5), Action, Rule, _).

test(element_lying_on_a_grown_element_is_joined, [Action-Rule == merge-elements_merged]) :-
    setup_call_cleanup(assertz(wm_kb:observation_origin(element)),
                       decide(element(e8, none, 12.0), Action, Rule, _),
                       retractall(wm_kb:observation_origin(_))).

test(scan_line_on_an_element_is_not_a_join, [Rule == unknown_element_merged]) :-
    setup_call_cleanup(assertz(wm_kb:observation_origin(scan)),
                       decide(element(e8, none, 1.5), _, Rule, _),
                       retractall(wm_kb:observation_origin(_))).

test(not_deformable_object_is_rigidly_adjusted, [Action-Rule == rigid_adjust-not_deformable_rigid]) :-
    decide(element(e9, t1, 0.5), Action, Rule, _).

test(unmatched_observation_is_added, [Action-Rule == add-unmatched_added]) :-
    decide(none, Action, Rule, _).

test(plain_apriori_object_is_confirmed, [Action-Rule == delete-apriori_confirmed]) :-
    decide(element(e10, d1, 0.1), Action, Rule, _).

test(solid_wins_over_not_deformable, [Rule == solid_confirmed]) :-
    decide(element(e11, x1, 0.1), _, Rule, _).

test(unknown_object_gets_no_decision, [fail]) :-
    decide(element(e12, ghost, 0.1), _, _, _).

test(only_first_solution_per_match, [Count == 1]) :-
    plan(Facts),
    with_facts(Facts,
               aggregate_all(count,
                             wm_rules_under_test:decide(observation(lidar, 2.0, 0.0, 3.5),
                                                        element(e7, w1, 0.25), _, _, _),
                             Count)).

test(explanation_names_element_object_and_distance) :-
    decide(element(e7, w1, 0.25), _, _, Explanation),
    string(Explanation),
    once(sub_string(Explanation, _, _, _, "e7")),
    once(sub_string(Explanation, _, _, _, "w1")),
    once(sub_string(Explanation, _, _, _, "0.2500")).

test(unmatched_explanation_gives_the_line) :-
    decide(none, _, _, Explanation),
    once(sub_string(Explanation, _, _, _, "rho = 2.0000 m")),
    once(sub_string(Explanation, _, _, _, "length = 3.5000 m")).

test(attributes_come_from_the_facts, [Rule == apriori_confirmed]) :-
    with_facts([object(w1, wall)],
               wm_rules_under_test:decide(observation(lidar, 2.0, 0.0, 3.5),
                                          element(e7, w1, 0.25), _, Rule, _)).

%   pruned(+Origin, +Backed, +Contrary, -Pruned): the elements prune/3 names for one element e5 of Origin with
%   the given grid shares.
pruned(Origin, Backed, Contrary, Pruned) :-
    with_facts([element(e5, Origin, robot, 2.0, 0.0, 1.5, 3, 0.0), element_grid(e5, Backed, Contrary),
                element(e6, scan, robot, 4.0, 0.0, 1.0, 9, 0.0)],
               findall(E-R, wm_rules_under_test:prune(E, R, _), Pruned)).

test(element_the_grid_sees_through_is_pruned, [Pruned == [e5-grid_unbacked]]) :-
    pruned(scan, 0.0, 0.9, Pruned).

test(element_the_grid_backs_in_part_stays, [Pruned == []]) :-
    pruned(scan, 0.2, 0.8, Pruned).

test(element_the_grid_has_barely_seen_stays, [Pruned == []]) :-
    pruned(grid, 0.0, 0.3, Pruned).

test(element_a_client_posted_stays_where_the_laser_sees_through, [Pruned == []]) :-
    pruned(client, 0.0, 1.0, Pruned).

test(prune_explanation_gives_the_numbers) :-
    with_facts([element(e5, scan, robot, 2.0, 0.0, 1.5, 3, 0.0), element_grid(e5, 0.0, 0.9)],
               wm_rules_under_test:prune(e5, _, Explanation)),
    once(sub_string(Explanation, _, _, _, "1.500 m")),
    once(sub_string(Explanation, _, _, _, "90 %")).

test(rules_do_not_see_user_predicates, [error(existence_error(procedure, _))]) :-
    wm_rules_under_test:wm_undefined_helper.

:- end_tests(world_model).

:- begin_tests(verdicts).

test(wall_seen_through_is_missing, [V-R == missing-wall_missing]) :-
    plan(P),
    with_facts([edge_evidence(w1, w1_e0, 0.0, 0.9, 0.95), edge_beams(w1, w1_e0, 250, 0)|P],
               wm_rules_under_test:edge_verdict(w1, w1_e0, V, R, _)).

test(wall_whose_beams_end_on_it_is_not_missing, [fail]) :-
    plan(P),
    with_facts([edge_evidence(w1, w1_e0, 0.0, 0.9, 0.95), edge_beams(w1, w1_e0, 30, 8)|P],
               wm_rules_under_test:edge_verdict(w1, w1_e0, missing, _, _)).

test(wall_free_but_not_crossed_by_beams_is_not_missing, [fail]) :-
    plan(P),
    with_facts([edge_evidence(w1, w1_e0, 0.0, 0.9, 0.95), edge_beams(w1, w1_e0, 1, 0)|P],
               wm_rules_under_test:edge_verdict(w1, w1_e0, missing, _, _)).

test(door_cut_in_is_partly_missing, [V-R == partly_missing(1.5, 2.5)-wall_partly_missing]) :-
    plan(P),
    with_facts([edge_evidence(w1, w1_e0, 0.7, 0.25, 0.95), edge_seen_through(w1, w1_e0, 1.5, 2.5, 40, 40)|P],
               wm_rules_under_test:edge_verdict(w1, w1_e0, V, R, _)).

test(stretch_whose_beams_end_on_it_is_not_partly_missing, [fail]) :-
    plan(P),
    with_facts([edge_evidence(w1, w1_e0, 0.7, 0.25, 0.95), edge_seen_through(w1, w1_e0, 1.5, 2.5, 40, 41)|P],
               wm_rules_under_test:edge_verdict(w1, w1_e0, _, _, _)).

test(backed_wall_has_no_verdict, [fail]) :-
    plan(P),
    with_facts([edge_evidence(w1, w1_e0, 0.9, 0.0, 0.95)|P],
               wm_rules_under_test:edge_verdict(w1, w1_e0, _, _, _)).

test(table_seen_through_is_gone, [R == object_gone]) :-
    plan(P),
    with_facts([edge_evidence(t1, t1_e0, 0.0, 1.0, 1.0)|P],
               wm_rules_under_test:object_verdict(t1, gone, R, _)).

:- end_tests(verdicts).
