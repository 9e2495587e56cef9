"""A whole plan: every planned case (:func:`bayesdrag.planning.case.plan_case`), which combination
of them reaches a target accuracy, and the plan in words.

Combining cases (decision): rounds of different cases are fitted separately and pooled by
inverse-variance weighting at each Mach, so the statistical parts (with the round-to-round
scatter, each over its case's rounds) combine as ``1 / sum_i (1 / v_i)``, while a systematic
source is one error shared by every round: its Cd errors add with their signs, weighted like
the pooling (``sum_i w_i a_ik``). The combination that reaches the target (relative sd of Cd)
over the widest contiguous Mach interval wins; among equals, the one with fewer cases, then fewer
rounds, then the smaller worst sd inside the interval. Up to :data:`EXHAUSTIVE_MAX` cases every
combination is tried, beyond that cases are added greedily.
"""
from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import numpy as np

from ..round import SYSTEMATIC_SOURCES
from ..errors import InputError
from ..track import ANGLE_CHANNELS, NATIVE_CHANNELS
from .case import (ASSUMPTIONS, PLAN_MACH_STEP, PLAN_SOURCES, declared_sources, drag_assumption, plan_case,
                   radar_channels, site_round)

__all__ = ["Plan", "make_plan", "combine", "best_combination", "plan_paragraph", "target_paragraph",
           "EXHAUSTIVE_MAX"]

#: every combination of up to this many cases is tried (2^12 - 1 = 4095 combinations)
EXHAUSTIVE_MAX = 12
#: the rounds a recommendation may ask for before it says the target is out of reach by rounds
ROUNDS_LIMIT = 1000


@dataclass(frozen=True, eq=False)
class Plan:
    """A planned firing: its cases and, with a target, the combination that reaches it.

    Attributes
    ----------
    cases : tuple of CasePlan
    round_name, round_path : str
    drag_source : str
        Where the assumed drag comes from; ``generic`` says it is the generic curve.
    generic : bool
    sigma : dict
        The radar noise sd per channel [m, m/s].
    dt : float, s
    lock_on, loss : float or None, s
    rounds : int
    scatter : float
    declared : dict stem -> sd
        Declared systematic sources.
    target : float or None
        Target relative sd of Cd.
    best : dict or None
        :func:`best_combination`'s answer.
    """

    cases: tuple
    round_name: str
    round_path: str
    drag_source: str
    generic: bool
    sigma: dict
    dt: float
    lock_on: float | None
    loss: float | None
    rounds: int
    scatter: float
    declared: dict
    target: float | None = None
    best: dict | None = None
    radar_sites: tuple | None = None

    @property
    def paragraph(self):
        """The plan in one paragraph (with a target: the recommendation)."""
        if self.target is not None:
            return target_paragraph(self)
        return plan_paragraph(self)

    def to_dict(self):
        """The content of ``plan.json`` (docs/planning.md: ``cases`` with ``elevation``, ``velocity``,
        ``rounds``, ``mach_range``, ``cd`` rows of ``mach`` and ``sd``; more keys beside them; with
        radar sites each case's ``radar`` and the plan's ``radar_sites`` and ``best_site``)."""
        undeclared = [s for s in SYSTEMATIC_SOURCES if s not in self.declared]
        target = None
        if self.target is not None:
            b = self.best or {}
            target = {"relative_sd": self.target, "cases": b.get("cases", []),
                      "mach_range": b.get("mach_range"), "rounds": b.get("rounds"),
                      "paragraph": target_paragraph(self)}
        return {"cases": [_case_dict(c, self.target) for c in self.cases],
                "round": {"name": self.round_name, "path": self.round_path},
                "assumed_drag": {"source": self.drag_source, "generic": self.generic},
                "radar": {"sigma": dict(self.sigma), "dt": self.dt, "lock_on": self.lock_on, "loss": self.loss},
                "rounds": self.rounds, "scatter": self.scatter,
                "systematics": {"declared": dict(self.declared), "undeclared": undeclared},
                "target": target, "summary": plan_paragraph(self), "assumptions": list(ASSUMPTIONS),
                "notes": sorted({n for c in self.cases for n in c.notes}),
                **self._sites()}

    def _sites(self):
        """``radar_sites`` (ranked) and ``best_site`` when candidate sites were planned."""
        if not self.radar_sites:
            return {}
        ranked = site_ranking(self.cases)
        return {"radar_sites": ranked, "best_site": ranked[0] if ranked else None}


