/*  world_model.pl — the shipped rules of the world-model knowledge base.

    A new line primitive is first matched numerically (in C++) against the vector map; these rules
    then decide what happens to it (the Action below). C++ does the numbers, this file only
    decides and explains.

    CONTRACT FOR RULE WRITERS (every *.pl file of the rules directory is loaded; *.plt is ignored)

    - Write plain clauses: no `:- module` directive. All files of the directory are loaded, sorted by
      name, into one fresh module; an edit only becomes active after a reload that loads every file
      without any error OR warning (singleton variables, discontiguous clauses... count) and passes
      the self-check below. Otherwise the previous rules stay active and the reload reports
      "file:line: message" for each problem.
    - Only `system` predicates, autoloadable library predicates and the facts below are visible;
      predicates of `user` are not.
    - A file is read as terms and checked before it is loaded, so loading it runs nothing. Allowed
      directives: `:- use_module(library(L))` (and ensure_loaded) for L in lists, apply, aggregate,
      pairs, yall, error, ordsets, assoc, rbtrees, option, solution_sequences, occurs, strings,
      dicts; `:- dynamic`, `:- discontiguous` and `:- multifile` of the file's own predicates. Any
      other directive, a clause for another module (`user:...`) or for a hook of Prolog itself
      (term_expansion, goal_expansion, message_hook, portray, ...) rejects the reload.
    - Everything decide/5 and prune/3 can call must pass library(sandbox) (no files, processes,
      threads, flags or writes to other modules), and no format text may use a column, fill or
      precision argument above 1000 or take one from its arguments (~*c): such calls run in C,
      where no time limit can stop them. Brackets may nest at most 200 levels deep.

    Facts (asserted by C++ from the floor plan; they exist, possibly empty, at all times):

        object(ObjectId, Kind).                          % atoms, e.g. object(w1, wall)
        attribute(ObjectId, Attribute).                  % atoms, e.g. solid, not_deformable
        edge(ObjectId, EdgeId, Rho, Phi, Length).        % world frame, Hesse normal form:
                                                         % x cos Phi + y sin Phi = Rho;
                                                         % Rho [m] >= 0, Phi [rad], Length [m]

    The decision predicate a rule set must define:

        % decide(+Observation, +Match, -Action, -Rule, -Explanation)
        % Observation = observation(Observer, Rho, Phi, Length)   Observer atom (the robot); Rho [m], Phi [rad],
        %                                                       Length [m] (floats)
        % Match = none                                  nothing in the map matched
        %       | element(ElementId, ObjectId, D2)      matched an a-priori edge of ObjectId
        %       | element(ElementId, none, D2)          matched an observed element not in the plan
        %         (D2: squared Mahalanobis distance of the match, a float; the match itself is
        %          made in the segment's frame, so D2 may exceed the χ² 95 % bound 5.991)
        % Action = delete | merge | rigid_adjust | add  (atoms; rule sets may add others that the
        %                                                server knows)
        % Rule = atom naming the rule that fired (logged with the decision)
        % Explanation = string or atom, human readable, with the numbers

    More facts and context the rules may read:

        element(Id, Origin, Observer, Rho, Phi, Length, Support, UpdatedAt)
                                     % observed map elements not in the plan; Origin = client | scan
                                     % | grid; Support = observations fused; UpdatedAt [unix s]
        element_grid(Id, Backed, Contrary)
                                     % what the occupancy grid said of element Id at its last check (every
                                     % few scans, over what the scans saw): the shares of its length within
                                     % one cell of an occupied cell (P > 0.65), and seen by the grid without
                                     % one (free, or too little evidence); the rest is unknown. Gone when
                                     % the element changes, until the next check.
        edge_evidence(Object, Edge, Backed, SeenThrough, Observed)
                                     % what the occupancy grid says of plan edge Edge of Object (as the
                                     % object stands now), at the last grid check that could see it: the
                                     % shares of its length within one cell of an occupied cell (backed),
                                     % seen free with nothing occupied within 3 cells across (seen through:
                                     % beams crossed the line where it is drawn), and seen at all
        edge_seen_through(Object, Edge, S0, S1, Through, Ended)
                                     % a stretch of Edge seen through, [m] from its first end (>= 0.3 m),
                                     % and the laser beams counted passing through it and returning on it
                                     % (edge_seen_through/5 leaves Ended out)
        edge_beams(Object, Edge, Through, Ended)
                                     % laser beams counted at Edge where it stands now: passed through
                                     % it (returned more than 10 cm beyond it), returned on it
        decision(Seq, Action, Rule, Element, Object, Observer, At)
                                     % the most recent decisions (Element/Object `none` if absent)
        observation_origin(Origin)   % of the observation being decided: client | scan | grid, or
                                     % element when an element is checked against a neighbour
                                     % that grew (Observer is then the element's id)
        observation_sensor(Sensor)   % laser | sonar | unknown

    Extension points (any rule file may add clauses, in any file order; see rules/examples/):

        override(Observation, Match, Action, Rule, Explanation)
                                     % tried before the rules below; the first answer wins
        prune(ElementId, Rule, Explanation)
                                     % asked after each update: elements to remove from the map
        verdict_override(Object, Edge, Verdict, Rule, Explanation)
                                     % tried before edge_verdict/5 for each edge with evidence; the
                                     % first answer wins; Verdict `kept` means no verdict (a glass wall)
        edge_verdict(Object, Edge, Verdict, Rule, Explanation)
                                     % what the evidence says of an edge: `missing` (the whole edge) or
                                     % partly_missing(S0, S1) (one answer per stretch); every answer counts
        object_verdict(Object, Verdict, Rule, Explanation)
                                     % what the evidence says of a whole object, e.g. `gone`

    Only the first solution counts. Each decision runs under an inference limit and a time limit.
    A decision that fails, throws, hits a limit or answers a non-atom action is replaced by the
    fallback `add` (rule `fallback`), which keeps the observation and changes nothing else.

    Self-check at every (re)load, on temporary facts: decide/5 must be defined in these files and
    answer an atom action for a matched solid wall, a matched element not in the plan, a matched
    not_deformable object and an unmatched observation.

    The rule names below (solid_confirmed, elements_merged, unknown_element_merged,
    not_deformable_rigid, unmatched_added, apriori_confirmed, grid_unbacked, wall_missing,
    wall_partly_missing, object_gone) are part of the API: clients and logs refer to them.
*/

