"""Campaigns: many rounds of one shell, their pooled (population) Cd(M) and the round-to-round
scatter (DESIGN.md "Campaigns").

A campaign TOML lists rounds (paths relative to the campaign file)::

    [campaign]
    name = "130 mm cargo shell, trial 5"

    [[rounds]]
    name = "r1"          # folder name of the round's outputs: letters, digits, '.', '_', '-'
    track = "r1.csv"
    round = "r1.toml"

Pooling model (decided here, written down)
------------------------------------------
Two stages. **Stage 1** is each round's own Scheme 1 fit (maximum likelihood with the
Cramér-Rao covariance, by default the colored-residual-corrected one, see :data:`COVARIANCES`).
From it we keep Cd on the campaign's Mach *nodes* (:func:`mach_nodes`: every
:data:`NODE_SPACING` Mach, every :data:`NODE_FINE` inside the transonic band) that fall inside
the round's Mach span, and the covariance of those values (delta method through the spline
basis) — a few kB per round (:func:`pooling_input`).

**Stage 2** is the hierarchical model on the logarithm of Cd::

    y_r = log Cd_r(nodes_r) ~ N(g(nodes_r) + e_r 1, C_r),   e_r ~ N(0, s^2),   e_r = log(1 + delta_r)

``g = log Cd_pop`` is the campaign (population) curve at the nodes with a flat prior, ``e_r``
the relative offset of round ``r`` (its Cd is ``Cd_pop (1 + delta_r)``: lot, fuze and
form-factor differences scale the whole curve), ``s`` the round-to-round relative sd with a
weak half-normal prior of scale :data:`SCATTER_PRIOR_SD` (5 %), and ``C_r`` the round's
stage-1 covariance of ``log Cd`` (``cov / (Cd Cd^T)``) plus an independent relative floor
:data:`REL_FLOOR` per node (the spline representation error; it also keeps ``C_r``
invertible, because a penalised spline's values on close nodes are almost perfectly
correlated). The log makes the model linear-Gaussian in ``g`` given ``s``: ``e_r`` and ``g``
integrate out in closed form (Sherman-Morrison per round), leaving the exact marginal posterior
of ``s``, which emcee samples (1-D, in ``log s``); ``g | s`` is then Gaussian and is drawn
exactly, and ``e_r | s, g`` too. So the posterior of ``(g, s, e)`` is exact for this model, not a
long high-dimensional chain to babysit. ``log(1 + delta) = delta`` to 5e-5 at 1 % scatter, so
``s`` *is* the relative sd of Cd (DESIGN.md ``scatter``), and ``exp(g)`` the population median
curve (its mean is larger by ``s^2/2``, 5e-5 at 1 %).

Why nodes and not a population spline: every round's curve is already a smooth spline, the
nodes carry no interpolation error at the printed Mach values, and the conditional of ``g`` is
exact. The pooled ``cd`` rows of ``campaign.json`` are at the nodes; figures draw lines between
them.

What it does *not* model: stage 1 uses each round's smoothness prior once per round (mild
double use of the prior when pooling); Mach-dependent round differences beyond a common
factor show up as rounds whose relative deviation is not flat (figure ``campaign_relative.png``).
"""
from __future__ import annotations

import math
import re
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .errors import InputError

#: node spacing of the pooled curve [Mach]
NODE_SPACING = 0.05
#: node spacing inside :data:`TRANSONIC_BAND` [Mach] (the drag rise is ~0.1 Mach wide)
NODE_FINE = 0.02
#: Mach band of the drag rise where the nodes are refined
TRANSONIC_BAND = (0.86, 1.20)
#: relative sd floor added independently at every node of a round (representation error of
#: the round's spline and conditioning of its covariance)
REL_FLOOR = 5e-4
#: scale of the half-normal prior of the round-to-round relative sd ``s`` (weak: 5 %)
SCATTER_PRIOR_SD = 0.05
#: which stage-1 covariance is pooled: "colored" (Morelli-Klein corrected, the default: honest
#: when residuals are correlated, equal to the CRB within its noise when they are white) or "crb"
COVARIANCES = ("colored", "crb")
#: credible band of the campaign outputs
BAND = (0.05, 0.95)

_NAME_RE = re.compile(r"^[A-Za-z0-9][A-Za-z0-9._-]{0,63}$")
_CAMPAIGN_KEYS = ("name", "description")
_ROUND_KEYS = ("name", "track", "round")


