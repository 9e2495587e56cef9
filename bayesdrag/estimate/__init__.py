"""Estimation, by concept, lowest first: ``model/`` (the output-error problem, its ML fit and
Cramér-Rao bounds), then ``scheme1/`` (the paper's Scheme 1 recipe), ``cd/`` (what is claimed
about Cd: rows, budget, quality gate) and ``bayes/`` (the posterior and its sampling), which do
not import each other, and ``scheme2`` (a constant Cd per window). The sub-layers are checked by
``tests/unit/test_architecture.py``."""
