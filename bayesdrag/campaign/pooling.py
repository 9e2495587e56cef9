"""Campaign pooling: the population Cd(M) of many rounds of one shell and the round-to-round
scatter.

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
``s`` *is* the relative sd of Cd (``scatter`` in campaign.json), and ``exp(g)`` the population median
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
from dataclasses import dataclass, field

import numpy as np

from .._runtime.renamed import warn_renamed


#: node spacing of the pooled curve [Mach]
NODE_SPACING = 0.05


#: node spacing inside :data:`TRANSONIC_BAND` [Mach] (the drag rise is ~0.1 Mach wide)
NODE_FINE = 0.02


#: Mach band of the drag rise where the nodes are refined
TRANSONIC_BAND = (0.86, 1.20)


#: node spacing of a round whose Mach span holds fewer than two nodes of the other lattices
#: [Mach]: a chronograph shot spans 0.02-0.15 (a pistol bullet's 0.02 held no node at 0.05)
NODE_NARROW = 0.01


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


def mach_nodes(mach_min, mach_max, spacing=NODE_SPACING, fine=NODE_FINE, band=TRANSONIC_BAND, narrow=NODE_NARROW):
    """Campaign Mach nodes inside ``[mach_min, mach_max]``.

    The nodes lie on one fixed lattice (multiples of ``spacing``, plus multiples of ``fine``
    inside ``band``) so that rounds with different Mach spans share nodes where they overlap; a
    span holding fewer than two of them takes the multiples of ``narrow`` instead (a
    chronograph shot), and a span narrower than ``narrow`` may hold none.

    Returns
    -------
    (n,) ndarray of Mach numbers, increasing.
    """
    lo, hi = float(mach_min), float(mach_max)
    coarse = np.arange(math.ceil(lo / spacing - 1e-9), math.floor(hi / spacing + 1e-9) + 1) * spacing
    a, b = max(band[0], lo), min(band[1], hi)
    dense = np.arange(math.ceil(a / fine - 1e-9), math.floor(b / fine + 1e-9) + 1) * fine if a <= b else []
    m = np.unique(np.round(np.concatenate([coarse, dense]), 6))
    m = m[(m >= lo - 1e-9) & (m <= hi + 1e-9)]
    if m.size < 2:      # a narrow span: a finer lattice, still shared by rounds that overlap
        m = np.round(np.arange(math.ceil(lo / narrow - 1e-9), math.floor(hi / narrow + 1e-9) + 1) * narrow, 6)
    return m


def pooling_input(res, drag_model, reference=None, covariance="colored", name=""):
    """What one round's Scheme 1 fit contributes to the campaign.

    Parameters
    ----------
    res : bayesdrag.estimate.model.ml.MLResult
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


#: most Mach nodes a round's pooling input may hold (every 0.02 Mach up to Mach 10 is ~300)
MAX_NODES = 1000


#: largest drag coefficient a pooling input may hold [-]: shells and bullets have Cd 0.1-1, a
#: flat plate ~2; a value above this is not a fitted Cd (a Cd of 1e300 pooled to 9.7e151)
CD_MAX = 5.0


#: longest ``name`` and ``drag_model`` text of a pooling input [characters] (a round's name is a
#: folder name of at most 64)
MAX_TEXT = 64


#: relative agreement of a pooling input with its round's ``result.json`` beyond what the
#: interpolation between the rows allows: both are written from the same fit, as
#: full-precision JSON numbers (round-off only)
RESULT_RTOL = 1e-9


#: the most a curve through ``result.json``'s rows may leave the range of the two rows around a
#: node, in units of the rows' own local bulge (largest second difference near it / 8): a
#: margin of four over what fitted rounds show (docs/measurements.md, "Where the constants come from")
BULGE_FACTOR = 2.0


#: Mach distance a node may lie outside ``result.json``'s rows (their Mach is rounded to 1e-4)
ROW_MACH_TOL = 1e-4


#: most negative eigenvalue of a pooling input's covariance, relative to its trace: a
#: covariance propagated through the spline basis is positive semi-definite to round-off
PSD_RTOL = 1e-9