# ----------------------------------------------------------------------------------------------
# campaign file
@dataclass(frozen=True)
class CampaignRound:
    """One round of a campaign: its name (output folder) and resolved input paths."""

    name: str
    track: Path
    round: Path


@dataclass(frozen=True)
class Campaign:
    """A campaign file: ``name`` and the ``rounds`` in file order; ``path`` the TOML file."""

    name: str
    rounds: tuple
    path: Path
    description: str = ""

    @property
    def names(self):
        return [r.name for r in self.rounds]


def is_campaign_file(path):
    """True if ``path`` is a TOML file with a ``[campaign]`` table or ``[[rounds]]`` array (so
    ``bayesdrag fit`` treats it as a campaign rather than a track)."""
    p = Path(path)
    if p.suffix.lower() != ".toml" or not p.is_file():
        return False
    try:
        doc = tomllib.loads(p.read_text(encoding="utf-8"))
    except (tomllib.TOMLDecodeError, UnicodeDecodeError, OSError):
        return False
    return "campaign" in doc or "rounds" in doc


def read_campaign(path):
    """Read and validate a campaign TOML.

    Parameters
    ----------
    path : str or os.PathLike

    Returns
    -------
    Campaign

    Raises
    ------
    InputError
        Naming the file and the key: unreadable TOML, unknown keys, a round without ``track``
        or ``round``, a name that is not a safe folder name, duplicate names, missing files,
        fewer than one round.
    """
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise InputError(f"{path}: campaign file not found") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"{path}: cannot read the campaign file ({exc})") from None
    try:
        doc = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise InputError(f"{path}: not valid TOML ({exc})") from None
    unknown = [k for k in doc if k not in ("campaign", "rounds")]
    if unknown:
        raise InputError(f"{path}: unknown top-level key {unknown[0]!r}; allowed: [campaign], [[rounds]]")
    camp = doc.get("campaign", {})
    if not isinstance(camp, dict):
        raise InputError(f"{path}: [campaign] must be a table with name = \"...\"")
    bad = [k for k in camp if k not in _CAMPAIGN_KEYS]
    if bad:
        raise InputError(f"{path}: unknown key campaign.{bad[0]}; allowed: {', '.join(_CAMPAIGN_KEYS)}")
    name = camp.get("name", path.stem)
    if not isinstance(name, str):
        raise InputError(f"{path}: campaign.name must be text, got {type(name).__name__}")
    rounds = doc.get("rounds")
    if not isinstance(rounds, list) or not rounds:
        raise InputError(f"{path}: a campaign needs at least one [[rounds]] entry with name, track and round")
    out, seen = [], set()
    for i, r in enumerate(rounds, 1):
        where = f"{path}: rounds entry {i}"
        if not isinstance(r, dict):
            raise InputError(f"{where}: must be a table with name, track and round")
        bad = [k for k in r if k not in _ROUND_KEYS]
        if bad:
            raise InputError(f"{where}: unknown key {bad[0]!r}; allowed: {', '.join(_ROUND_KEYS)}")
        for k in ("track", "round"):
            if k not in r:
                raise InputError(f"{where}: missing key {k!r} (a path relative to the campaign file)")
            if not isinstance(r[k], str) or not r[k]:
                raise InputError(f"{where}: {k} must be a non-empty path, got {r[k]!r}")
        nm = r.get("name", Path(r["track"]).stem)
        if not isinstance(nm, str) or not _NAME_RE.match(nm):
            raise InputError(f"{where}: name {nm!r} is not allowed; use 1-64 letters, digits, '.', '_', '-' "
                             f"(it names the output folder)")
        if nm in seen:
            raise InputError(f"{where}: duplicate round name {nm!r}; names must be unique")
        seen.add(nm)
        files = {}
        for k in ("track", "round"):
            p = (path.parent / r[k]).resolve() if not Path(r[k]).is_absolute() else Path(r[k])
            if not p.is_file():
                raise InputError(f"{where} ({nm}): {k} file {r[k]!r} not found (looked at {p})")
            files[k] = p
        out.append(CampaignRound(nm, files["track"], files["round"]))
    return Campaign(name, tuple(out), path.resolve(), str(camp.get("description", "")))


