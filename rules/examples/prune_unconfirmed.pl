/*  Example extension: removal of unreliable primitives (the seed paper's pruning step).

    An observed element that nothing confirmed (support 1: seen once) for longer than
    prune_after_s/1 seconds is most likely a person, a cart or a bad fit: remove it. The server asks
    prune/3 after every update and logs each removal as a `prune` decision.

    To use it, copy this file into the rules directory; edit the age below to taste.
*/

prune_after_s(600).

prune(Element, unconfirmed_pruned, Explanation) :-
    prune_after_s(MaxAge),
    get_time(Now),
    element(Element, Origin, Observer, _, _, Length, Support, UpdatedAt),
    Support < 2,
    Age is Now - UpdatedAt,
    Age > MaxAge,
    format(string(Explanation),
           "element ~w (~2f m, ~w from ~w) was seen ~d time(s) and not confirmed for ~0f s \c
            (limit ~w s): removed as unreliable",
           [Element, Length, Origin, Observer, Support, Age, MaxAge]).
