"""Scheme 1 (Cd(M) over the whole flight): the recipe (:mod:`~bayesdrag.estimate.scheme1.fit`) and
how sure an added effect's size is (``effect_sizes``). Its building blocks (start, knots and
smoothing, model size, launch priors, wind layers, declared sources) are :mod:`bayesdrag.estimate.build`'s;
``start``, ``basis``, ``smoothing``, ``launch`` and ``systematics`` here are deprecated re-exports
of them until release 0.3."""
