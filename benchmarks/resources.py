"""Benchmark: the memory and time of the two inputs an attacker (or a slip) can make huge:
reading a 5 M-row track, and ``bayesdrag plan --dt 0.0001``.

    python benchmarks/resources.py [--rows 5000000] [--cases 1,64] [--timeout 600] [--quick]

``read``: a valid track of ``--rows`` rows (t, x, y, z, v of a straight climb, 10 us apart, the
writer's precision) is written once into a temporary folder; a fresh interpreter imports
``bayesdrag.io.tracks``, notes its peak resident memory (``ru_maxrss``: the interpreter and
numpy), reads the track with :func:`read_track` and notes the peak again. Reported: the file's
size, the peak, the growth of the peak over the baseline and its ratio to the file's size (the
target is ~3x), and the read's wall time.

``plan``: ``bayesdrag plan`` of the shipped demo round at ``--dt 0.0001`` s for one case
(QE 15 deg, 818 m/s) and for 64 cases (8 elevations x 8 velocities), each in a fresh process
with a time limit (``--timeout``): its wall time, the child's own peak resident memory
(``wait4``) and whether it finished.

The machine is shared: wall times move with the load (printed), memory does not. The last line
printed is one JSON object.

Measured (2 cores shared, load 0.3-2.3; ``python benchmarks/resources.py``), issue 25:

=====================================  ==============================  ==============================
                                       before (eb6905e)                after
=====================================  ==============================  ==============================
read_track, 5 M rows (234 MB)          peak 1878 MB, growth 7.6x file  peak 657 MB, growth 2.4x file
                                       7.5 s                           4.4 s
plan --dt 0.0001, 1 case               3542 MB, 13.7 s                 347 MB, 2.2 s
plan --dt 0.0001, 64 cases             not finished in 300 s (killed   496 MB, 18.2 s
                                       at 6.7 GB)
=====================================  ==============================  ==============================
"""
import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

_READER = r"""
import json, resource, sys, time
from bayesdrag.io.tracks import read_track
base = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
t0 = time.perf_counter()
tr = read_track(sys.argv[1])
sec = time.perf_counter() - t0
peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
print(json.dumps({"rows": tr.n, "baseline_kib": base, "peak_kib": peak, "seconds": sec}))
"""


def write_track(path, rows, block=500_000):
    """A valid straight-climb track of ``rows`` rows at 10 us (x 800 m/s, z 300 m/s)."""
    with open(path, "w", encoding="ascii") as fh:
        fh.write("# benchmark track: straight climb, 10 us samples\nt,x,y,z,v\n")
        speed = float(np.hypot(800.0, 300.0))
        for i0 in range(0, rows, block):
            t = np.arange(i0, min(rows, i0 + block)) * 1e-5
            cols = np.column_stack([t, 800.0 * t, 0.01 * t, 300.0 * t, np.full(t.size, speed)])
            np.savetxt(fh, cols, fmt=["%.6f", "%.4f", "%.4f", "%.4f", "%.4f"], delimiter=",")


def bench_read(rows, folder):
    path = Path(folder) / "track.csv"
    write_track(path, rows)
    size = path.stat().st_size
    out = run_child([sys.executable, "-c", _READER, str(path)], folder, 3600.0)
    if out["exit"] != 0:
        return {"rows": rows, "file_bytes": size, "error": out["stderr"].strip().splitlines()[-1:]}
    r = json.loads(out["stdout"].strip().splitlines()[-1])
    growth = (r["peak_kib"] - r["baseline_kib"]) * 1024
    path.unlink()
    return {"rows": r["rows"], "file_bytes": size, "peak_rss_bytes": r["peak_kib"] * 1024,
            "growth_bytes": growth, "growth_over_file": growth / size, "seconds": r["seconds"]}