def _f(v, digits=6):
    """A float rounded to ``digits`` decimals (None when not finite)."""
    v = float(v)
    return round(v, digits) if math.isfinite(v) else None


def _sig(v, digits=6):
    """A float rounded to ``digits`` significant digits (None when not finite)."""
    v = float(v)
    return float(f"{v:.{digits}g}") if math.isfinite(v) else None


def _case_dict(c, target):
    sd, one = c.sd, c.sd_one_round
    rows = []
    for i, m in enumerate(c.mach):
        rows.append({"mach": float(m), "sd": _sig(sd[i]), "relative_sd": _sig(sd[i] / c.cd[i]),
                     "reference": _sig(c.cd[i]), "sd_one_round": _sig(one[i]), "statistical": _sig(c.statistical[i]),
                     "by_source": {k: _sig(abs(v[i])) for k, v in c.by_source.items()}})
    out = {"elevation": c.elevation_deg, "velocity": c.velocity, "rounds": c.rounds,
           "mach_range": [_f(c.mach_range[0], 4), _f(c.mach_range[1], 4)], "cd": rows, "dt": c.dt,
           "tracked": {"t_start": _f(c.t_tracked[0], 4), "t_end": _f(c.t_tracked[1], 4), "samples": c.samples,
                       "t_impact": _f(c.t_impact, 4)},
           "smoothing": {k: c.smoothing[k] for k in ("sd", "edf", "at_grid_end")}, "drag_model": c.drag_model,
           "best_relative_sd": _sig(np.min(sd / c.cd), 4), "notes": list(c.notes)}
    if c.radar is not None:
        out["radar"] = dict(c.radar)
    if target is not None:
        run = _longest_run(c.mach, sd / c.cd <= target)
        out["target_mach_range"] = None if run is None else [float(c.mach[run[0]]), float(c.mach[run[1]])]
    return out


def make_plan(rnd, elevations, velocities, *, dt, rounds=1, scatter=0.0, target=None, lock_on=None, loss=None,
              assumed_drag=None, seed=0, radar_sites=None):
    """Every elevation x velocity case of a round (x every candidate radar site), and the
    combination that reaches ``target``.

    ``radar_sites``: candidate positions [m] of a radar recording its own channels (the round's
    ``[radar] sigma`` gives ``range, azimuth, elevation, range_rate``); each case is planned from
    each site and ``best_site`` names the site with the smallest median relative sd over the
    cases' Mach grids.

    Returns
    -------
    Plan
    """
    _, source, generic = drag_assumption(rnd, assumed_drag)
    chans, sigma = radar_channels(rnd)
    if radar_sites and not any(c in NATIVE_CHANNELS for c in chans):
        raise InputError(f"{rnd.path or 'round'}: radar sites are planned for a radar's own channels; the round's "
                         f"[radar] sigma gives {', '.join(chans)}: give the sd of range, azimuth, elevation or "
                         f"range_rate")
    rounds_at = [site_round(rnd, p) for p in radar_sites] if radar_sites else [rnd]
    cases = tuple(plan_case(r, e, v, dt=dt, rounds=rounds, scatter=scatter, lock_on=lock_on, loss=loss,
                            assumed_drag=assumed_drag, seed=seed)
                  for r in rounds_at for e in elevations for v in velocities)
    best = best_combination(cases, target) if target is not None else None
    return Plan(cases, rnd.projectile.name, rnd.path, source, generic, sigma, float(dt), lock_on, loss, int(rounds),
                float(scatter), declared_sources(rnd, chans), target, best,
                tuple(tuple(float(v) for v in p) for p in radar_sites) if radar_sites else None)