:- dynamic override/5, prune/3, verdict_override/5, edge_verdict/5, object_verdict/4.
:- multifile override/5, prune/3, verdict_override/5, edge_verdict/5, object_verdict/4.
:- discontiguous override/5, prune/3, verdict_override/5, edge_verdict/5, object_verdict/4.

%   0. Extensions first (glass, movable objects, ...: rules/examples/).
decide(Observation, Match, Action, Rule, Explanation) :-
    override(Observation, Match, Action, Rule, Explanation),
    !.
%   1. A match on a solid a-priori object (a wall) confirms the plan: the observation is dropped.
decide(observation(Observer, _, _, _), element(Element, Object, D2), delete, solid_confirmed,
       Explanation) :-
    Object \== none,
    attribute(Object, solid),
    !,
    format(string(Explanation),
           "~w matched element ~w of solid object ~w (d2 = ~4f): the plan is confirmed, \c
            the observation is deleted",
           [Observer, Element, Object, D2]).
%   2a. Maintenance: after an element grew, another element not in the plan lies on it (within the
%       match gate). Asked with observation_origin(element) and the other element's id as Observer:
%       the two are views of one wall and are joined (fused line, union of extents, support summed).
decide(observation(Other, _, _, Length), element(Element, none, D2), merge, elements_merged,
       Explanation) :-
    observation_origin(element),
    !,
    format(string(Explanation),
           "element ~w (~3f m) lies on element ~w (d2 = ~4f): one wall, joined into ~w",
           [Other, Length, Element, D2, Element]).
