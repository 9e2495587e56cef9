"""The sim-to-real gap diagnosis: where the nominal simulation misses a track, which unmodelled
effect explains it, how large the effect is, how much of the gap it removes, and what it would
have done to a fitted Cd (``diagnosis.json``, docs/diagnosis.md). Pure functions, no I/O;
:mod:`bayesdrag.report.diagnosis` writes the files and :mod:`bayesdrag.plots.diagnosis` draws the
figures.

Method (each decision with its reason; docs/diagnosis.md has the long form):

1. **Noise and outliers from the data, not from the fit.** Per channel the residual about a
   local cubic (Savitzky-Golay, 11 samples, never across a dropout or gap) measures the
   high-frequency content. Samples further
   than ``OUTLIER_K`` robust sd from it are flagged as gross outliers and get weight 0 in every
   fit (listed in the output). The noise sd is the round's ``[radar] sigma`` when given;
   otherwise the robust sd of that local residual corrected for the smoother. The baseline
   residuals are never used for sigma: a misfit would inflate it and hide the gap. Limitation:
   strongly correlated (AR(1)) noise has little high-frequency content, so an estimated sigma is
   then too small; the significance rule below is invariant to that scale (it uses the residual
   autocovariance measured against the assumed sigma), but ``chi2_per_sample`` and the gap are
   inflated — the output says which sigma was estimated.
2. **Baseline** = the round's reference drag (or, without one, a fitted Cd as nuisance: the
   penalised spline of a Scheme 1 fit of the same track and channels, :func:`setup.nuisance_drag`,
   with its smoothness penalty at the evidence-chosen sd as linear pseudo-priors; the Scheme 1
   fit supplies only the drag model, the penalty and the starting coefficients and state) in the
   round's atmosphere, without Earth rotation and without any effect, with the initial state as
   nuisance parameters. When the round gives launch velocity and elevation the state is the one
   *at launch, t = 0*, with Gaussian priors: muzzle at the origin (``position_sd``), launch speed
   (``velocity_sd``), elevation (``elevation_sd``) and heading along the firing azimuth
   (sd = ``elevation_sd``: the gun is laid in deflection as carefully as in elevation). So a
   track whose start is inconsistent with the muzzle at t = 0 costs prior misfit (a late radar
   clock is a symptom, not absorbed). Without launch data the state is at the first sample and
   ``radar_time`` is not identifiable.
3. **Gap** = chi2 (noise-weighted residuals plus prior misfit) minus its noise-only expectation
   (number of weighted samples + launch priors - effective parameters: the free ones less what
   the nuisance spline's penalty takes, :func:`setup.edf`); ``shrink`` = fraction of it an effect
   removes, clipped to [0, 1].
4. **Which**: every candidate is fitted by ML with its parameters and the initial state.
   Significance: the chi2 drop ``d`` is divided by the colored-noise inflation
   ``g' Rvv g / g' R g`` of the fitted output change ``g`` (residual autocovariance measured on
   the candidate's own residuals, summed to the lag where it drops below its noise level, as in
   Morelli & Klein's colored-residual CRB). Under AR(1) noise with rho = 0.95 this inflation is
   ~30, and it also absorbs a wrong assumed sigma. The statistic is compared with the chi2
   quantile of the effect's number of parameters at ``ALPHA / K`` (Bonferroni over the K
   candidates tested). Ranking by chi2 drop (= 2 delta log-likelihood); exact ties keep the
   library order.
5. **Confounding**: two effects are ``confounded_with`` each other when their signatures (output
   sensitivities with the initial state and drag nuisance projected out) span nearly the same
   direction (canonical correlation >= ``CONFOUND_CORR``: density vs drag_scale is exactly 1),
   or when both are significant and the data prefer one over the other by less than the 95 %
   point of chi2(1) in colored units.
6. **Forward selection**: the best significant effect enters the verdict; the others are refitted
   together with the selected ones and enter when their conditional chi2 drop is significant
   (same rule, K = remaining candidates) and removes at least ``MIN_SECOND_SHARE`` of the
   baseline gap (a practical-size rule: a model mismatch that no effect describes leaves
   correlated residuals that a second effect would always nibble at). Forward selection is also
   started from up to two runners-up that explain most of the gap alone; between the resulting
   explanations parsimony wins unless the larger is significantly better (:func:`selection.is_better`).
   The verdict is ordered by what each member explains alone. Without a ``y`` channel the cross
   wind is held at 0 (:func:`setup.extra_free`); a candidate whose fit fails is skipped with the
   reason.
7. **Where**: normalised baseline residuals smoothed over ~1 % of the flight; segments where the
   smoothed residual exceeds the noise sd (merged over short breaks), by channel, with time,
   Mach range, phase (ascent, apex = within 10 % of the flight time of the summit, descent) and
   share of the systematic residual energy.
8. **Cd shift**: the output change an effect causes, refitted by a Scheme 1 spline Cd plus the
   initial state (linearised), shows what a Cd fit that ignored the effect would have absorbed.
9. **Materiality**: a detected effect is material when ignoring it would shift a
   fitted Cd by more than ``material_cd_shift`` (0.1 %) anywhere in the flown Mach range or move
   the track's last sample by more than ``material_end_sd`` (3) noise sd; both figures of a
   detected effect come from the detected effects' joint fit (:func:`impact.effect_change`). The
   verdict lists the material ones; ``immaterial`` the detectable but immaterial ones.
10. **A table of another shell** is ``drag_shape`` (the table times a correction that
    ``drag_scale`` cannot mimic) with its level as ``drag_scale`` or its twin ``density``; when
    it is detected, every other effect is judged against a fitted Cd, as without a table
    (:func:`selection.wrong_table_fit`): no finite correction makes a wrong table a reference a
    weather effect could be measured against.

The steps live in the package's modules, lowest first:

* :mod:`~bayesdrag.diagnosis.setup`: the baseline problem (:class:`Setup`, :func:`make_setup`, the
  nuisance drag, the flown Mach span, the ``drag_shape`` functions) and the ML fits of the
  baseline plus effects, with their noise floor (steps 1-3);
* :mod:`~bayesdrag.diagnosis.statistics`: residual autocovariance, colored inflation, the
  significance rule (step 4);
* :mod:`~bayesdrag.diagnosis.signatures`: projected signatures, identifiability, confounding (5);
* :mod:`~bayesdrag.diagnosis.candidates`: which candidates are testable, each fitted alone (4);
* :mod:`~bayesdrag.diagnosis.selection`: forward selection, backward elimination, the wrong-table
  rule (6, 10);
* :mod:`~bayesdrag.diagnosis.where`: where the baseline misses (7);
* :mod:`~bayesdrag.diagnosis.impact`: Cd shift, end-of-track shift, materiality (8, 9);
* :mod:`~bayesdrag.diagnosis.core`: :func:`diagnose` and its result :class:`Diagnosis`.

The noise and outlier helpers are :mod:`bayesdrag.estimate.model.noise`'s.
"""
from __future__ import annotations

