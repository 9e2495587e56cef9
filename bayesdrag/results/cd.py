"""The Cd(M) a fit reports, as arrays: :class:`CdTable`.

A table is built from ``result.json``'s ``cd`` rows (:meth:`CdTable.from_rows`), so a table read
back from a written folder equals the one of the fit that wrote it.
"""
from __future__ import annotations

import math
import statistics
from dataclasses import dataclass, fields
from typing import TYPE_CHECKING, Any

import numpy as np

from ..errors import InputError

if TYPE_CHECKING:
    import pandas

__all__ = ["CdTable"]

#: Mach numbers closer than this to the table's ends count as inside it (the grid is rounded to
#: 4 decimals in result.json)
MACH_EDGE_TOL = 1e-9

#: the columns of :meth:`CdTable.to_dataframe`, in order (posterior columns only when sampled)
_ML_COLUMNS = ("mach", "ml", "sd", "determined", "reference", "crb_sd", "statistical_sd")
_POSTERIOR_COLUMNS = ("mean", "q05", "q95")


def _column(rows: list[dict[str, Any]], key: str, fallback: str | None = None) -> np.ndarray:
    """A float column of ``rows`` (None and missing -> NaN; ``fallback`` where ``key`` is absent)."""
    out = np.full(len(rows), np.nan)
    for i, r in enumerate(rows):
        v = r.get(key)
        if v is None and fallback is not None:
            v = r.get(fallback)
        if v is not None:
            out[i] = float(v)
    return out


def _frozen(a: np.ndarray) -> np.ndarray:
    a = np.array(a)
    a.setflags(write=False)
    return a


