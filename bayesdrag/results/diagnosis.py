"""What a diagnosis found, as a value: :class:`DiagnosisResult`, and :func:`load_diagnosis` to
read a written diagnosis folder back into one."""
from __future__ import annotations

import json
from pathlib import Path
from typing import TYPE_CHECKING, Any

from ..errors import MissingDataError
from .document import DIAGNOSIS_SCHEMA, jsonable, read_document
from .summary import Summary
from .words import grouped_effects, verdict_words

if TYPE_CHECKING:
    import pandas
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

    from ..round import Round
    from ..track import RadarTrack

__all__ = ["DiagnosisResult", "load_diagnosis"]

#: characters of an effect's parameters a summary row shows (the data frame has them all)
SUMMARY_PARAMS_CHARS = 60
#: the columns of :meth:`DiagnosisResult.to_dataframe` taken from each effect as they are
EFFECT_COLUMNS = ("name", "significant", "material", "shrink", "delta_loglik", "delta_bic", "test_statistic",
                  "threshold", "cd_shift_max", "end_shift_sd")


def _params_text(e: dict[str, Any]) -> str:
    """``factor = 0.9777 ± 0.0017 [-]``-like text of an effect's parameters."""
    units = e.get("units") or {}
    sd = e.get("sd") or {}
    out = []
    for k, v in (e.get("params") or {}).items():
        s = sd.get(k)
        unit = f" {units[k]}" if units.get(k) and units[k] != "-" else ""
        out.append(f"{k} = {_num(v, '.4g')}" + (f" ± {s:.2g}" if isinstance(s, (int, float)) else "") + unit)
    return ", ".join(out)


def _num(v: Any, spec: str) -> str:
    """A number as ``spec`` formats it; ``—`` for a value the document holds as null."""
    return "—" if v is None else format(v, spec)


def _short(text: str) -> str:
    return text if len(text) <= SUMMARY_PARAMS_CHARS else text[:SUMMARY_PARAMS_CHARS - 3] + "..."


