"""The ``plan`` verb: predict, before firing, the Cd sd by Mach each planned case will give
(:func:`plan`, ``bayesdrag.plan``). The statistics are in :mod:`bayesdrag.planning`; the command
that reads a round file and writes the folder is :mod:`bayesdrag.commands.plan`."""
from __future__ import annotations

import time
from typing import Any

from ..drag import ReferenceTable
from ..errors import InputError
from ..options import PLAN_MAX_CASES, PlanOptions
from ..planning.plan import make_plan
from ..results import PlanResult
from ..round import Round

__all__ = ["plan"]


def plan(rnd: Round, options: PlanOptions | None = None, *, assumed_drag: ReferenceTable | None = None,
         **kwargs: Any) -> PlanResult:
    """Predict, before firing, the Cd sd by Mach each planned case will give.

    Parameters
    ----------
    rnd : Round
        Needs ``[radar] sigma``; its declared systematic sds are marginalised.
    options : PlanOptions, optional
        Keyword arguments override single fields: ``elevations=(15, 45)`` [deg],
        ``velocities=(684, 818)`` [m/s] (defaults: the round's launch), ``dt`` [s],
        ``rounds``, ``scatter``, ``target``, ``lock_on``, ``loss`` [s], ``seed``,
        ``radar_sites=((-40, 25, 2), (0, -30, 1))`` [m] (candidate sites of a radar recording its
        own channels: ``plan.json`` then has ``radar_sites`` ranked and ``best_site``).
    assumed_drag : ReferenceTable, optional
        The drag the shell is expected to have (default: the round's reference drag, else a
        generic 155 mm curve).

    Returns
    -------
    PlanResult
        ``to_dict()`` is ``plan.json``, ``to_dataframe()`` the cases, ``summary()`` a printable
        table; ``write(DIR)`` writes the folder the command writes.

    Raises
    ------
    InputError
        No elevation or velocity (neither given nor in the round), no ``[radar] sigma``, a case
        that does not fly or is tracked too briefly.
    """
    t0 = time.perf_counter()
    opts = options if options is not None else PlanOptions()
    if kwargs:
        opts = PlanOptions(**{**opts.to_dict(), **kwargs})
    L = rnd.launch
    elevations = opts.elevations or ((L.elevation_deg,) if L.elevation_deg is not None else None)
    velocities = opts.velocities or ((L.velocity,) if L.velocity is not None else None)
    where = rnd.path or "round"
    if elevations is None:
        raise InputError(f"{where}: plan needs elevations: give --elevations (e.g. 15,45) or [launch] elevation")
    if velocities is None:
        raise InputError(f"{where}: plan needs launch velocities: give --velocities (e.g. 684,818) or "
                         f"[launch] velocity")
    n_sites = len(opts.radar_sites) if opts.radar_sites else 1
    if len(elevations) * len(velocities) * n_sites > PLAN_MAX_CASES:
        raise InputError(f"{len(elevations)} elevations x {len(velocities)} velocities x {n_sites} radar site(s) are "
                         f"{len(elevations) * len(velocities) * n_sites} cases; plan at most {PLAN_MAX_CASES} at once")
    p = make_plan(rnd, elevations, velocities, dt=opts.dt, rounds=opts.rounds, scatter=opts.scatter,
                  target=opts.target, lock_on=opts.lock_on, loss=opts.loss, assumed_drag=assumed_drag, seed=opts.seed,
                  radar_sites=opts.radar_sites)
    return PlanResult(p.to_dict(), p, rnd, opts, time.perf_counter() - t0)