def site_ranking(cases):
    """Candidate radar sites ranked by the median relative Cd sd of their cases (best first):
    list of ``{"position", "median_relative_sd", "cases"}``; empty without sites."""
    by = {}
    for c in cases:
        if c.radar is None:
            continue
        key = tuple(c.radar["position"])
        by.setdefault(key, []).append(np.median(c.sd / c.cd))
    ranked = sorted(by.items(), key=lambda kv: float(np.mean(kv[1])))
    return [{"position": list(k), "median_relative_sd": _sig(float(np.mean(v)), 4), "cases": len(v)}
            for k, v in ranked]


def _common(cases):
    """The cases on one Mach grid: grid (G,), cd (G,), variances v (n, G) of the statistical
    part with scatter over rounds (inf where a case does not fly), signed shares a (n, S, G)."""
    step = PLAN_MACH_STEP
    lo = min(int(round(c.mach[0] / step)) for c in cases)
    hi = max(int(round(c.mach[-1] / step)) for c in cases)
    grid = np.round(np.arange(lo, hi + 1) * step, 4)
    stems = [s for s in PLAN_SOURCES if any(s in c.by_source for c in cases)]
    n, G = len(cases), grid.size
    v = np.full((n, G), np.inf)
    a = np.zeros((n, len(stems), G))
    cd = np.full(G, np.nan)
    for i, c in enumerate(cases):
        idx = np.round(c.mach / step).astype(int) - lo
        v[i, idx] = (c.statistical ** 2 + (c.scatter * c.cd) ** 2) / c.rounds
        for k, s in enumerate(stems):
            if s in c.by_source:
                a[i, k, idx] = c.by_source[s]
        cd[idx] = c.cd
    return grid, cd, v, a, stems


def combine(cases, members=None):
    """Pooled Cd sd of a combination of cases on their common Mach grid.

    Parameters
    ----------
    cases : sequence of CasePlan
    members : sequence of int, optional
        Indices of the cases fired (default all).

    Returns
    -------
    (grid, cd, sd, systematic)
        Mach (G,), assumed Cd (G,), pooled sd (G,; inf where no member flies) and its
        systematic part (G,).
    """
    grid, cd, v, a, _ = _common(cases)
    return (grid, cd) + _pool(v, a, list(range(len(cases))) if members is None else list(members))


def _pool(v, a, members):
    vi = v[members]
    with np.errstate(divide="ignore"):
        info = np.sum(1.0 / vi, axis=0)
    covered = info > 0
    stat = np.full(vi.shape[1], np.inf)
    stat[covered] = 1.0 / info[covered]
    w = np.where(covered, (1.0 / vi) / np.where(covered, info, 1.0), 0.0)
    sys = np.sum((np.einsum("ig,ikg->kg", w, a[members])) ** 2, axis=0)
    return np.sqrt(stat + sys), np.sqrt(sys)


def _longest_run(mach, ok):
    """(first, last) indices of the longest run of True in ``ok`` (widest in Mach), or None."""
    best, i, n = None, 0, len(ok)
    while i < n:
        if ok[i]:
            j = i
            while j + 1 < n and ok[j + 1]:
                j += 1
            if best is None or mach[j] - mach[i] > mach[best[1]] - mach[best[0]]:
                best = (i, j)
            i = j + 1
        else:
            i += 1
    return best


