"""Planning a drag firing before it is fired: the Cramér-Rao sd of one planned case
(:mod:`~bayesdrag.planning.case`) and the whole plan (:mod:`~bayesdrag.planning.plan`)."""
