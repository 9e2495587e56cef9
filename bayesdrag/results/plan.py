"""What a plan predicts, as a value: :class:`PlanResult`, and :func:`load_plan` to read a written
plan folder back into one."""
from __future__ import annotations

import json
from pathlib import Path
from typing import TYPE_CHECKING, Any

from ..errors import MissingDataError
from .document import PLAN_SCHEMA, jsonable, read_document
from .summary import Summary

if TYPE_CHECKING:
    import pandas
    from matplotlib.axes import Axes

    from ..planning.case import CasePlan
    from ..planning.plan import Plan
    from ..round import Round

__all__ = ["PlanResult", "load_plan", "CASE_COLUMNS"]

#: the columns of :meth:`PlanResult.to_dataframe`
CASE_COLUMNS = ("elevation", "velocity", "rounds", "mach_min", "mach_max", "best_relative_sd", "samples", "t_start",
                "t_end", "drag_model", "target_mach_min", "target_mach_max")


def _case_row(c: dict[str, Any]) -> dict[str, Any]:
    tr = c.get("tracked") or {}
    tm = c.get("target_mach_range") or [None, None]
    mr = c.get("mach_range") or [None, None]
    return {"elevation": c["elevation"], "velocity": c["velocity"], "rounds": c["rounds"], "mach_min": mr[0],
            "mach_max": mr[1], "best_relative_sd": c.get("best_relative_sd"), "samples": tr.get("samples"),
            "t_start": tr.get("t_start"), "t_end": tr.get("t_end"), "drag_model": c.get("drag_model"),
            "target_mach_min": tm[0], "target_mach_max": tm[1]}


def _pct(v: float | None) -> str:
    return "—" if v is None else f"{100 * v:.3g} %"


