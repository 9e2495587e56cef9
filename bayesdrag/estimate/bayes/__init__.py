"""Bayesian sampling seeded by the ML fit: the log posterior (``posterior``), its sampling
coordinates (``coords``), emcee moves (``moves``), the sampler (``sampler``), convergence
diagnostics (``chain_diagnostics``), Cd from the draws (``draws``), the pointwise
log-likelihood (``loglik``) and the ArviZ conversion (``inference``)."""