def check_input(doc):
    """Raise :class:`ValueError` saying why ``doc`` is not a pooling input as :func:`pooling_input`
    writes it: ``name`` and ``drag_model`` text of at most :data:`MAX_TEXT` characters;
    ``mach`` the campaign nodes of ``mach_range`` (:func:`mach_nodes`, at most
    :data:`MAX_NODES`); ``cd`` finite in (0, :data:`CD_MAX`] there; ``cov`` a finite symmetric
    matrix, positive semi-definite (to :data:`PSD_RTOL` of its trace), whose standard
    deviations are at most :data:`CD_MAX` and whose relative covariance plus the floor is
    positive definite (what :func:`pool_rounds` factorises);
    ``cd_crb_sd`` finite in [0, :data:`CD_MAX`]; ``reference`` None or in (0, :data:`CD_MAX`];
    ``covariance`` one of :data:`COVARIANCES`.
    A round's file is read back from its folder, which someone may have edited: a crafted one
    must leave the round out of the pooling, not stop the campaign nor move its Cd."""
    if not isinstance(doc, dict):
        raise ValueError("not a JSON object")
    try:
        lo, hi = (float(v) for v in doc["mach_range"])
        m = np.asarray(doc["mach"], dtype=float)
        cd = np.asarray(doc["cd"], dtype=float)
        cov = np.asarray(doc["cov"], dtype=float)
        crb_sd = np.asarray(doc["cd_crb_sd"], dtype=float)
        ref = None if doc.get("reference") is None else np.asarray(doc["reference"], dtype=float)
    except (KeyError, TypeError, ValueError) as exc:
        raise ValueError(f"missing or not numbers: {type(exc).__name__} {exc}") from None
    if not isinstance(doc.get("name"), str) or doc.get("covariance") not in COVARIANCES \
            or not isinstance(doc.get("drag_model"), str):
        raise ValueError("name, covariance or drag_model missing or not of this version")
    if len(doc["name"]) > MAX_TEXT or len(doc["drag_model"]) > MAX_TEXT:
        raise ValueError(f"name or drag_model is longer than {MAX_TEXT} characters")
    if not (math.isfinite(lo) and math.isfinite(hi) and 0.0 < lo <= hi <= 10.0):
        raise ValueError("mach_range is not an interval of Mach numbers in (0, 10]")
    nodes = mach_nodes(lo, hi)
    if nodes.size == 0:
        raise ValueError(f"its Mach span {lo:.4f}-{hi:.4f} holds no campaign node (multiples of {NODE_NARROW:g}): "
                         f"too narrow to pool")
    if m.ndim != 1 or not 1 <= m.size <= MAX_NODES or m.shape != nodes.shape \
            or not np.allclose(m, nodes, rtol=0.0, atol=1e-6):
        raise ValueError("mach is not the campaign's nodes of its mach_range")
    n = m.size
    if cd.shape != (n,) or not np.all(np.isfinite(cd)) or not np.all(cd > 0.0):
        raise ValueError("cd is not a positive finite value at every node")
    if np.any(cd > CD_MAX):
        i = int(np.argmax(cd))
        raise ValueError(f"cd is {cd[i]:.6g} at Mach {m[i]:.2f}, outside the physical range (0, {CD_MAX:g}] of a "
                         f"drag coefficient")
    if cov.shape != (n, n) or not np.all(np.isfinite(cov)) or not np.allclose(cov, cov.T, rtol=1e-9,
                                                                             atol=1e-12 * float(np.max(np.abs(cov)))):
        raise ValueError("cov is not a finite symmetric matrix of the nodes")
    var = np.diag(cov)
    if np.any(var < 0.0) or np.any(var > CD_MAX ** 2):
        raise ValueError(f"cov has a variance outside [0, {CD_MAX:g}^2] (a Cd standard deviation larger than any "
                         f"drag coefficient)")
    if np.linalg.eigvalsh(cov).min() < -PSD_RTOL * float(np.trace(cov)):
        raise ValueError("cov is not a covariance (not positive semi-definite)")
    if crb_sd.shape != (n,) or not np.all(np.isfinite(crb_sd)) or np.any(crb_sd < 0.0) or np.any(crb_sd > CD_MAX):
        raise ValueError(f"cd_crb_sd is not a value in [0, {CD_MAX:g}] at every node")
    if ref is not None and (ref.shape != (n,) or not np.all(np.isfinite(ref)) or not np.all(ref > 0.0)
                            or np.any(ref > CD_MAX)):
        raise ValueError(f"reference is not a value in (0, {CD_MAX:g}] at every node")
    try:
        np.linalg.cholesky(cov / np.outer(cd, cd) + REL_FLOOR ** 2 * np.eye(n))
    except np.linalg.LinAlgError:
        raise ValueError("cov is not a covariance (not positive semi-definite)") from None