%   2. A match on an element that is not in the plan (e.g. a temporary wall of boxes): fuse both.
decide(observation(Observer, _, _, _), element(Element, none, D2), merge, unknown_element_merged,
       Explanation) :-
    !,
    format(string(Explanation),
           "~w matched element ~w, which is not in the floor plan (d2 = ~4f): merged by \c
            Kalman fusion",
           [Observer, Element, D2]).
%   3. A match on a not_deformable object (a table, a wardrobe): move the object, keep its shape.
decide(observation(Observer, _, _, _), element(Element, Object, D2), rigid_adjust,
       not_deformable_rigid, Explanation) :-
    attribute(Object, not_deformable),
    !,
    format(string(Explanation),
           "~w matched element ~w of not_deformable object ~w (d2 = ~4f): the object's pose \c
            is adjusted, its shape kept",
           [Observer, Element, Object, D2]).
%   4. Nothing matched: a new element.
decide(observation(Observer, Rho, Phi, Length), none, add, unmatched_added, Explanation) :-
    !,
    format(string(Explanation),
           "~w observed a line (rho = ~4f m, phi = ~4f rad, length = ~4f m) that matches \c
            nothing: added as a new element",
           [Observer, Rho, Phi, Length]).
%   5. A match on any other a-priori object: the plan element is confirmed, nothing changes.
decide(observation(Observer, _, _, _), element(Element, Object, D2), delete, apriori_confirmed,
       Explanation) :-
    object(Object, Kind),
    !,
    format(string(Explanation),
           "~w matched element ~w of a-priori ~w ~w (d2 = ~4f): the plan element is confirmed, \c
            the observation is deleted",
           [Observer, Element, Kind, Object, D2]).

%   Removal: an element made from scans (or by the grid extractor) of which the occupancy grid backs no part
%   while it has seen at least half of it: the surface has gone (a person who walked past, a chair that was
%   moved, a door that opened) or was never there (a bad fit). Elements a client posted stay: a client may
%   know of a surface the laser sees through (glass).
prune(Element, grid_unbacked, Explanation) :-
    element_grid(Element, Backed, Contrary),
    Backed < 0.05,
    Contrary >= 0.5,
    element(Element, Origin, _, _, _, Length, Support, _),
    Origin \== client,
    Percent is round(100 * Contrary),
    format(string(Explanation),
           "the occupancy grid backs none of element ~w (~3f m, ~w, support ~w) and has seen ~w % \c
            of it without an occupied cell: removed",
           [Element, Length, Origin, Support, Percent]).

%   Verdicts on the plan. The server checks the plan's edges against the occupancy grid every few scans
%   (where the scans since the last check could see) and asks these rules what the evidence means. A
%   verdict changes nothing by itself: it is listed as a change (GET /api/v1/changes) that a person
%   accepts into the plan or rejects.

%   A solid wall the laser sees through over most of what it has seen of it, and that no occupied cell
%   backs: it has gone (demolished). Most of it must have been seen, so a glimpse is not a verdict.
edge_verdict(Object, Edge, missing, wall_missing, Explanation) :-
    wall_seen_through(Object, Edge, Backed, SeenThrough, Observed),
    edge(Object, Edge, _, _, Length),
    beams(Object, Edge, Through, Ended),
    Seen is SeenThrough * Length,
    BackedPercent is round(100 * Backed),
    ObservedPercent is round(100 * Observed),
    format(string(Explanation),
           "wall ~w (edge ~w, ~2f m): the laser saw through ~2f m of it, ~w beams passed where it is drawn \c
            and ~w returned on it (free cells, nothing occupied within 3 grid cells across); ~w % of it was \c
            observed and ~w % is backed by an occupied cell: missing",
           [Object, Edge, Length, Seen, Through, Ended, ObservedPercent, BackedPercent]).