from .core import MIN_DIAGNOSIS_SAMPLES, Diagnosis, diagnose
from .impact import MATERIAL_CD_SHIFT, MATERIAL_END_SD, cd_shift, effect_change, end_shift, materiality
from .selection import DRAG_EFFECTS, MAX_VERDICT, MIN_LEFT_SHARE, MIN_SECOND_SHARE
from .setup import Setup, flown_mach_span, make_setup, nuisance_drag
from .signatures import CONFOUND_CORR, IDENTIFIABLE_FRACTION, canonical_corr, signatures
from .statistics import ALPHA, autocovariance, chi2_noise_sd, colored_inflation, threshold
from .where import where_segments

__all__ = ["diagnose", "Diagnosis", "MIN_DIAGNOSIS_SAMPLES", "ALPHA", "MATERIAL_CD_SHIFT", "MATERIAL_END_SD",
           "CONFOUND_CORR", "IDENTIFIABLE_FRACTION", "MIN_SECOND_SHARE", "MIN_LEFT_SHARE", "MAX_VERDICT",
           "DRAG_EFFECTS", "Setup", "make_setup", "nuisance_drag", "flown_mach_span", "autocovariance",
           "chi2_noise_sd", "colored_inflation", "threshold", "signatures", "canonical_corr", "where_segments",
           "effect_change", "end_shift", "cd_shift", "materiality"]