def write_campaign(path, name, rounds):
    """Write a campaign TOML. ``rounds``: iterable of (name, track path, round path); paths are
    written relative to the campaign file's folder when possible."""
    import os

    path = Path(path)
    lines = [f"[campaign]\nname = {_toml_str(name)}\n"]
    for nm, tr, ro in rounds:
        rel = [Path(os.path.relpath(Path(p).resolve(), path.resolve().parent)).as_posix() for p in (tr, ro)]
        lines.append(f"\n[[rounds]]\nname = {_toml_str(nm)}\ntrack = {_toml_str(rel[0])}\n"
                     f"round = {_toml_str(rel[1])}\n")
    path.write_text("".join(lines), encoding="utf-8")
    return path


def _toml_str(s):
    return '"' + str(s).replace("\\", "\\\\").replace('"', '\\"') + '"'


# ----------------------------------------------------------------------------------------------
# stage 1: what a round contributes
def mach_nodes(mach_min, mach_max, spacing=NODE_SPACING, fine=NODE_FINE, band=TRANSONIC_BAND):
    """Campaign Mach nodes inside ``[mach_min, mach_max]``.

    The nodes lie on one fixed lattice (multiples of ``spacing``, plus multiples of ``fine``
    inside ``band``) so that rounds with different Mach spans share nodes where they overlap.

    Returns
    -------
    (n,) ndarray of Mach numbers, increasing.
    """
    lo, hi = float(mach_min), float(mach_max)
    coarse = np.arange(math.ceil(lo / spacing - 1e-9), math.floor(hi / spacing + 1e-9) + 1) * spacing
    a, b = max(band[0], lo), min(band[1], hi)
    dense = np.arange(math.ceil(a / fine - 1e-9), math.floor(b / fine + 1e-9) + 1) * fine if a <= b else []
    m = np.unique(np.round(np.concatenate([coarse, dense]), 6))
    return m[(m >= lo - 1e-9) & (m <= hi + 1e-9)]


def pooling_input(res, drag_model, reference=None, covariance="colored", name=""):
    """What one round's Scheme 1 fit contributes to the campaign.

    Parameters
    ----------
    res : bayesdrag.estimate.ml.MLResult
    drag_model : bayesdrag.drag.DragModel
        The model of the fit (``prob.model.drag``).
    reference : ReferenceTable, optional
    covariance : {"colored", "crb"}
        Which covariance of the drag parameters to propagate.
    name : str

    Returns
    -------
    dict
        ``name``, ``mach`` (n,) nodes inside the fit's Mach span, ``cd`` (n,) ML values,
        ``cov`` (n, n) their covariance, ``cd_crb_sd`` (n,), ``reference`` (n,) or None,
        ``mach_range`` [lo, hi], ``covariance``, ``drag_model``; JSON-ready (lists).
    """
    if covariance not in COVARIANCES:
        raise ValueError(f"covariance must be one of {COVARIANCES}, got {covariance!r}")
    lo, hi = float(np.min(res.mach)), float(np.max(res.mach))
    m = mach_nodes(lo, hi)
    P = drag_model.n_params
    B = drag_model.jacobian(m)
    cov_p = (res.cov_colored if covariance == "colored" else res.cov)[:P, :P]
    cov = B @ cov_p @ B.T
    cov = 0.5 * (cov + cov.T)
    cd = np.asarray(drag_model.cd(res.drag_params, m), float)
    return {"name": name, "mach": m.tolist(), "cd": cd.tolist(), "cov": cov.tolist(),
            "cd_crb_sd": np.sqrt(np.clip(np.diag(B @ res.cov[:P, :P] @ B.T), 0, None)).tolist(),
            "reference": None if reference is None else [float(v) for v in reference.value(m)],
            "mach_range": [lo, hi], "covariance": covariance, "drag_model": drag_model.name}