@dataclass(frozen=True, eq=False, repr=False)
class CdTable:
    """Cd(M) on the fit's Mach grid: the maximum-likelihood curve, the band the fit stands by,
    and the posterior summaries when the fit sampled. Read-only arrays of one length ``M``.

    Attributes
    ----------
    mach : (M,) ndarray
        Mach numbers [-], increasing.
    ml : (M,) ndarray
        Maximum-likelihood Cd [-].
    sd : (M,) ndarray
        The total sd of each row's band [-] (``result.json``'s ``band_sd``: the Cramér-Rao sd
        with the declared sources, or the model-error floor where the residuals show model
        error); what the fit's honesty is judged by.
    determined : (M,) ndarray of bool
        Whether the fit claims Cd at that Mach number (band sd < 1 % of Cd, inside the data,
        not clamped).
    reference : (M,) ndarray
        The round's reference Cd [-]; NaN without a reference drag.
    crb_sd : (M,) ndarray
        Cramér-Rao sd of the ML curve [-] (with the declared sources, white-noise bound).
    statistical_sd : (M,) ndarray
        The statistical part of the Cramér-Rao sd [-] (every declared source held at its value).
    mean, q05, q95 : (M,) ndarray or None
        Posterior mean and 5 % / 95 % quantiles of Cd [-]; None when the fit did not sample.
    """

    mach: np.ndarray
    ml: np.ndarray
    sd: np.ndarray
    determined: np.ndarray
    reference: np.ndarray
    crb_sd: np.ndarray
    statistical_sd: np.ndarray
    mean: np.ndarray | None = None
    q05: np.ndarray | None = None
    q95: np.ndarray | None = None

    def __post_init__(self) -> None:
        n = None
        for f in fields(self):
            v = getattr(self, f.name)
            if v is None:
                continue
            a = np.asarray(v, bool if f.name == "determined" else float)
            if a.ndim != 1 or (n is not None and a.size != n):
                raise ValueError(f"CdTable.{f.name}: shape {a.shape}, expected ({n if n is not None else 'M'},)")
            n = a.size
            object.__setattr__(self, f.name, _frozen(a))

    @classmethod
    def from_rows(cls, rows: list[dict[str, Any]], statistical_sd: np.ndarray | None = None) -> CdTable:
        """The table of ``result.json``'s ``cd`` rows.

        Parameters
        ----------
        rows : list of dict
            Keys ``mach``, ``ml``, ``band_sd``, ``crb_sd``, ``determined``, ``reference`` and,
            when sampled, ``mean``, ``q05``, ``q95``; ``crb_sd_statistical`` when present.
        statistical_sd : (M,) ndarray, optional
            The statistical sd when the rows do not carry it (Scheme 2: from its windows);
            default the rows' ``crb_sd_statistical``, else their ``crb_sd``.
        """
        sampled = bool(rows) and all(r.get("q05") is not None for r in rows)
        stat = (_column(rows, "crb_sd_statistical", fallback="crb_sd") if statistical_sd is None
                else np.asarray(statistical_sd, float))
        post = {k: _column(rows, k) for k in _POSTERIOR_COLUMNS} if sampled else {}
        return cls(mach=_column(rows, "mach"), ml=_column(rows, "ml"), sd=_column(rows, "band_sd", fallback="crb_sd"),
                   determined=np.array([bool(r.get("determined", False)) for r in rows], bool),
                   reference=_column(rows, "reference"), crb_sd=_column(rows, "crb_sd"), statistical_sd=stat, **post)

    # -- what a reader asks ---------------------------------------------------------------------
    def __len__(self) -> int:
        return int(self.mach.size)

    @property
    def sampled(self) -> bool:
        """True when the table holds posterior summaries."""
        return self.q05 is not None

    @property
    def determined_range(self) -> tuple[float, float] | None:
        """``(lowest, highest)`` Mach of the determined rows, None when no row is determined
        (holes inside it are rows with ``determined`` False)."""
        m = self.mach[self.determined]
        return (float(m.min()), float(m.max())) if m.size else None

    def columns(self) -> tuple[str, ...]:
        """The column names of :meth:`to_dataframe`."""
        return _ML_COLUMNS + (_POSTERIOR_COLUMNS if self.sampled else ())

    def to_dataframe(self) -> pandas.DataFrame:
        """The table as a ``pandas.DataFrame``, one row per Mach number (columns
        :meth:`columns`: ``mach, ml, sd, determined, reference, crb_sd, statistical_sd`` and,
        when sampled, ``mean, q05, q95``)."""
        import pandas as pd

        return pd.DataFrame({c: np.array(getattr(self, c)) for c in self.columns()})

    def at(self, mach: float | np.ndarray) -> CdTable:
        """The table at other Mach numbers inside its range, linearly interpolated.

        A row is determined when the rows on both sides of it are.

        Parameters
        ----------
        mach : float or (K,) array_like
            Mach numbers [-] within ``[mach[0], mach[-1]]``.

        Returns
        -------
        CdTable
            K rows (one for a scalar).

        Raises
        ------
        InputError
            A Mach number outside the table (the fit says nothing there; no extrapolation) or
            not finite.
        """
        x = np.atleast_1d(np.asarray(mach, float))
        lo, hi = float(self.mach[0]), float(self.mach[-1])
        bad = x[~np.isfinite(x) | (x < lo - MACH_EDGE_TOL) | (x > hi + MACH_EDGE_TOL)]
        if bad.size:
            raise InputError(f"Mach {bad[0]:g} is outside the table ({lo:.4g} - {hi:.4g}): the fit says nothing "
                             f"there and Cd is not extrapolated; ask for Mach numbers inside that range")
        x = np.clip(x, lo, hi)
        j = np.clip(np.searchsorted(self.mach, x, side="right"), 1, self.mach.size - 1)
        exact = np.isclose(x, self.mach[j - 1], rtol=0.0, atol=MACH_EDGE_TOL)
        det = np.where(exact, self.determined[j - 1], self.determined[j - 1] & self.determined[j])
        kw: dict[str, Any] = {f.name: (None if getattr(self, f.name) is None
                                       else np.interp(x, self.mach, getattr(self, f.name)))
                              for f in fields(self) if f.name not in ("mach", "determined")}
        return CdTable(mach=x, determined=det, **kw)

    # -- a value --------------------------------------------------------------------------------
    def __eq__(self, other: object) -> bool:
        if not isinstance(other, CdTable):
            return NotImplemented
        for f in fields(self):
            a, b = getattr(self, f.name), getattr(other, f.name)
            if (a is None) != (b is None) or (a is not None and not np.array_equal(a, b, equal_nan=True)):
                return False
        return True

    __hash__ = None  # type: ignore[assignment]   # arrays: equal tables need not hash alike

    def __repr__(self) -> str:
        det = self.determined_range
        rng = f"determined {det[0]:.3g}-{det[1]:.3g}" if det else "nowhere determined"
        span = f"Mach {self.mach[0]:.3g}-{self.mach[-1]:.3g}" if len(self) else "empty"
        return (f"CdTable({len(self)} rows, {span}, {rng}"
                + (", with posterior" if self.sampled else "") + ")")

    def rows_at(self, count: int) -> np.ndarray:
        """Indices of ``count`` rows evenly spread over the determined range (the whole table
        when nothing is determined): what a summary shows."""
        det = self.determined_range
        lo, hi = det if det else (float(self.mach[0]), float(self.mach[-1]))
        targets = np.linspace(lo, hi, max(1, count))
        idx = np.unique([int(np.argmin(np.abs(self.mach - t))) for t in targets])
        return idx


def band_z(level: float) -> float:
    """The Gaussian quantile of a central band of probability ``level`` (0.9 -> 1.645)."""
    if not (isinstance(level, (int, float)) and 0.0 < float(level) < 1.0 and math.isfinite(level)):
        raise InputError(f"band level {level!r} is not a probability strictly between 0 and 1 (e.g. 0.9)")
    return float(statistics.NormalDist().inv_cdf(0.5 + float(level) / 2.0))   # stdlib: no scipy.stats import
