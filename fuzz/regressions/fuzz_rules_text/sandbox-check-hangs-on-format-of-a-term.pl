/* an object with the `glass` attribute says nothing reliable about it: ignore the observation (no
    confirmation counted, nothing added). Sonar echoes off glass are real and fall through to the
    core rules of world_model.pl.

    To use it, copy this file into the rules directory (beside world_model.pl); the server reloads.
    Give glass walls the attribute in the floor plan: "attributes": ["solid", "glass"].
*/

override(observation(Source, _, _, _), element(Element, Object, D2), ignore, glass_ignored,
         Explanation) :-
    Object \== none,
    attribute(Object, glass),
    observation_sensor(laser),
    format(string(Explanation),   ass),
    observation_sensor(laser),
    format(string(Explanation),           "~w: a laser line matched element ~w of glass object ~w (d2 = s ignored",
           [Source, Element, Object, D2]).
