/*  Example extension: glass walls.

    A laser beam passes through glass or reflects off it at odd angles, so a laser line that matches
    an object with the `glass` attribute says nothing reliable about it: ignore the observation (no
    confirmation counted, nothing added). Sonar echoes off glass are real and fall through to the
    core rules of world_model.pl.

    To use it, copy this file into the rules directory (beside world_model.pl); the server reloads.
    Give glass walls the attribute in the floor plan: "attributes": ["solid", "glass"].
*/

override(observation(Observer, _, _, _), element(Element, Object, D2), ignore, glass_ignored,
         Explanation) :-
    Object \== none,
    attribute(Object, glass),
    observation_sensor(laser),
    format(string(Explanation),
           "~w: a laser line matched element ~w of glass object ~w (d2 = ~4f): lasers do not see \c
            glass reliably, the observation is ignored",
           [Observer, Element, Object, D2]).

%   A laser sees through glass, so the grid finds free cells where a glass wall is drawn: that is no
%   evidence that the wall has gone. A glass wall is never called missing.
verdict_override(Object, _Edge, kept, glass_kept, Explanation) :-
    attribute(Object, glass),
    format(string(Explanation), "~w is glass: the laser sees through it, no verdict", [Object]).
