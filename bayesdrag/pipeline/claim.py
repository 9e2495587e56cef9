"""Stage 5 of a fit, *claim*: each Cd row's band and whether it is claimed (determined). The
model-error terms the check left are joined by the wind layers' placement spread and a narrow
span's shape term, the quality assessment makes each row's ``band_sd`` and ``determined``
(:func:`~bayesdrag.estimate.cd.quality.assess`), and what the check found, what the air
contradicts and (for a rigid drag model) the flexible fit of the same track may withdraw rows."""
from __future__ import annotations

import numpy as np

from ..errors import FitError, InputError
from ..estimate.build.model_size import narrow_shape_sd
from ..estimate.cd.claims import BandTerm, add_model_error, claim
from ..estimate.cd.quality import assess, assess_claims, check_against_flexible, intervals
from ..estimate.cd.table import cd_table
from ..estimate.scheme1.fit import fit_scheme1
from .check import Checked
from .model_check import air, air_contradiction, note_model_error, withdrawn_by_check
from .preparation import Prepared

__all__ = ["claim_stage", "placement_error", "rigid_check", "PLACEMENT_TERM", "NARROW_SHAPE_TERM"]

#: the wind layers' equivalent placements: where the track cannot tell where a wind step lies
PLACEMENT_TERM = BandTerm("placement", why="the Cd spread of the wind layers' equivalent placements")
#: one factor on the table over a narrow span: how far the table's shape may lean
NARROW_SHAPE_TERM = BandTerm("narrow_shape", why="a narrow span's lean of the table's shape")


def claim_stage(prep: Prepared, chk: Checked, ml_progress):
    """The claim of the checked answer ``chk``: its rows' bands and determination (written into
    the rows) and ``(quality, placement)``: ``ml.quality`` and the largest placement spread of the
    wind layers (None without placements)."""
    track, rnd = prep.track, prep.rnd
    ans, gap = chk.answer, chk.gap
    f1, grid, rows = ans.f1, ans.grid, ans.rows
    placement = placement_error(f1, grid, rows)
    if (f1.model_size or {}).get("narrow_span"):   # one factor on the table: the shape may lean
        add_model_error(rows, NARROW_SHAPE_TERM, narrow_shape_sd(f1.model_size["narrow_span"], grid,
                                                            [r["ml"] for r in rows]))
    quality, data = assess_claims(f1, rows, track, rnd.radar.sigma)
    if prep.notes:
        quality["notes"] = list(prep.notes) + list(quality.get("notes") or [])
    withdrawn = np.zeros(len(rows), bool)
    if gap is not None:
        if withdrawn_by_check(gap):
            withdrawn[:] = True
            claim(rows, data, withdrawn)
        note_model_error(gap, quality, grid, rows)
    quality["air"] = air(f1, gap)
    air_contradiction(rnd, quality["air"], quality, rows)
    if f1.drag_model.name != "spline":
        if ml_progress is not None:
            ml_progress("the flexible fit the rigid model is checked against")
        off = rigid_check(track, rnd, prep.opts, prep.chans, f1, grid, rows, quality)
        if off is not None and off.any():
            claim(rows, data, withdrawn | off)
            quality["undetermined"] = intervals(grid, ~np.array([r["determined"] for r in rows]))
    if ml_progress is not None and hasattr(ml_progress, "done"):
        ml_progress.done()
    return quality, placement


def placement_error(f1, grid, rows):
    """Add the Cd spread of the wind layers' equivalent placements
    (:func:`~bayesdrag.estimate.build.winds.placement_sd`) to each row's ``model_error_sd`` in
    squares: where the track cannot tell where a wind step lies, the Cd that follows from each
    choice is as good as the kept one. Returns its largest value [Cd], or None without such
    placements."""
    from ..estimate.build.winds import placement_sd

    if not f1.layer_placements:
        return None
    sd = placement_sd(f1.drag_model, f1.layer_placements, grid)
    add_model_error(rows, PLACEMENT_TERM, sd)
    return float(f"{float(np.max(sd)):.4g}")


def rigid_check(track, rnd, opts, chans, f1, grid, rows, quality):
    """A rigid model's band holds no shape error: check its curve against the flexible fit of
    the same track (:func:`check_against_flexible`). The check never refuses a track the rigid
    model fits: when the flexible fit cannot be made (a track too short for it) or does not
    converge, ``quality.rigid_check`` and a note say so and the rows stand as fitted (None).
    Returns the rows the check withdraws."""
    try:
        ff = fit_scheme1(track, rnd, drag="spline", channels=chans, free_ic=not opts.fix_ic,
                         likelihood=opts.likelihood, nu=opts.ml_nu, start=f1.start, span_rule=False)
    except (InputError, FitError) as exc:
        ff, why = None, str(exc)
    else:
        why = None if ff.success else ff.message
        if why is None and ff.drag_model.name != "spline":
            why = "the track is too short for it"
    if why is not None:
        quality["rigid_check"] = {"against": "spline", "skipped": why}
        quality.setdefault("notes", []).append(
            f"the {f1.drag_model.name} curve could not be checked against the flexible fit of the same track "
            f"({why}): its band holds the noise only, not its shape error")
        return None
    rows_f = cd_table(ff.ml, ff.drag_model, grid, rnd.reference_drag)
    assess(ff, rows_f, track, rnd.radar.sigma)
    return check_against_flexible(rows, rows_f, quality, f1.drag_model.name)