# ----------------------------------------------------------------------------------------------
# stage 2: the hierarchical model
class _Stage2:
    """Precomputed pieces of the log-space model: per round the node indices, ``y``,
    ``C^-1``, ``log|C|``, ``C^-1 1`` and ``1' C^-1 1``."""

    def __init__(self, inputs, rel_floor):
        allm = np.unique(np.round(np.concatenate([np.asarray(r["mach"], float) for r in inputs]), 6))
        self.mach = allm
        self.rounds = []
        for r in inputs:
            m = np.round(np.asarray(r["mach"], float), 6)
            cd = np.asarray(r["cd"], float)
            if np.any(cd <= 0) or not np.all(np.isfinite(cd)):
                raise ValueError(f"round {r.get('name')}: Cd must be positive and finite at the nodes")
            cov = np.asarray(r["cov"], float)
            C = cov / np.outer(cd, cd) + rel_floor ** 2 * np.eye(len(cd))
            L = np.linalg.cholesky(C)
            Ci = np.linalg.inv(C)
            Ci = 0.5 * (Ci + Ci.T)
            one = np.ones(len(cd))
            Ci1 = Ci @ one
            self.rounds.append({"idx": np.searchsorted(allm, m), "y": np.log(cd), "Ci": Ci,
                                "logdet": 2.0 * float(np.sum(np.log(np.diag(L)))), "Ci1": Ci1,
                                "q": float(one @ Ci1)})

        # s-independent parts: H(s) = H0 - U diag(k) U', b(s) = b0 - U diag(k) w with
        # k_r = s^2 / (1 + s^2 q_r), U[:, r] = A_r' C_r^-1 1, w_r = 1' C_r^-1 y_r
        n, R = allm.size, len(self.rounds)
        self.H0 = np.zeros((n, n))
        self.b0 = np.zeros(n)
        self.U = np.zeros((n, R))
        self.w = np.zeros(R)
        self.q = np.array([r["q"] for r in self.rounds])
        self.quad0 = self.logdet0 = 0.0
        for j, r in enumerate(self.rounds):
            idx = r["idx"]
            self.H0[np.ix_(idx, idx)] += r["Ci"]
            self.b0[idx] += r["Ci"] @ r["y"]
            self.U[idx, j] = r["Ci1"]
            self.w[j] = float(r["Ci1"] @ r["y"])
            self.quad0 += float(r["y"] @ r["Ci"] @ r["y"])
            self.logdet0 += r["logdet"]

    def conditional(self, s, want_mean=True):
        """Batched over ``s`` (B,): log marginal likelihood of s with g integrated out under a
        flat prior (B,), and chol(H) (B, n, n), H^-1 b (B, n) where g | s, y ~ N(H^-1 b, H^-1).
        Sherman-Morrison per round: (C + s^2 11')^-1 = C^-1 - k C^-1 11' C^-1 with
        k = s^2 / (1 + s^2 q), |C + s^2 11'| = |C| (1 + s^2 q)."""
        s2 = np.atleast_1d(np.asarray(s, float)) ** 2
        k = s2[:, None] / (1.0 + s2[:, None] * self.q[None, :])            # (B, R)
        H = self.H0[None] - (self.U[None] * k[:, None, :]) @ self.U.T
        bv = self.b0[None] - (k * self.w[None]) @ self.U.T                   # (B, n)
        quad = self.quad0 - np.sum(k * self.w ** 2, axis=1)
        logdet = self.logdet0 + np.sum(np.log1p(s2[:, None] * self.q[None]), axis=1)
        Lh = np.linalg.cholesky(H)
        z = np.linalg.solve(Lh, bv[..., None])[..., 0]
        ll = -0.5 * (logdet + quad - np.sum(z * z, axis=1)) - np.sum(np.log(np.diagonal(Lh, axis1=1, axis2=2)), axis=1)
        if not want_mean:
            return ll, Lh, None
        mean = np.linalg.solve(np.swapaxes(Lh, 1, 2), z[..., None])[..., 0]
        return ll, Lh, mean

    def log_post_log_s(self, log_s, prior_sd):
        """Log posterior density of ``log s`` (B,) (half-normal prior on s, Jacobian included)."""
        x = np.atleast_1d(np.asarray(log_s, float))
        out = np.full(x.shape, -np.inf)
        ok = (x > -20.0) & (x < 2.0)
        if np.any(ok):
            s = np.exp(x[ok])
            out[ok] = self.conditional(s, want_mean=False)[0] - 0.5 * (s / prior_sd) ** 2 + x[ok]
        return out


