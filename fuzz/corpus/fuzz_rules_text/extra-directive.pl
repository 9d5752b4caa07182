:- use_module(library(lists)).
:- discontiguous foo/1.
foo(1).
user:term_expansion(x, y).
other:bar :- true.
