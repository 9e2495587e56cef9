"""The real LabRadar series as chronograph sessions: bands, and honesty without a truth.

Run: ``python3 tests/acceptance/run_real_sessions.py [--data DIR] [--json OUT] [SERIES ...]``
(about a minute on 2 cores; ``tests/acceptance/test_real_sessions.py`` runs it, marked slow).

For every series of :mod:`labradar_catalogue` (air stated as ICAO, the device's offset unknown):

* the whole series as one session: its central row (the information-weighted Mach) and band;
* **odd/even**: a series of 8+ usable shots fitted twice more, its odd and its even shots as two
  sessions; at each common Mach where both have ``sd``/Cd <= 1.5 %, ``z = delta / sqrt(sd1^2 +
  sd2^2)``; and every determined row of either half against the other;
* **same day**: series of one bullet fired the same day from the same rifle compared at a
  common Mach.

Gates (issue 49): every centrefire rifle series of 8+ usable shots has its central row's
``sd``/Cd <= 1.5 %; odd/even ``|z| <= 3`` everywhere and the RMS of z across series <= 1.3;
same-day series within 3 combined sd; no negative Cd in any row of any series.
"""
from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))

from support.labradar_catalogue import SAME_DAY, SERIES, round_text  # noqa: E402

from bayesdrag.campaign.session.run import fit_chronograph_session  # noqa: E402
from bayesdrag.io.rounds import read_round  # noqa: E402
from bayesdrag.io.sessions import read_session  # noqa: E402

DATA = HERE.parents[2] / "shared" / "data" / "labradar"
#: odd/even and same-day rows are compared where both bands are at most this
COMPARE_REL_SD = 0.015
#: the rifle gate: central sd/Cd at most this with 8+ usable shots
RIFLE_REL_SD = 0.015
MIN_SHOTS_GATE = 8


def _fit(files, rnd):
    try:
        return fit_chronograph_session(files, rnd).record, None
    except Exception as exc:  # noqa: BLE001 - a suite reports every failure and goes on
        return None, f"{type(exc).__name__}: {exc}"


def _cd_at(rec, mach):
    """(Cd, sd) of a record's curve at ``mach`` (linear between its rows), None outside its span."""
    m = np.array([r["mach"] for r in rec["cd"]])
    if not m.size or not m[0] <= mach <= m[-1]:
        return None
    return (float(np.interp(mach, m, [r["mean"] for r in rec["cd"]])),
            float(np.interp(mach, m, [r["sd"] for r in rec["cd"]])))


def _z_common(a, b):
    """z at the common Mach where the two bands are narrowest together (both <= 1.5 %)."""
    if not a["cd"] or not b["cd"]:
        return None
    lo = max(a["cd"][0]["mach"], b["cd"][0]["mach"])
    hi = min(a["cd"][-1]["mach"], b["cd"][-1]["mach"])
    if hi < lo:
        return None
    best = None
    for m in np.linspace(lo, hi, 21):
        ca, cb = _cd_at(a, m), _cd_at(b, m)
        if ca[1] / ca[0] > COMPARE_REL_SD or cb[1] / cb[0] > COMPARE_REL_SD:
            continue
        s = np.hypot(ca[1], cb[1])
        if best is None or s < best[2]:
            best = (float(m), (ca[0] - cb[0]) / s, s)
    return best


def run(data=DATA, only=None, log=print):
    out, t_start = {"series": [], "same_day": []}, time.time()
    records = {}
    with tempfile.TemporaryDirectory() as tmp:
        for folder, cal, gr, ref, kind, bullet in SERIES:
            if only and not any(folder.endswith(o) for o in only):
                continue
            path = Path(tmp) / f"{folder.replace('/', '_')}.toml"
            path.write_text(round_text(cal, gr, ref, f"{cal} {gr} gr {bullet}"))
            rnd = read_round(path)
            files = read_session(data / folder)
            rec, err = _fit(files, rnd)
            row = {"series": folder, "kind": kind, "bullet": f"{cal} {gr} gr {bullet}", "shots": len(files.usable),
                   "error": err}
            if rec is not None:
                records[folder] = rec
                c = rec["central"]
                row.update(mach=c["mach"], cd=c["mean"], rel_sd=c["rel_sd"], determined=c["determined"],
                           rows_determined=rec["determined"]["rows"], rows=rec["determined"]["of"],
                           negative=any(r["mean"] <= 0 for r in rec["cd"]), order=rec["model"]["order"],
                           tau=rec["scatter"]["mean"], ff_g7=rec["form_factor"]["G7"]["value"])
            if len(files.usable) >= MIN_SHOTS_GATE:
                halves = []
                for parity in (0, 1):
                    keep = [s for k, s in enumerate(files.usable) if k % 2 == parity]
                    halves.append(_fit(replace(files, shots=tuple(keep), name=f"{files.name}-{parity}"), rnd)[0])
                if all(h is not None for h in halves):
                    z = _z_common(*halves)
                    row["odd_even"] = None if z is None else {"mach": z[0], "z": z[1]}
                    # every determined row of either half against the other half
                    worst = 0.0
                    for a, b in (halves, halves[::-1]):
                        for r in a["cd"]:
                            if r["determined"]:
                                cb = _cd_at(b, r["mach"])
                                if cb is not None:
                                    worst = max(worst, abs(r["mean"] - cb[0]) / np.hypot(r["sd"], cb[1]))
                    row["odd_even_determined_max_z"] = worst
            out["series"].append(row)
            log(json.dumps(row))
        for group in SAME_DAY:
            recs = [records.get(g) for g in group]
            for i in range(len(group)):
                for j in range(i + 1, len(group)):
                    if recs[i] is None or recs[j] is None:
                        continue
                    z = _z_common(recs[i], recs[j])
                    out["same_day"].append({"a": group[i], "b": group[j],
                                            "z": None if z is None else z[1], "mach": None if z is None else z[0]})
    out["seconds"] = time.time() - t_start
    out["summary"] = summarise(out)
    return out


def summarise(out):
    rows = out["series"]
    gated = [r for r in rows if r["kind"] == "rifle" and r["shots"] >= MIN_SHOTS_GATE]
    over = [r["series"] for r in gated if r.get("rel_sd") is None or r["rel_sd"] > RIFLE_REL_SD]
    zs = [r["odd_even"]["z"] for r in rows if r.get("odd_even")]
    det_bad = [r["series"] for r in rows if r.get("odd_even_determined_max_z", 0.0) > 3]
    same = [d for d in out["same_day"] if d["z"] is not None]
    return {"rifle_series_gated": len(gated), "rifle_over_1p5": over,
            "rifle_rel_sd_median": float(np.median([r["rel_sd"] for r in gated if r.get("rel_sd")])) if gated else None,
            "odd_even_pairs": len(zs), "odd_even_max_abs_z": float(np.max(np.abs(zs))) if zs else None,
            "odd_even_rms_z": float(np.sqrt(np.mean(np.square(zs)))) if zs else None,
            "odd_even_determined_over_3": det_bad,
            "same_day_max_abs_z": float(np.max(np.abs([d["z"] for d in same]))) if same else None,
            "negative_cd": [r["series"] for r in rows if r.get("negative")],
            "errors": [(r["series"], r["error"]) for r in rows if r["error"]]}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("series", nargs="*")
    ap.add_argument("--data", type=Path, default=DATA)
    ap.add_argument("--json", type=Path, default=None)
    a = ap.parse_args(argv)
    out = run(a.data, a.series or None)
    print(json.dumps(out["summary"], indent=1))
    if a.json:
        a.json.write_text(json.dumps(out, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
