"""What the result values cost on the shipped demo track (issue 24): the length of ``repr(res)``,
the seconds of ``res.write(DIR)`` and the size of the files it writes (``posterior.nc`` above
all), without and with sampling.

Each fit runs once (warm kernel: a first ML fit compiles it); ``res.write`` is timed twice and
the second is reported (the first imports matplotlib and the report's templates). The machine's
load average is printed with the results: on a shared 2-core machine the times scale with it.
The last line is one JSON object.

    python3 benchmarks/result_api.py [--no-mcmc] [--seed 0]
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))


def demo_round_and_track():
    """The shipped demo track (as ``bayesdrag demo`` reads it) and its round."""
    from bayesdrag.commands.demo import demo_inputs
    from bayesdrag.io.rounds import read_round
    from bayesdrag.io.tracks import read_track

    track_path, round_path = demo_inputs()
    return read_track(track_path), read_round(round_path)


def measure(res, label):
    """``repr`` length, write seconds (second of two writes) and file sizes of one result."""
    out = {"repr_chars": len(repr(res))}
    with tempfile.TemporaryDirectory() as tmp:
        secs = []
        for k in range(2):
            t = time.perf_counter()
            res.write(Path(tmp) / f"run{k}")
            secs.append(time.perf_counter() - t)
        folder = Path(tmp) / "run1"
        sizes = {p.name: p.stat().st_size for p in folder.iterdir() if p.is_file()}
    out["write_seconds"] = round(secs[1], 2)
    out["write_seconds_first"] = round(secs[0], 2)
    out["posterior_nc_bytes"] = sizes.get("posterior.nc")
    out["folder_bytes"] = sum(sizes.values())
    print(f"{label}: repr {out['repr_chars']} chars; write {out['write_seconds']} s (first "
          f"{out['write_seconds_first']} s); posterior.nc {out['posterior_nc_bytes']} bytes; "
          f"folder {out['folder_bytes']} bytes", flush=True)
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--no-mcmc", action="store_true", help="only the maximum-likelihood fit")
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args(argv)
    import bayesdrag

    track, rnd = demo_round_and_track()
    report = {"load_average": os.getloadavg()[0]}
    report["ml"] = measure(bayesdrag.fit(track, rnd, mcmc=False), "ML")
    if not args.no_mcmc:
        report["sampled"] = measure(bayesdrag.fit(track, rnd, seed=args.seed), "sampled")
    print(f"load average {report['load_average']:.2f}")
    print(json.dumps(report))


if __name__ == "__main__":
    main()