def best_combination(cases, target):
    """The combination of cases that reaches ``target`` (relative sd) over the widest
    contiguous Mach interval (module docstring for the rules).

    Returns
    -------
    dict
        ``cases`` (indices), ``mach_range`` ([lo, hi] or None), ``width``, ``rounds`` (total),
        ``worst_relative_sd`` inside the interval, ``floor`` (relative systematic sd of all
        cases pooled, its largest source and where), ``rounds_needed`` (rounds per case with
        every case fired that would reach the target over the longest interval the systematic
        floor allows; None when the floor is above the target everywhere).
    """
    grid, cd, v, a, stems = _common(cases)
    n = len(cases)

    def score(members):
        sd, _ = _pool(v, a, list(members))
        rel = sd / cd
        run = _longest_run(grid, rel <= target)
        if run is None:
            # nothing reaches the target: the combination that comes closest
            return (-1.0, -float(np.nanmin(rel)), -len(members), 0.0), None, rel
        width = float(grid[run[1]] - grid[run[0]])
        rounds = sum(cases[i].rounds for i in members)
        return (width, -len(members), -rounds, -float(np.max(rel[run[0]:run[1] + 1]))), run, rel

    if n <= EXHAUSTIVE_MAX:
        candidates = (c for k in range(1, n + 1) for c in itertools.combinations(range(n), k))
        best = max(((score(c), c) for c in candidates), key=lambda t: t[0][0])
    else:
        chosen, best = [], None
        while len(chosen) < n:
            trial = max(((score(chosen + [j]), chosen + [j]) for j in range(n) if j not in chosen),
                        key=lambda t: t[0][0])
            if best is not None and not trial[0][0] > best[0][0]:
                break
            best, chosen = trial, trial[1]
    (key, run, rel), members = best
    members = sorted(members)
    out = {"cases": members, "mach_range": None, "width": 0.0, "rounds": sum(cases[i].rounds for i in members),
           "worst_relative_sd": None, "best_relative_sd": float(np.nanmin(rel))}
    if run is not None:
        out.update(mach_range=[float(grid[run[0]]), float(grid[run[1]])], width=key[0],
                   worst_relative_sd=-key[3])
    out["best_mach"] = float(grid[int(np.nanargmin(rel))])
    out.update(_floor_and_rounds(cases, grid, cd, v, a, stems, target))
    return out


def _floor_and_rounds(cases, grid, cd, v, a, stems, target):
    """What limits the target: the systematic floor of all cases pooled, and how many rounds per
    case (every case fired) the statistical part would need."""
    allm = list(range(len(cases)))
    sd, sys = _pool(v, a, allm)
    flies = np.isfinite(sd)
    floor = sys / cd
    out = {"floor": None, "rounds_needed": None}
    if stems and np.any(flies):
        k = int(np.nanargmax(np.where(flies, floor, -np.inf)))
        vi = v[:, k]
        w = np.where(np.isfinite(vi), (1.0 / vi) / np.sum(1.0 / vi), 0.0)
        shares = {s: abs(float(np.sum(w * a[:, j, k]))) / cd[k] for j, s in enumerate(stems)}
        top = max(shares, key=shares.get)
        out["floor"] = {"relative_sd_max": float(floor[k]), "mach": float(grid[k]), "largest_source": top,
                        "largest_relative_sd": shares[top],
                        "relative_sd_min": float(np.min(floor[flies]))}
    room = (target * cd) ** 2 - sys ** 2
    ok = flies & (room > 0)
    run = _longest_run(grid, ok)
    if run is not None:
        sl = slice(run[0], run[1] + 1)
        stat_var = sd[sl] ** 2 - sys[sl] ** 2
        factor = float(np.max(stat_var / room[sl]))
        per_case = max(c.rounds for c in cases)
        need = int(math.ceil(per_case * factor - 1e-9))
        if need <= ROUNDS_LIMIT:
            out["rounds_needed"] = {"per_case": max(need, 1), "mach_range": [float(grid[run[0]]), float(grid[run[1]])]}
    return out


def _join(names):
    """'a', 'a and b', 'a, b and c'."""
    names = list(names)
    return names[0] if len(names) == 1 else ", ".join(names[:-1]) + " and " + names[-1]


def _planned(n):
    return "the planned case" if n == 1 else f"the {n} planned cases"


def _case_name(c, sites=False):
    """``QE 45° at 818 m/s``, with the radar's site when the plan compares sites."""
    where = f" from {[float(f'{v:g}') for v in c.radar['position']]} m" if sites and c.radar is not None else ""
    return f"QE {c.elevation_deg:g}° at {c.velocity:g} m/s{where}"


def _sigma_text(sigma):
    """The radar's noise in the round file's units: ``range 2 m, azimuth 0.03 deg``."""
    return ", ".join(f"{c} {math.degrees(s):g} deg" if c in ANGLE_CHANNELS else f"{c} {s:g}" for c, s in sigma.items())


