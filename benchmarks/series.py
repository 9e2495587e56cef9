"""A chronograph session against one of its shots: ``bayesdrag fit SR0047/ ROUND --no-mcmc`` (all
ten shots as one session, with each shot's outputs) and ``bayesdrag fit "SR0047/TRK/Shot0001
Track.csv" ROUND --no-mcmc`` (one shot as an ordinary round), warm, in the same run.

    python3 benchmarks/series.py [--repeat 2]

Prints both wall times [s] and their ratio; the last line is one JSON object
``{"session_s": ..., "shot_s": ..., "ratio": ...}`` (issue 49: the session at most 10 s and at
most 3 times the single shot). The series is the real LabRadar SR0047 shipped with the package.
"""
from __future__ import annotations

import argparse
import json
import shutil
import subprocess
import sys
import tempfile
import time
from importlib.resources import files
from pathlib import Path

ROUND = ('[projectile]\nname = "6.5 mm 142 gr Sierra MatchKing"\nmass = 0.009201\ndiameter = 0.006706\n'
         'reference_drag = "G7"\n[launch]\nelevation = 0.0\nvelocity = 750.0\n')


def _wall(args, cwd):
    t = time.perf_counter()
    p = subprocess.run([sys.executable, "-m", "bayesdrag", *args], cwd=cwd, capture_output=True, text=True)
    if p.returncode:
        raise SystemExit(f"bayesdrag {' '.join(args)} failed: {p.stderr[-500:]}")
    return time.perf_counter() - t


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=2)
    a = ap.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        shutil.copytree(files("bayesdrag") / "data" / "labradar" / "SR0047", Path(tmp) / "SR0047")
        (Path(tmp) / "r.toml").write_text(ROUND)
        session = ["fit", "SR0047", "r.toml", "-o", "s", "--no-mcmc", "-qq"]
        shot = ["fit", "SR0047/TRK/Shot0001 Track.csv", "r.toml", "-o", "o", "--no-mcmc", "-qq"]
        _wall(session, tmp), _wall(shot, tmp)          # warm: numba's cache, the imports
        s = min(_wall(session, tmp) for _ in range(a.repeat))
        o = min(_wall(shot, tmp) for _ in range(a.repeat))
    print(f"session (10 shots, outputs included): {s:.2f} s; one shot as a round: {o:.2f} s; ratio {s / o:.2f}")
    print(json.dumps({"session_s": s, "shot_s": o, "ratio": s / o}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