@dataclass(frozen=True, eq=False)
class PooledResult:
    """The campaign posterior.

    Attributes
    ----------
    names : tuple of str
        Rounds pooled, in input order.
    mach : (n,) ndarray
        Campaign nodes [Mach].
    cd_draws : (D, n) ndarray
        Draws of the population Cd at the nodes.
    scatter_draws : (D,) ndarray
        Draws of the round-to-round relative sd ``s``.
    delta_draws : (D, R) ndarray
        Draws of each round's relative offset ``delta_r``.
    reference : (n,) ndarray or None
    coverage : (n,) int ndarray
        How many rounds cover each node.
    success : bool
    message : str
    sampler : dict
        emcee diagnostics of the ``log s`` chain: walkers, steps, burn, acceptance, tau, draws.
    """

    names: tuple
    mach: np.ndarray
    cd_draws: np.ndarray
    scatter_draws: np.ndarray
    delta_draws: np.ndarray
    reference: np.ndarray | None
    coverage: np.ndarray
    success: bool
    message: str
    sampler: dict = field(default_factory=dict)

    def cd_rows(self, band=BAND):
        """``campaign.json`` ``cd`` rows: mach, mean, q05, q95, reference, sd, n_rounds."""
        q = np.quantile(self.cd_draws, band, axis=0)
        mean = self.cd_draws.mean(axis=0)
        sd = self.cd_draws.std(axis=0, ddof=1)
        return [{"mach": round(float(m), 4), "mean": float(mean[i]), "q05": float(q[0, i]),
                 "q95": float(q[1, i]), "sd": float(sd[i]), "n_rounds": int(self.coverage[i]),
                 "reference": None if self.reference is None else float(self.reference[i])}
                for i, m in enumerate(self.mach)]

    def scatter_summary(self, band=BAND):
        """``campaign.json`` ``scatter``: mean, q05, q95 (and median) of ``s``."""
        s = self.scatter_draws
        q = np.quantile(s, [band[0], 0.5, band[1]])
        return {"mean": float(s.mean()), "q05": float(q[0]), "median": float(q[1]), "q95": float(q[2])}

    def delta_summary(self, band=BAND):
        """Per round: mean, q05, q95 of ``delta_r`` (relative offset of its Cd)."""
        q = np.quantile(self.delta_draws, band, axis=0)
        m = self.delta_draws.mean(axis=0)
        return [{"name": n, "mean": float(m[i]), "q05": float(q[0, i]), "q95": float(q[1, i])}
                for i, n in enumerate(self.names)]


