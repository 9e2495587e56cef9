"""Planning a firing as a command, ``bayesdrag plan ROUND -o DIR`` (:func:`run_plan`); the Python
API ``bayesdrag.plan`` is :func:`bayesdrag.pipeline.plans.plan`. The statistics are in
:mod:`bayesdrag.planning.case` and :mod:`bayesdrag.planning.plan`."""
from __future__ import annotations

import sys
from pathlib import Path

from ..errors import InputError
from ..pipeline.plans import plan

__all__ = ["plan", "run_plan"]




def run_plan(round_path, out, options=None, *, assumed_drag_path=None, echo=print):
    """``bayesdrag plan ROUND -o DIR``: read the round (and an assumed drag table), plan, write
    ``DIR/plan.json``, ``plan.html`` and the figures. Returns the :class:`PlanResult`."""
    from ..io.drag_tables import read_drag_table
    from ..io.outputs import OutputRun
    from ..io.rounds import read_round, round_files

    rnd = read_round(round_path)
    drag = read_drag_table(assumed_drag_path) if assumed_drag_path is not None else None
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise InputError(f"{out}: output path exists and is not a folder")
    inputs = dict(round_files(round_path, rnd))
    if assumed_drag_path is not None:
        inputs["assumed_drag"] = assumed_drag_path
    opts = options.to_dict() if hasattr(options, "to_dict") else options
    # one consistent set like every command's: checked and locked before the work, staged,
    # swapped in with a manifest, an earlier plan's files superseded
    with OutputRun(out, "plan", inputs=inputs, options=opts,
                   echo=lambda m: print(m, file=sys.stderr, flush=True)) as run:
        result = plan(rnd, options, assumed_drag=drag)
        result.write(run.staging, sources={"round": round_path})
    echo(f"plan: {len(result.cases)} case(s) in {result.seconds:.1f} s; wrote {out / 'plan.json'}, plan.html, "
         f"manifest.json")
    echo(result.paragraph)
    return result