class PlanResult:
    """What a plan predicts (:func:`bayesdrag.plan`), as a value.

    Attributes
    ----------
    record : dict
        The content of ``plan.json``; :meth:`to_dict` gives a copy.
    plan : Plan or None
        The cases (:class:`~bayesdrag.planning.case.CasePlan`: Mach, assumed Cd, statistical
        and systematic shares) and the target's answer; None for a result read from a folder.
    round : Round or None
    options : PlanOptions or None
    seconds : float
        Wall time [s].
    folder : Path or None
        The folder a loaded result was read from.
    """

    record: dict[str, Any]
    plan: Plan | None
    round: Round | None
    options: Any
    seconds: float
    folder: Path | None

    def __init__(self, record: dict[str, Any], plan: Plan | None = None, round: Round | None = None,
                 options: Any = None, seconds: float = 0.0, *, folder: Path | None = None) -> None:
        for k, v in dict(record=record, plan=plan, round=round, options=options, seconds=float(seconds),
                         folder=None if folder is None else Path(folder)).items():
            object.__setattr__(self, k, v)

    def __setattr__(self, name: str, value: Any) -> None:
        raise AttributeError(f"PlanResult is frozen: cannot set {name!r}")

    @property
    def success(self) -> bool:
        """True: a plan that could not be made raises instead."""
        return True

    @property
    def message(self) -> str:
        """How many cases were planned."""
        return f"{len(self.record['cases'])} case(s) planned"

    @property
    def loaded(self) -> bool:
        """True for a result read back from a folder (:func:`load_plan`)."""
        return self.folder is not None

    @property
    def cases(self) -> tuple[CasePlan, ...]:
        """The :class:`~bayesdrag.planning.case.CasePlan` of every case (elevation x velocity);
        needs the plan's objects (``to_dict()["cases"]`` holds their numbers)."""
        return tuple(self._plan("cases").cases)

    @property
    def paragraph(self) -> str:
        """The plan in one paragraph; with a target, the recommendation."""
        t = self.record.get("target")
        return str(t["paragraph"] if t else self.record["summary"])

    def to_dict(self) -> dict[str, Any]:
        """The content of ``plan.json``: plain JSON types, a fresh copy."""
        return json.loads(json.dumps(jsonable(self.record), allow_nan=False))

    def to_dataframe(self) -> pandas.DataFrame:
        """The planned cases, one row each (:data:`CASE_COLUMNS`; the target's Mach range None
        without a target or where it is not reached)."""
        import pandas as pd

        return pd.DataFrame([_case_row(c) for c in self.record["cases"]], columns=list(CASE_COLUMNS))

    def summary(self) -> Summary:
        """A printable summary: the round, the assumed drag, the radar, the target and every
        case's Mach span and best relative sd of Cd."""
        d = self.record
        radar = d.get("radar") or {}
        t = d.get("target")
        header = [("round", str((d.get("round") or {}).get("name"))),
                  ("assumed drag", str((d.get("assumed_drag") or {}).get("source"))),
                  ("radar noise sd", ", ".join(f"{c} {v:g}" for c, v in (radar.get("sigma") or {}).items())),
                  ("rounds per case", str(d.get("rounds"))),
                  ("target relative sd", _pct(t["relative_sd"]) if t else "none")]
        rows = tuple((f"{r['elevation']:g}", f"{r['velocity']:g}", str(r["rounds"]),
                      f"{r['mach_min']:.2f}-{r['mach_max']:.2f}", _pct(r["best_relative_sd"]),
                      "—" if r["target_mach_min"] is None else f"{r['target_mach_min']:.2f}-{r['target_mach_max']:.2f}")
                     for r in (_case_row(c) for c in d["cases"]))
        return Summary(title="bayesdrag plan", header=tuple(header),
                       columns=("elevation [deg]", "velocity [m/s]", "rounds", "Mach", "best sd of Cd",
                                "target reached over Mach"),
                       rows=rows, notes=(self.paragraph,))

    def __repr__(self) -> str:
        d = self.record
        best = min((c.get("best_relative_sd") for c in d["cases"] if c.get("best_relative_sd") is not None),
                   default=None)
        where = f"read from {self.folder}" if self.loaded else f"{self.seconds:.1f} s"
        return (f"<PlanResult: {self.message}; best relative sd of Cd {_pct(best)}; "
                f"target {_pct(d['target']['relative_sd']) if d.get('target') else 'none'}; {where}. "
                f"See .summary(), .to_dataframe(), .paragraph, .to_dict()>")

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, PlanResult):
            return NotImplemented
        return self.to_dict() == other.to_dict()

    __hash__ = None  # type: ignore[assignment]

    def _plan(self, what: str) -> Plan:
        if self.plan is None:
            raise MissingDataError(f"{what} needs the plan's objects, and this result was read from {self.folder} "
                                   f"(plan.json only): run bayesdrag.plan to get them")
        return self.plan

    # -- figures and the folder -------------------------------------------------------------------
    def plot_plan(self, ax: Axes | None = None) -> Axes:
        """The predicted relative sd of Cd by Mach of every case (``plan.png``; needs the plan's
        objects)."""
        from ..plots.plan import plot_plan

        return plot_plan(self._plan("plot_plan"), ax=ax)

    def write(self, directory: str | Path, *, sources: dict[str, Any] | None = None) -> list[Path]:
        """Write ``plan.json``, ``plan.html`` and the figures into ``directory`` (created if
        needed). Returns the list of files written."""
        from ..report.plan import write_plan

        p = self._plan("writing the plan folder")
        src = sources or {}
        rnd = src.get("round", self.round.path if self.round is not None else "")
        return write_plan(Path(directory), p, round_name=str(rnd), seconds=self.seconds)


def load_plan(directory: str | Path) -> PlanResult:
    """The :class:`PlanResult` of a folder ``bayesdrag plan`` (or ``res.write``) wrote: equal to
    the one that wrote it (the same ``to_dict()``), holding ``plan.json`` only.

    Raises
    ------
    InputError
        No ``plan.json`` in the folder, or not a valid one: a link, not JSON, a number that is
        not finite, or a key the result reads of another type (:data:`~.document.PLAN_SCHEMA`),
        named by its path (``cases[0].mach_range``).
    """
    folder = Path(directory)
    record = read_document(folder, "plan.json", "plan", required=("cases", "summary"), schema=PLAN_SCHEMA)
    return PlanResult(record, folder=folder)