class DiagnosisResult:
    """What a diagnosis found (:func:`bayesdrag.diagnose`), as a value.

    Attributes
    ----------
    record : dict
        The content of ``diagnosis.json`` (with ``summary``, the paragraph); :meth:`to_dict`
        gives a copy.
    diagnosis : Diagnosis or None
        The analysis (:func:`bayesdrag.diagnosis.diagnose`): the residuals the figures show;
        None for a result read from a folder.
    track : RadarTrack or None
    round : Round or None
    folder : Path or None
        The folder a loaded result was read from.
    """

    record: dict[str, Any]
    diagnosis: Any
    track: RadarTrack | None
    round: Round | None
    folder: Path | None

    def __init__(self, record: dict[str, Any], diagnosis: Any = None, track: RadarTrack | None = None,
                 round: Round | None = None, *, folder: Path | None = None) -> None:
        for k, v in dict(record=record, diagnosis=diagnosis, track=track, round=round,
                         folder=None if folder is None else Path(folder)).items():
            object.__setattr__(self, k, v)

    def __setattr__(self, name: str, value: Any) -> None:
        raise AttributeError(f"DiagnosisResult is frozen: cannot set {name!r}")

    @property
    def verdict(self) -> list[str]:
        """The material effects found, best first (``[]``: the nominal model explains the track)."""
        return list(self.record["verdict"])

    @property
    def immaterial(self) -> list[str]:
        """Effects the track shows that would not change a fitted Cd materially."""
        return list(self.record.get("immaterial") or [])

    @property
    def paragraph(self) -> str:
        """The diagnosis in one paragraph of words (``diagnosis.json``'s ``summary``)."""
        return str(self.record["summary"])

    @property
    def loaded(self) -> bool:
        """True for a result read back from a folder (:func:`load_diagnosis`)."""
        return self.folder is not None

    def to_dict(self) -> dict[str, Any]:
        """The content of ``diagnosis.json``: plain JSON types, a fresh copy (with ``summary``, the
        paragraph)."""
        return json.loads(json.dumps(jsonable(self.record), allow_nan=False))

    def to_dataframe(self) -> pandas.DataFrame:
        """The candidate effects, best first, one row each: :data:`EFFECT_COLUMNS`, ``verdict``
        (in the verdict), ``confounded_with`` and ``params`` (their values ± sd, as text)."""
        import pandas as pd

        verdict = set(self.verdict)
        rows = []
        for e in self.record["effects"]:
            r = {k: e.get(k) for k in EFFECT_COLUMNS}
            r["verdict"] = e["name"] in verdict
            r["confounded_with"] = ", ".join(e.get("confounded_with") or [])
            r["params"] = _params_text(e)
            rows.append(r)
        return pd.DataFrame(rows, columns=list(EFFECT_COLUMNS) + ["verdict", "confounded_with", "params"])

    def summary(self) -> Summary:
        """A printable summary: the verdict, the baseline's misfit, and every candidate effect
        (significant, material, the share of the gap it removes, its parameters)."""
        s = self.record
        b = s["baseline"]
        header = (("verdict", verdict_words(self.verdict, s["effects"]) or "none (the nominal model explains the track)"),
                  ("detectable, immaterial", ", ".join(self.immaterial) or "none"),
                  ("baseline chi2 per sample", _num(b["chi2_per_sample"], ".4g")),
                  ("gap", _num(b["gap"], ".4g")),
                  ("reference drag", "yes" if s.get("reference_drag") else "no (judged against a fitted Cd)"),
                  ("candidates tested", str((s.get("tests") or {}).get("candidates", len(s["effects"])))))
        rows = tuple((e["name"], "yes" if e.get("significant") else "no",
                      "yes" if e["name"] in self.verdict else "no", _num(e.get("shrink"), ".3f"),
                      _num(e.get("delta_loglik"), ".4g"), _short(_params_text(e))) for e in grouped_effects(s["effects"]))
        return Summary(title="bayesdrag diagnosis", header=header,
                       columns=("effect", "significant", "in verdict", "shrink", "delta loglik", "parameters"),
                       rows=rows, notes=(self.paragraph,), align=("<", ">", ">", ">", ">", "<"))

    def __repr__(self) -> str:
        s = self.record
        sig = sum(1 for e in s["effects"] if e.get("significant"))
        where = f"; read from {self.folder}" if self.loaded else ""
        return (f"<DiagnosisResult: verdict {self.verdict or 'none'}; immaterial {self.immaterial or 'none'}; "
                f"baseline chi2/sample {_num(s['baseline']['chi2_per_sample'], '.3g')}; "
                f"{len(s['effects'])} candidates, "
                f"{sig} significant{where}. See .summary(), .to_dataframe(), .paragraph, .to_dict()>")

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, DiagnosisResult):
            return NotImplemented
        return self.to_dict() == other.to_dict()

    __hash__ = None  # type: ignore[assignment]

    def require(self, what: str) -> None:
        """Raise :class:`~bayesdrag.errors.MissingDataError` when the analysis's arrays are
        missing (a result read from a folder)."""
        if self.diagnosis is None or self.track is None or self.round is None:
            raise MissingDataError(f"{what} needs the diagnosis's residual arrays, track and round, and this result "
                                   f"was read from {self.folder} (diagnosis.json only): run bayesdrag.diagnose to "
                                   f"get them")

    # -- figures ------------------------------------------------------------------------------
    def plot_ranking(self, ax: Axes | None = None) -> Axes:
        """Bars of the share of the gap each candidate removes (``diagnosis_ranking.png``)."""
        from ..plots.diagnosis import plot_ranking

        return plot_ranking(self.record, ax=ax)

    def plot_residuals(self, fig: Figure | None = None) -> Figure:
        """Residuals of the nominal model and of the detected effects' fit
        (``diagnosis_residuals.png``; needs the analysis's arrays)."""
        from ..plots.diagnosis import plot_residuals_before_after

        self.require("plot_residuals")
        return plot_residuals_before_after(self.diagnosis, fig=fig)

    def plot_where(self, fig: Figure | None = None) -> Figure:
        """Where the nominal model misses, against time and Mach (``diagnosis_where.png``;
        needs the analysis's arrays)."""
        from ..plots.diagnosis import plot_where

        self.require("plot_where")
        return plot_where(self.diagnosis, fig=fig)

    # -- the output folder --------------------------------------------------------------------
    def write(self, directory: str | Path, *, sources: dict[str, Any] | None = None) -> list[Path]:
        """Write ``diagnosis.json``, the figures and ``diagnosis.html`` into ``directory`` as one
        consistent set (:class:`~bayesdrag.io.outputs.OutputRun`, as :meth:`FitResult.write`).

        Returns
        -------
        list of Path
        """
        from ..io.outputs import OutputRun

        self.require("writing the diagnosis folder")
        files = {k: v for k, v in (sources or {}).items() if v is not None and Path(v).is_file()}
        with OutputRun(directory, "diagnose", inputs=files) as run:
            self.write_files(run.staging, sources=sources)
        assert run.manifest is not None
        return [run.folder / f["name"] for f in run.manifest["files"]]

    def write_files(self, directory: str | Path, *, sources: dict[str, Any] | None = None) -> list[Path]:
        """Write ``diagnosis.json``, the figures and ``diagnosis.html`` into ``directory`` as
        plain files. Returns the paths."""
        from ..report.diagnosis import write_diagnosis

        self.require("writing the diagnosis folder")
        assert self.track is not None and self.round is not None
        src = sources or {}
        out = Path(directory)
        write_diagnosis(out, self.diagnosis, track_name=str(src.get("track", self.track.source)),
                        round_name=str(src.get("round", self.round.path)))
        return [out / "diagnosis.json", out / "diagnosis.html"] + sorted(out.glob("diagnosis_*.png"))


def load_diagnosis(directory: str | Path) -> DiagnosisResult:
    """The :class:`DiagnosisResult` of a folder ``bayesdrag diagnose`` (or ``d.write``) wrote:
    equal to the one that wrote it (the same ``to_dict()``), holding ``diagnosis.json`` only.

    Raises
    ------
    InputError
        No ``diagnosis.json`` in the folder, or not a valid one: a link, not JSON, a number
        that is not finite, or a key the result reads of another type
        (:data:`~.document.DIAGNOSIS_SCHEMA`), named by its path (``effects[2].shrink``).
    """
    folder = Path(directory)
    record = read_document(folder, "diagnosis.json", "diagnosis",
                           required=("baseline", "effects", "verdict", "summary"), schema=DIAGNOSIS_SCHEMA)
    return DiagnosisResult(record, folder=folder)