def _pct(x):
    return f"{100 * x:.2g} %" if x < 0.01 else f"{100 * x:.2f} %"


def plan_paragraph(plan):
    """The plan in one paragraph, without a target."""
    cs = plan.cases
    parts = []
    for c in cs:
        rel = c.sd / c.cd
        k = int(np.argmin(rel))
        parts.append(f"{_case_name(c, bool(plan.radar_sites))} flies Mach {c.mach_range[0]:.2f}-"
                     f"{c.mach_range[1]:.2f} and reaches {_pct(rel[k])} at Mach {c.mach[k]:.2f} "
                     f"({_pct(rel.max())} at worst)")
    n = f"{plan.rounds} round{'s' if plan.rounds > 1 else ''} per case"
    if plan.scatter > 0:
        n += f" and a round-to-round scatter of Cd of {_pct(plan.scatter)}"
    text = (f"Predicted relative sd of Cd with {n}, radar sigma {_sigma_text(plan.sigma)} every {plan.dt:g} s: "
            + "; ".join(parts) + ".")
    if plan.declared:
        floor = max(float(np.max(c.systematic / c.cd)) for c in cs)
        text += (f" The declared systematic sources ({', '.join(plan.declared)}) contribute up to {_pct(floor)}, "
                 f"shared by all rounds: more rounds do not lower it.")
    else:
        text += " No systematic source is declared: the Cd is conditional on the nominal mass, diameter, air and radar calibration."
    if plan.generic:
        text += (" The round gives no reference drag: the tracks were simulated with a generic 155 mm curve (M101); "
                 "give the shell's expected drag (assumed_drag, --assumed-drag CSV) for a prediction of this shell.")
    return text


def target_paragraph(plan):
    """The recommendation for ``plan.target`` in one paragraph."""
    b, cs, t = plan.best, plan.cases, plan.target
    names = [_case_name(cs[i], bool(plan.radar_sites)) for i in b["cases"]]
    rounds = f"{plan.rounds} round{'s' if plan.rounds > 1 else ''}" + (" each" if len(b["cases"]) > 1 else "")
    if b["mach_range"] is not None:
        lo, hi = b["mach_range"]
        text = (f"Target {100 * t:g} %: firing {_join(names)} ({rounds}) reaches it over Mach {lo:.2f}-{hi:.2f}, "
                f"the widest interval of any combination of {_planned(len(cs))} (worst sd inside it "
                f"{_pct(b['worst_relative_sd'])}).")
        others = [i for i in range(len(cs)) if i not in b["cases"]]
        if others:
            text += f" Adding {_join(_case_name(cs[i], bool(plan.radar_sites)) for i in others)} does not widen it."
    else:
        who = f"no combination of {_planned(len(cs))} reaches" if len(cs) > 1 else "the planned case does not reach"
        text = (f"Target {100 * t:g} %: {who} it anywhere; the closest is {_pct(b['best_relative_sd'])} at Mach "
                f"{b['best_mach']:.2f} with {_join(names)} ({rounds}).")
    fl = b.get("floor")
    if fl is not None:
        lo_hi = sorted({_pct(fl['relative_sd_min']), _pct(fl['relative_sd_max'])}, key=lambda v: float(v.split()[0]))
        text += (f" The shared systematic sources alone give {' to '.join(lo_hi)} "
                 f"(largest: {fl['largest_source']}, {_pct(fl['largest_relative_sd'])}), which no number of rounds lowers.")
    rn = b.get("rounds_needed")
    if rn is not None and (b["mach_range"] is None or rn["mach_range"][1] - rn["mach_range"][0] > b["width"] + 1e-9):
        lo, hi = rn["mach_range"]
        text += (f" With {'every planned case' if len(cs) > 1 else 'this case'} fired, {rn['per_case']} rounds "
                 f"{'each ' if len(cs) > 1 else ''}would reach it over Mach "
                 f"{lo:.2f}-{hi:.2f} (the statistical part falls as 1/sqrt(rounds)).")
    elif rn is None and b["mach_range"] is None:
        text += " More rounds cannot reach it: the systematic floor is above the target wherever the cases fly."
    return text
