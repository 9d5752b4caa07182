/*  Example extension: movable objects (doors, sliding partitions).

    A door is drawn closed, but it is often open: an observation that matches a `movable` object is
    not a confirmation of the drawing (delete) but news about where the door is now, so it is merged:
    the server keeps the drawing as drawn and starts (or continues) an observed element from the fusion
    of the drawn edge and the observation.

    To use it, copy this file into the rules directory; mark doors "attributes": ["movable"].
*/

override(observation(Observer, _, _, _), element(Element, Object, D2), merge, movable_merged,
         Explanation) :-
    Object \== none,
    attribute(Object, movable),
    format(string(Explanation),
           "~w matched element ~w of movable object ~w (d2 = ~4f): merged as its observed state, \c
            the drawing is kept",
           [Observer, Element, Object, D2]).
