"""What bayesdrag claims about Cd, row by row: each band term named, and a row's ``band_sd`` and
``determined`` made in one function (:func:`claimed`).

A ``cd`` row's columns -- Mach, the estimate ``ml``, the Cramér-Rao sd ``crb_sd`` and its colored
form, the AR(1) noise's own sd, the reference -- are read off the fit
(:func:`~bayesdrag.estimate.cd.table.cd_table`) and not changed after. Its band is made of named
terms, each reported under one key of ``uncertainty_budget.by_source`` (:data:`BAND_TERMS`):

* **the data's band** (:class:`DataBand`, made by the quality gate,
  :func:`~bayesdrag.estimate.cd.quality.assess`): the Cramér-Rao sd, its colored form where the
  residuals are correlated (raised to the white fit's where an AR(1) noise model was fitted:
  the floor), the AR(1) noise's own sd, a short track's unresolved bend, an origin's air. The
  declared sources' share of it is held out of the judgement (a systematic the user states is
  no failure of the data);
* **model error** (``model_error_sd``: its terms added in squares by :func:`set_model_error` and
  :func:`add_model_error`, the only writers): the shift of the effects the check fits, of the
  noise model's check, of a close alternative explanation, of a shape the data cannot tell from a
  yaw, what an effect's fit leaves, the wind layers' placements, a narrow span's shape.

A row is **determined** when the judged band (the data's band less the declared sources, with
the model error) is below :data:`DETERMINED_REL_SD` of its Cd, it
lies where the data reach the drag model (``usable``), and nothing withdrew it (the check found
an effect it could not size, the track is seen from a site the round does not give, a rigid
model misses the flexible fit of the same track). :func:`claimed` is that rule for a round's
rows, a Scheme 2 window and its stitched grid, and a session's pooled rows alike.

Adding a band term changes one module, the stage that sizes it: declare the term there
(``RATE_SCALE_TERM = BandTerm("rate_scale", why="...")``, reported under ``model_error`` unless
said) and call ``add_model_error(rows, RATE_SCALE_TERM, sd)``; ``tests/unit/test_claims.py`` finds
every declared term and checks its budget key (docs/architecture.md shows it).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .model_error import combine


__all__ = ["DETERMINED_REL_SD", "BandTerm", "DataBand", "claimed", "claim", "set_model_error", "add_model_error",
           "set_floor", "DATA_TERMS", "BUDGET_KEYS"]

#: a row is determined when its judged band is below this fraction of its Cd [-]
DETERMINED_REL_SD = 0.01
#: the ``uncertainty_budget.by_source`` keys a band term may be reported under (``"<source>"``: a
#: declared systematic source under its own stem: ``wind``, ``density``, ...)
BUDGET_KEYS = ("statistical", "noise_model", "model_error", "<source>")


@dataclass(frozen=True)
class BandTerm:
    """One named term of a row's band.

    Attributes
    ----------
    name : str
        Its name (the key of ``ml.quality.model_error.parts`` where the check records it).
    reported_under : str
        The ``uncertainty_budget.by_source`` key it is reported under (one of :data:`BUDGET_KEYS`).
    why : str
        What it holds, in a line.
    """

    name: str
    reported_under: str = "model_error"
    why: str = ""

    def __post_init__(self):
        if self.reported_under not in BUDGET_KEYS:
            raise ValueError(f"band term {self.name!r}: reported under {self.reported_under!r}, not one of "
                             f"{', '.join(BUDGET_KEYS)}")


#: the data's band terms (made by the quality gate, :class:`DataBand`)
DATA_TERMS = (
    BandTerm("crb", "statistical", "the Cramér-Rao sd with the declared sources held"),
    BandTerm("crb_colored", "statistical", "its colored-residual form where the residuals are correlated"),
    BandTerm("model_error_floor", "statistical", "the white fit's colored sd under an AR(1) noise model"),
    BandTerm("short_track_bend", "statistical", "how far Cd may bend between a short track's samples"),
    BandTerm("origin_density", "statistical", "a frame not at the gun's height: the air's difference"),
    BandTerm("noise_model", "noise_model", "the AR(1) noise's own uncertainty"),
    BandTerm("declared_sources", "<source>", "each declared systematic under its own key"),
)


@dataclass(frozen=True)
class DataBand:
    """The data's band of each row before the model error (made by the quality gate).

    Attributes
    ----------
    sd : (M,) ndarray
        The data's band [Cd]: noise, correlated residuals, unresolved bends, the declared sources.
    held_var : (M,) ndarray
        The declared sources' share of ``sd**2`` [Cd^2], held out of the judgement.
    usable : (M,) bool ndarray
        Rows the data can claim at all: inside the flown span, not held flat beyond the drag
        model's span, not at a bound of the model.
    """

    sd: np.ndarray
    held_var: np.ndarray
    usable: np.ndarray

    @classmethod
    def plain(cls, sd, usable=True):
        """A band with no declared share: ``sd`` judged whole."""
        sd = np.asarray(sd, float)
        return cls(sd, np.zeros(sd.shape), np.broadcast_to(np.asarray(usable, bool), sd.shape))


def claimed(ml, data, model_error_sd=None, withdrawn=None):
    """Each row's band and whether it is claimed: the one rule (module docstring).

    Parameters
    ----------
    ml : (M,) array_like
        The rows' Cd.
    data : DataBand
    model_error_sd : (M,) array_like, optional
        The rows' model-error terms added in squares [Cd] (default none).
    withdrawn : (M,) bool array_like or bool, optional
        Rows a check withdrew (default none).

    Returns
    -------
    (band_sd (M,) ndarray, determined (M,) bool ndarray)
        ``band_sd = sqrt(sd**2 + model_error_sd**2)``; ``determined`` when
        ``sqrt(sd**2 - held_var + model_error_sd**2)`` is positive, finite and below
        ``DETERMINED_REL_SD * ml``, the row usable and not withdrawn. A zero band is no bound at
        all (an information matrix the data leave singular there).
    """
    ml = np.asarray(ml, float)
    band = np.asarray(data.sd, float)
    me = np.zeros(ml.shape) if model_error_sd is None else np.asarray(model_error_sd, float)
    judged = np.sqrt(np.clip(band**2 - np.asarray(data.held_var, float), 0, None) + me**2)
    band = np.sqrt(band**2 + me**2)
    with np.errstate(divide="ignore", invalid="ignore"):
        rel = np.where(ml > 0, judged / ml, np.inf)
    det = (rel < DETERMINED_REL_SD) & np.asarray(data.usable, bool) & np.isfinite(band) & (judged > 0)
    if withdrawn is not None:
        det &= ~np.broadcast_to(np.asarray(withdrawn, bool), det.shape)
    return band, det


def claim(rows, data, withdrawn=None):
    """Write each row's ``band_sd`` and ``determined`` (:func:`claimed`, with the rows' own
    ``model_error_sd``) into the ``cd`` rows ``rows``; a second call with more ``withdrawn``
    rows replaces the first."""
    me = np.array([r.get("model_error_sd", 0.0) for r in rows], float)
    band, det = claimed([r["ml"] for r in rows], data, me, withdrawn)
    for r, b, d in zip(rows, band, det):
        r["band_sd"] = float(b)
        r["determined"] = bool(d)


def set_model_error(rows, parts, terms):
    """The rows' ``model_error_sd`` from the check's parts added in squares; nothing written
    without parts.

    Parameters
    ----------
    rows : list of dict
    parts : dict
        Term name -> (M,) sd [Cd] (None: left out).
    terms : sequence of BandTerm
        The terms the parts may name (each part must be one of them).
    """
    _known(parts, terms)
    me = combine(*parts.values())
    if me is None:
        return
    for r, v in zip(rows, me):
        r["model_error_sd"] = float(v)


def add_model_error(rows, term, sd):
    """Add the :class:`BandTerm` ``term``, ``sd`` [Cd] per row, to each row's ``model_error_sd``
    in squares (independent model errors)."""
    _known({getattr(term, "name", term): sd}, (term,))
    for r, v in zip(rows, sd):
        r["model_error_sd"] = float(np.hypot(r.get("model_error_sd", 0.0) or 0.0, v))


def set_floor(rows, floor):
    """The AR(1) fit's floor (``model_error_floor``, the white fit's colored sd with the declared
    sources [Cd] per row): kept on each row, and its colored sd raised to it."""
    for r, f in zip(rows, floor):
        r["model_error_floor"] = float(f)
        r["crb_sd_colored"] = float(max(r["crb_sd_colored"], f))


def _known(parts, terms):
    """Each part is one of the declared :class:`BandTerm` ``terms``, reported under ``model_error``."""
    if not all(isinstance(t, BandTerm) for t in terms):
        raise TypeError(f"a model-error term is a BandTerm declared in the stage that sizes it, got "
                        f"{', '.join(repr(t) for t in terms if not isinstance(t, BandTerm))}")
    names = {t.name for t in terms if t.reported_under == "model_error"}
    unknown = [k for k in parts if k not in names]
    if unknown:
        raise ValueError(f"model-error part(s) {', '.join(unknown)} are none of the declared terms "
                         f"({', '.join(sorted(names))})")