def check_against_result(doc, result):
    """Raise :class:`ValueError` when the pooling input ``doc`` (checked by :func:`check_input`)
    is not what the fit whose ``result.json`` is ``result`` wrote.

    Both files are written from one Scheme 1 fit: the same drag model, the same Mach span, and
    the same Cd curve, ``result.json``'s rows on the fit's grid (every <= 0.01 Mach) and
    ``pooling.json`` on the campaign's nodes, which lie between those rows. At every node the
    Cd and its Cramér-Rao sd must lie within the two rows around it, widened by the rows' own
    local bulge (:data:`BULGE_FACTOR` x the largest second difference of the four rows around
    it / 8: how far a smooth curve can leave the chord between two rows) and by
    :data:`RESULT_RTOL`; the range, not an interpolation, so a curve with a jump (``poly2-split``
    at its split Mach) passes too. The pooled covariance's sd must be the rows'
    ``crb_sd_colored`` (``crb_sd`` for ``covariance = "crb"``) the same way, or below it where
    the rows carry a model-error floor (which only raises them).

    Parameters
    ----------
    doc : dict
        A round's ``pooling.json``.
    result : dict
        The same round's ``result.json``.

    Raises
    ------
    ValueError
        Naming the first disagreement: another drag model or Mach span, rows that are not a Cd
        table of the nodes, or a value at a node outside what the rows allow.
    """
    if not isinstance(result, dict) or result.get("scheme") != 1 or not isinstance(result.get("ml"), dict) \
            or not isinstance(result.get("cd"), list):
        raise ValueError("result.json is not a Scheme 1 result (scheme, ml and cd rows)")
    if result.get("drag_model") != doc["drag_model"]:
        raise ValueError(f"drag model {doc['drag_model']!r} in pooling.json, {result.get('drag_model')!r} in "
                         f"result.json")
    try:
        span = np.asarray(result["ml"]["mach_range_data"], dtype=float)
        rows = result["cd"]
        g = np.array([r["mach"] for r in rows], dtype=float)
        ml = np.array([r["ml"] for r in rows], dtype=float)
        crb = np.array([r["crb_sd"] for r in rows], dtype=float)
        key = "crb_sd_colored" if doc["covariance"] == "colored" else "crb_sd"
        band = np.array([r[key] for r in rows], dtype=float)
    except (KeyError, TypeError, ValueError) as exc:
        raise ValueError(f"result.json's ml.mach_range_data or cd rows are missing or not numbers: "
                         f"{type(exc).__name__} {exc}") from None
    lo, hi = (float(v) for v in doc["mach_range"])
    if span.shape != (2,) or not np.allclose(span, [lo, hi], rtol=RESULT_RTOL, atol=0.0):
        raise ValueError(f"Mach range [{lo:.6g}, {hi:.6g}] in pooling.json, {span.tolist()} in result.json")
    if g.size < 2 or not np.all(np.isfinite(np.concatenate([g, ml, crb, band]))) or np.any(np.diff(g) <= 0.0):
        raise ValueError("result.json's cd rows are not a finite table of increasing Mach")
    m = np.asarray(doc["mach"], dtype=float)
    if m[0] < g[0] - ROW_MACH_TOL or m[-1] > g[-1] + ROW_MACH_TOL:
        raise ValueError(f"the nodes Mach {m[0]:.2f}-{m[-1]:.2f} are not inside result.json's rows "
                         f"(Mach {g[0]:.4f}-{g[-1]:.4f})")
    cov_sd = np.sqrt(np.diag(np.asarray(doc["cov"], dtype=float)))
    floored = any(isinstance(r, dict) and "model_error_floor" in r for r in rows)
    checks = [("Cd", np.asarray(doc["cd"], dtype=float), ml, False),
              ("Cramér-Rao sd of Cd", np.asarray(doc["cd_crb_sd"], dtype=float), crb, False),
              (f"sd of Cd (its cov against the rows' {key})", cov_sd, band, floored)]
    for what, value, table, only_below in checks:
        low, high = _row_range(g, table, m)
        bad = (value > high) if only_below else (value < low) | (value > high)
        if np.any(bad):
            i = int(np.argmax(bad))
            allowed = f"at most {high[i]:.6g}" if only_below else f"{low[i]:.6g} to {high[i]:.6g}"
            raise ValueError(f"{what} at Mach {m[i]:.2f} is {value[i]:.6g} in pooling.json, result.json's rows "
                             f"allow {allowed} there")


