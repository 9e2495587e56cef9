"""Scheme 1 (Cd(M) over the whole flight): the recipe (:mod:`~bayesdrag.estimate.scheme1.fit`),
its start from the data (``start``), knots and smoothing (``basis``, ``smoothing``), how large a
model the track determines (``model_size``), launch priors (``launch``) and declared systematic
sources as nuisance parameters (``systematics``)."""
