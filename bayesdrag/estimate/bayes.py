"""Compatibility module: the Bayesian layer's public names, re-exported from where they live.

=========================================  ==================================================
:mod:`bayesdrag.estimate.posterior`        the log posterior (:class:`LogPosterior`), its
                                           Laplace approximation and start
:mod:`bayesdrag.estimate.moves`            the independence move and the move mixes
:mod:`bayesdrag.estimate.sampler`          :func:`sample_posterior`, convergence rules and
                                           diagnostics, :class:`BayesResult`, Cd draws and rows
:mod:`bayesdrag.estimate.inference`        :func:`to_inference_data` (ArviZ)
:mod:`bayesdrag.io.chain`                  the chain file (:class:`ChainFile`)
=========================================  ==================================================

New code imports from those modules; this one keeps older imports working.
"""
from __future__ import annotations

from ..io.chain import ChainBackend, ChainFile
from .inference import to_inference_data
from .moves import (INDEPENDENCE_WEIGHT, PROPOSAL_DOF, PROPOSAL_SCALE, describe_moves, independence_move,
                    make_moves)
from .posterior import (IC_PRIOR_FACTOR, LOG_NU_RANGE, SIGMA_RANGE, LogPosterior, fisher_information, mode_fit,
                        student_t_mode)
from .sampler import (DEFAULT_WALKERS, ESS_MIN, RHAT_MAX, TAU_FACTOR, TAU_RTOL, BayesResult, cd_draws,
                      cd_posterior_rows, ess, integrated_time, sample_posterior, split_rank_rhat, summarize)

__all__ = [
    "BayesResult", "ChainBackend", "ChainFile", "DEFAULT_WALKERS", "ESS_MIN", "IC_PRIOR_FACTOR",
    "INDEPENDENCE_WEIGHT", "LOG_NU_RANGE", "LogPosterior", "PROPOSAL_DOF", "PROPOSAL_SCALE", "RHAT_MAX",
    "SIGMA_RANGE", "TAU_FACTOR", "TAU_RTOL", "cd_draws", "cd_posterior_rows", "describe_moves", "ess",
    "fisher_information", "independence_move", "integrated_time", "make_moves", "mode_fit",
    "sample_posterior", "split_rank_rhat", "student_t_mode", "summarize", "to_inference_data",
]