def run_child(cmd, folder, timeout, max_memory=None):
    """Run ``cmd`` alone with a time limit; its own peak RSS from ``wait4`` (not the largest of
    all children so far)."""
    so, se = Path(folder) / "child.out", Path(folder) / "child.err"
    t0 = time.perf_counter()
    with open(so, "w") as fo, open(se, "w") as fe:
        def cap():   # the machine is shared: an address-space cap, not the whole RAM
            resource.setrlimit(resource.RLIMIT_AS, (int(max_memory), int(max_memory)))

        proc = subprocess.Popen(cmd, stdout=fo, stderr=fe, text=True, preexec_fn=cap if max_memory else None)
        finished = True
        while True:
            pid, status, ru = os.wait4(proc.pid, os.WNOHANG)
            if pid:
                break
            if time.perf_counter() - t0 > timeout:
                proc.kill()
                pid, status, ru = os.wait4(proc.pid, 0)
                finished = False
                break
            time.sleep(0.2)
    proc.returncode = os.waitstatus_to_exitcode(status)
    return {"finished": finished, "exit": proc.returncode, "seconds": time.perf_counter() - t0,
            "peak_rss_bytes": ru.ru_maxrss * 1024, "stdout": so.read_text(), "stderr": se.read_text()}


def bench_plan(n_cases, folder, timeout, max_memory):
    import bayesdrag

    demo = Path(bayesdrag.__file__).parent / "data" / "demo_round.toml"
    side = int(round(n_cases ** 0.5))
    els = ",".join(f"{e:g}" for e in np.linspace(10, 45, side)) if n_cases > 1 else "15"
    vels = ",".join(f"{v:g}" for v in np.linspace(650, 830, side)) if n_cases > 1 else "818"
    out = Path(folder) / f"plan{n_cases}"
    cmd = [sys.executable, "-m", "bayesdrag", "plan", str(demo), "-o", str(out), "--dt", "0.0001",
           "--elevations", els, "--velocities", vels]
    r = run_child(cmd, folder, timeout, max_memory)
    last = (r["stderr"].strip().splitlines() or [""])[-1] if r["exit"] else ""
    return {"cases": n_cases, "finished": r["finished"], "exit": r["exit"], "seconds": r["seconds"],
            "peak_rss_bytes": r["peak_rss_bytes"], "stderr_last_line": last[:200],
            "stdout_first_line": (r["stdout"].strip().splitlines() or [""])[0][:200]}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--rows", type=int, default=5_000_000)
    ap.add_argument("--cases", default="1,64", help="plan case counts (square numbers), e.g. 1,64")
    ap.add_argument("--timeout", type=float, default=600.0, help="time limit of each plan [s]")
    ap.add_argument("--max-memory", type=float, default=8e9,
                    help="address-space cap of each plan child [bytes] (default 8e9; 0: none)")
    ap.add_argument("--quick", action="store_true", help="500 000 rows, one planned case")
    ap.add_argument("--skip", default="", help="comma-separated parts to skip: read, plan")
    a = ap.parse_args(argv)
    rows = 500_000 if a.quick else a.rows
    cases = [1] if a.quick else [int(c) for c in a.cases.split(",") if c]
    skip = set(a.skip.split(","))
    result = {"load_average": os.getloadavg()}
    with tempfile.TemporaryDirectory(prefix="bayesdrag-resources-") as folder:
        if "read" not in skip:
            r = bench_read(rows, folder)
            result["read"] = r
            if "growth_bytes" in r:
                print(f"read_track: {r['rows']} rows, file {r['file_bytes'] / 1e6:.1f} MB, peak RSS "
                      f"{r['peak_rss_bytes'] / 1e6:.0f} MB, growth {r['growth_bytes'] / 1e6:.0f} MB = "
                      f"{r['growth_over_file']:.2f} x the file, {r['seconds']:.1f} s")
            else:
                print(f"read_track failed: {r['error']}")
        if "plan" not in skip:
            result["plan"] = []
            for n in cases:
                p = bench_plan(n, folder, a.timeout, a.max_memory)
                result["plan"].append(p)
                print(f"plan --dt 0.0001, {n} case(s): {'finished' if p['finished'] else 'did not finish'} "
                      f"(exit {p['exit']}) in {p['seconds']:.1f} s, peak RSS "
                      f"{p['peak_rss_bytes'] / 1e6:.0f} MB"
                      + (f"; {p['stderr_last_line']}" if p["stderr_last_line"] else ""))
    print(json.dumps(result))


if __name__ == "__main__":
    main()