%   Part of a solid wall seen through, the rest standing (a door cut in, a wall shortened): one verdict
%   per stretch. At least as many beams must have crossed the stretch as returned on it: a thin standing
%   wall seen from both sides with a poor pose has its cells freed by the beams of each side that fall a
%   cell short of it, yet most of its beams end on it (a twelfth passed, on the walls measured). A stretch
%   that is gone still has returns counted on it, from the walls it met and from the pose's error, but
%   fewer than half as many as passed.
edge_verdict(Object, Edge, partly_missing(S0, S1), wall_partly_missing, Explanation) :-
    solid_wall(Object),
    \+ wall_seen_through(Object, Edge, _, _, _),
    edge_seen_through(Object, Edge, S0, S1, Through, Ended),
    Stretch is S1 - S0,
    crossed_along(Through, Stretch),
    Through >= Ended,
    edge(Object, Edge, _, _, Length),
    format(string(Explanation),
           "wall ~w (edge ~w, ~2f m): the laser saw through it from ~2f m to ~2f m of its length \c
            (~2f m, free cells where it is drawn, nothing occupied within 3 grid cells across), ~w beams \c
            passed through that stretch and ~w returned on it: that part is missing",
           [Object, Edge, Length, S0, S1, Stretch, Through, Ended]).

%   The beams counted at an edge: passed through it, returned on it (0 when none were counted).
beams(Object, Edge, Through, Ended) :-
    (   edge_beams(Object, Edge, Through, Ended)
    ->  true
    ;   Through = 0,
        Ended = 0
    ).

solid_wall(Object) :- attribute(Object, solid).

%   Enough beams crossed a stretch to have crossed it all along: at least 3, and one per 15 cm (three
%   cells) on average. Its free cells alone may come from beams running along the line; a standing
%   wall seen at a grazing angle with a poor pose lets a few beams slip across it near an end, and
%   they cross it at a few points, not over a metre or more.
crossed_along(Beams, Stretch) :-
    Beams >= 3,
    Beams >= Stretch / 0.15.

wall_seen_through(Object, Edge, Backed, SeenThrough, Observed) :-
    solid_wall(Object),
    edge_evidence(Object, Edge, Backed, SeenThrough, Observed),
    Observed >= 0.5,
    Backed =< 0.05,
    SeenThrough >= 0.8 * Observed,
    %   At least 0.3 m seen through, as for a stretch: the face of a column or a door jamb, a few
    %   centimetres long, is too short to tell a wall gone from a pose error.
    edge(Object, Edge, _, _, Length),
    SeenThrough * Length >= 0.3,
    %   Seen through means crossed: free cells alone may come from beams running along the wall. And
    %   the beams that crossed it must outnumber those that returned on it five to one: a standing wall
    %   seen far off with a poor pose smears its returns over many cells (the grid then backs none of
    %   them), but its beams still end on it.
    beams(Object, Edge, Through, Ended),
    crossed_along(Through, SeenThrough * Length),
    Through >= 5 * Ended.

%   A not_deformable object (a table) none of whose edges the grid backs, while it has seen through
%   most of what it has seen of them: it has been taken away. (An object that moved is followed by its
%   rigid adjustments; its edges are checked where it stands now.)
object_verdict(Object, gone, object_gone, Explanation) :-
    attribute(Object, not_deformable),
    aggregate_all(count, edge(Object, _, _, _, _), Edges),
    Edges > 0,
    aggregate_all(count, (edge_evidence(Object, _, _, _, Observed), Observed >= 0.3), Seen),
    Seen * 2 >= Edges,
    \+ ( edge_evidence(Object, _, Backed, _, _), Backed > 0.05 ),
    aggregate_all(sum(SeenThrough), edge_evidence(Object, _, _, SeenThrough, _), SumSeenThrough),
    aggregate_all(sum(Observed), edge_evidence(Object, _, _, _, Observed), SumObserved),
    SumObserved > 0,
    SumSeenThrough >= 0.8 * SumObserved,
    format(string(Explanation),
           "object ~w: ~w of its ~w edges were observed, none is backed by an occupied cell and the laser \c
            sees through where they are drawn: gone",
           [Object, Seen, Edges]).