def _row_range(g, f, m):
    """The range (low, high) at Mach ``m`` a curve sampled as ``f`` at rows ``g`` can take
    between the rows around each node (:func:`check_against_result`)."""
    j = np.clip(np.searchsorted(g, m, side="right") - 1, 0, g.size - 2)
    a, b = f[j], f[j + 1]
    d2 = np.zeros(g.size)
    if g.size >= 3:
        d2[1:-1] = np.abs(f[2:] - 2.0 * f[1:-1] + f[:-2])
        d2[0], d2[-1] = d2[1], d2[-2]
    near = np.max([d2[np.clip(j + k, 0, g.size - 1)] for k in (-1, 0, 1, 2)], axis=0)
    # a node just outside the rows (their Mach rounded): the end interval's slope carries on
    t = (m - g[j]) / (g[j + 1] - g[j])
    beyond = np.abs(b - a) * np.maximum(np.maximum(-t, t - 1.0), 0.0)
    slack = BULGE_FACTOR * near / 8.0 + beyond + RESULT_RTOL * np.maximum(np.abs(a), np.abs(b))
    return np.minimum(a, b) - slack, np.maximum(a, b) + slack


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

    def scatter_record(self, band=BAND):
        """``campaign.json`` ``scatter``: mean, q05, q95 (and median) of ``s``. One round shows no
        round-to-round scatter (its posterior is its prior): the values are then NaN (null in
        campaign.json) and ``note`` says why."""
        if len(self.names) < 2:
            nan = float("nan")
            return {"mean": nan, "q05": nan, "median": nan, "q95": nan,
                    "note": "one round: no round-to-round scatter can be seen (the draws are the prior's)"}
        s = self.scatter_draws
        q = np.quantile(s, [band[0], 0.5, band[1]])
        return {"mean": float(s.mean()), "q05": float(q[0]), "median": float(q[1]), "q95": float(q[2])}

    def delta_records(self, band=BAND):
        """Per round: mean, q05, q95 of ``delta_r`` (relative offset of its Cd)."""
        q = np.quantile(self.delta_draws, band, axis=0)
        m = self.delta_draws.mean(axis=0)
        return [{"name": n, "mean": float(m[i]), "q05": float(q[0, i]), "q95": float(q[1, i])}
                for i, n in enumerate(self.names)]

    def scatter_summary(self, band=BAND):
        """Deprecated name of :meth:`scatter_record` (removed in release 0.3)."""
        warn_renamed("PooledResult.scatter_summary", "scatter_record")
        return self.scatter_record(band)

    def delta_summary(self, band=BAND):
        """Deprecated name of :meth:`delta_records` (removed in release 0.3)."""
        warn_renamed("PooledResult.delta_summary", "delta_records")
        return self.delta_records(band)


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
    # 1-D target: the stretch move mixes slowly in one dimension, the differential-evolution
    # move with a snooker share faster
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
    """The ``campaign.json`` document (keys: ``name``, ``rounds``, ``cd``, ``scatter``, and ``deltas``, ``sampler``,
    ``model``, ``failed``, ``rounds_detail``)."""
    doc = {"name": campaign_name, "rounds": list(pooled.names), "cd": pooled.cd_rows(),
           "scatter": pooled.scatter_record(), "deltas": pooled.delta_records(),
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