def pool_rounds(inputs, rng=None, n_draws=4000, nwalkers=16, n_steps=600, prior_sd=SCATTER_PRIOR_SD,
                rel_floor=REL_FLOOR):
    """Pool rounds into the campaign Cd(M) and the round-to-round scatter (module docstring).

    Parameters
    ----------
    inputs : list of dict
        :func:`pooling_input` of each round (>= 2 rounds with overlapping Mach spans for a
        scatter estimate; with one round the scatter is its prior).
    rng : numpy.random.Generator, optional
        Seeds emcee and the conditional draws (default ``default_rng(0)``: reproducible).
    n_draws : int
        Posterior draws returned.
    nwalkers, n_steps : int
        emcee ensemble for ``log s``; the chain is checked with the integrated autocorrelation
        time (``success`` is False when it is longer than ``n_steps / 50``).
    prior_sd : float
        Scale of the half-normal prior on ``s``.
    rel_floor : float
        Relative sd floor per node (:data:`REL_FLOOR`).

    Returns
    -------
    PooledResult
    """
    import emcee

    if not inputs:
        raise ValueError("pool_rounds needs at least one round")
    rng = np.random.default_rng(0) if rng is None else rng
    st = _Stage2(inputs, rel_floor)
    n = st.mach.size
    cover = np.zeros(n, int)
    for r in st.rounds:
        cover[r["idx"]] += 1
    # --- log s by emcee (1-D), started around the mode found on a coarse grid
    grid = np.linspace(math.log(1e-4), math.log(0.5), 60)
    x0 = grid[int(np.argmax(st.log_post_log_s(grid, prior_sd)))]
    p0 = x0 + 0.1 * rng.standard_normal((nwalkers, 1))
    # 1-D target: the stretch move mixes slowly in one dimension (tau ~ 20 steps measured); the
    # differential-evolution move with a snooker share mixes in ~5 steps
    moves = [(emcee.moves.DEMove(), 0.8), (emcee.moves.DESnookerMove(), 0.2)]
    sampler = emcee.EnsembleSampler(nwalkers, 1, lambda x: st.log_post_log_s(x[:, 0], prior_sd),
                                    moves=moves, vectorize=True)
    # emcee keeps its own RandomState; seed it from rng so the chain is reproducible
    sampler.random_state = np.random.RandomState(int(rng.integers(2**31))).get_state()
    sampler.run_mcmc(p0, n_steps, progress=False)
    tau = float(np.max(sampler.get_autocorr_time(quiet=True)))
    burn = int(min(max(5 * tau, 100), n_steps // 2))
    chain = sampler.get_chain(discard=burn, flat=True)[:, 0]
    ok = bool(np.isfinite(tau) and tau < n_steps / 50)
    take = rng.choice(chain.size, size=n_draws, replace=chain.size < n_draws)
    s_draws = np.exp(chain[take])
    # --- g | s and e_r | s, g, exactly (in blocks to bound memory)
    g_draws = np.empty((n_draws, n))
    for a0 in range(0, n_draws, 500):
        sl = slice(a0, min(a0 + 500, n_draws))
        _, Lh, mean = st.conditional(s_draws[sl])
        zz = rng.standard_normal((sl.stop - sl.start, n, 1))
        g_draws[sl] = mean + np.linalg.solve(np.swapaxes(Lh, 1, 2), zz)[..., 0]
    e_draws = np.empty((n_draws, len(st.rounds)))
    for j, r in enumerate(st.rounds):
        resid = r["y"][None, :] - g_draws[:, r["idx"]]
        prec = 1.0 / s_draws ** 2 + r["q"]
        e_draws[:, j] = (resid @ r["Ci1"]) / prec + rng.standard_normal(n_draws) / np.sqrt(prec)
    ref = _pooled_reference(inputs, st.mach)
    info = {"walkers": nwalkers, "steps": n_steps, "burn": burn, "tau": tau,
            "acceptance": float(np.mean(sampler.acceptance_fraction)), "draws": n_draws,
            "prior": f"s ~ half-normal(scale {prior_sd:g}); flat prior on log Cd_pop at the nodes",
            "rel_floor": rel_floor}
    msg = (f"pooled {len(inputs)} rounds on {n} Mach nodes; log-s chain tau = {tau:.1f} steps"
           + ("" if ok else f" (longer than {n_steps // 50}: chain too short)"))
    return PooledResult(tuple(r.get("name", f"r{i + 1}") for i, r in enumerate(inputs)), st.mach,
                        np.exp(g_draws), s_draws, np.expm1(e_draws), ref, cover, ok, msg, info)


def scatter_log_posterior(inputs, s, prior_sd=SCATTER_PRIOR_SD, rel_floor=REL_FLOOR):
    """Unnormalised log posterior density of ``s`` (not ``log s``) on an array of values; for
    checking the sampler against quadrature."""
    st = _Stage2(inputs, rel_floor)
    s = np.atleast_1d(np.asarray(s, float))
    return st.conditional(s)[0] - 0.5 * (s / prior_sd) ** 2


def _pooled_reference(inputs, mach):
    vals = np.full(mach.size, np.nan)
    for r in inputs:
        if r.get("reference") is None:
            continue
        idx = np.searchsorted(mach, np.round(np.asarray(r["mach"], float), 6))
        vals[idx] = np.where(np.isnan(vals[idx]), r["reference"], vals[idx])
    return None if np.all(np.isnan(vals)) else vals


def campaign_json(pooled, inputs=None, campaign_name="", failed=()):
    """The ``campaign.json`` document (DESIGN.md keys plus extensions: ``deltas``, ``sampler``,
    ``model``, ``failed``, ``rounds_detail``)."""
    doc = {"name": campaign_name, "rounds": list(pooled.names), "cd": pooled.cd_rows(),
           "scatter": pooled.scatter_summary(), "deltas": pooled.delta_summary(),
           "success": pooled.success, "message": pooled.message, "sampler": pooled.sampler,
           "model": "log Cd_r = log Cd_pop + log(1 + delta_r), delta_r ~ N(0, scatter^2); "
                    "stage-1 covariance per round (" + (inputs[0]["covariance"] if inputs else "?") + ")",
           "failed": [dict(f) for f in failed]}
    if inputs:
        doc["rounds_detail"] = [{"name": r["name"], "mach_range": r["mach_range"], "drag_model": r["drag_model"],
                                 "nodes": len(r["mach"])} for r in inputs]
    return _clean(doc)


def _clean(o):
    if isinstance(o, dict):
        return {str(k): _clean(v) for k, v in o.items()}
    if isinstance(o, (list, tuple)):
        return [_clean(v) for v in o]
    if isinstance(o, (float, np.floating)):
        return float(o) if np.isfinite(o) else None
    if isinstance(o, np.integer):
        return int(o)
    if isinstance(o, np.bool_):
        return bool(o)
    return o


# ----------------------------------------------------------------------------------------------
# simulated campaigns (tests, benchmark, tutorial)
def simulate_campaign(directory, n_rounds=7, scatter=0.01, rng=None, velocities=(790.0, 840.0),
                      elevations=(12.0, 20.0), dt=0.054, sigma=None, reference=None, mass=42.6,
                      diameter=0.155, name="simulated campaign"):
    """Write a simulated campaign: rounds whose Cd is ``reference * (1 + delta_r)`` with
    ``delta_r ~ N(0, scatter^2)``, launch speed and elevation spread over the given ranges
    (so the rounds cover different Mach spans), point-mass tracks with Gaussian noise.

    Parameters
    ----------
    directory : path
        Created if needed; receives ``campaign.toml``, ``reference.csv`` and per round
        ``<name>.toml``, ``<name>.csv``.
    n_rounds : int
    scatter : float
        Round-to-round relative sd of Cd.
    rng : numpy.random.Generator
    velocities, elevations : (lo, hi)
        Launch speed [m/s] and quadrant elevation [deg] ranges (evenly spread, shuffled).
    dt : float, s
        Radar sample interval.
    sigma : dict, optional
        Noise sd per channel (default x, y, z 1 m, v 0.3 m/s).
    reference : ReferenceTable, optional
        Campaign truth (default the 155 mm M101 table shipped in the package).

    Returns
    -------
    (Path, dict)
        The campaign file and the truth: ``deltas`` (list), ``scatter``, ``reference``.
    """
    from .drag import ReferenceTable
    from .io.drag_tables import load_m101
    from .simulate import add_noise, simulate_round
    from .round import Launch, Projectile, Radar, Round
    from .io.rounds import write_round
    from .io.tracks import write_track

    rng = np.random.default_rng() if rng is None else rng
    d = Path(directory)
    d.mkdir(parents=True, exist_ok=True)
    ref = load_m101() if reference is None else reference
    sigma = dict(sigma or {"x": 1.0, "y": 1.0, "z": 1.0, "v": 0.3})
    ref_path = d / "reference.csv"
    ref_path.write_text("# campaign truth: population Cd(M)\nmach,cd\n"
                        + "".join(f"{m:.6g},{c:.8g}\n" for m, c in zip(ref.mach, ref.cd_values)), encoding="utf-8")
    deltas = scatter * rng.standard_normal(n_rounds)
    vel = np.linspace(*velocities, n_rounds)[rng.permutation(n_rounds)]
    el = np.linspace(*elevations, n_rounds)[rng.permutation(n_rounds)]
    rows = []
    for i in range(n_rounds):
        nm = f"r{i + 1}"
        table = ReferenceTable(ref.mach, tuple(np.asarray(ref.cd_values) * (1.0 + deltas[i])), source=f"{nm} truth")
        launch = Launch(elevation_deg=float(round(el[i], 3)), velocity=float(round(vel[i], 2)), azimuth_deg=90.0)
        proj = Projectile("simulated shell", mass, diameter, reference_drag=table)
        truth_round = Round(proj, launch, radar=Radar(sigma))
        track = add_noise(simulate_round(truth_round, dt=dt), sigma, rng)
        file_round = Round(Projectile("simulated shell", mass, diameter, reference_drag=ref,
                                      reference_drag_path=str(ref_path)), launch, radar=Radar(sigma))
        write_round(d / f"{nm}.toml", file_round, comment=f"{name}: round {nm} (truth delta = {deltas[i]:+.5f})")
        write_track(d / f"{nm}.csv", track, comment=f"{name}: round {nm}, simulated point mass, noise {sigma}")
        rows.append((nm, d / f"{nm}.csv", d / f"{nm}.toml"))
    path = write_campaign(d / "campaign.toml", name, rows)
    return path, {"deltas": deltas.tolist(), "scatter": scatter, "reference": ref}
