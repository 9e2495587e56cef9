"""Process plumbing, apart from the physics and the statistics: work forked beside the fit
(:mod:`.beside`), the garbage collector's pauses (:mod:`.garbage`), numba's compiled-code cache
(:mod:`.numba_cache`, :mod:`.numba_setup`), Ctrl-C and termination (:mod:`.signals`), BLAS and
numba threads (:mod:`.threads`) and the per-user cache folder (:mod:`.user_cache`)."""
