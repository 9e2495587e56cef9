"""One honesty-suite flight flown again with other noise seeds: how honest its bands are on average.

    python tests/acceptance/run_honesty_seeds.py CASE_ID [--seeds N] [--with EFFECTS]

The flight of ``CASE_ID`` (:func:`acceptance.honesty_suite.case_by_id`) is remade with the noise
and outlier seed ``seed + 100 k`` for ``k = 1..N`` (default 12) and fitted with the default options
(``--with``: the ``with_effects`` option), without sampling. For each seed it prints the rows the
fit marks determined inside the span's 5 % margins, the rms and the largest |z| of their error over
their ``band_sd`` (z = (Cd - truth) / band_sd at the row's Mach) and the suite's count of wrong
determined rows; the last line pools the seeds: rows, rms z and the shares beyond 2 and 3. Honest
Gaussian bands give an rms near 1 (below where the model error is sized generously) and about
0.3 % of the rows beyond 3.
"""
from __future__ import annotations

import argparse
import dataclasses
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from acceptance import honesty_suite as hs  # noqa: E402

#: seeds of the flight are its own plus this step times k
SEED_STEP = 100


def seed_z(case, with_effects="default"):
    """z of the determined rows inside the span's margins of one fit of ``case``, and its judgement."""
    import bayesdrag

    track, rnd, truth = hs.make(case)
    d = bayesdrag.fit(track, rnd, mcmc=False, with_effects=with_effects).to_dict()
    lo, hi = truth["mach_span"]
    w = hi - lo
    z = [(r["ml"] - float(truth["cd"](np.array([r["mach"]]))[0])) / r["band_sd"] for r in d["cd"]
         if r.get("determined") and lo + hs.SPAN_TRIM * w <= r["mach"] <= hi - hs.SPAN_TRIM * w]
    return np.array(z), hs.judge(d, truth)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("case")
    ap.add_argument("--seeds", type=int, default=12)
    ap.add_argument("--with", dest="with_effects", default="default")
    a = ap.parse_args(argv)
    base = hs.case_by_id(a.case)
    pooled = []
    for k in range(1, a.seeds + 1):
        if base.withheld is not None:      # a diagnosis-suite flight: its own seed
            w = dataclasses.replace(base.withheld, seed=base.withheld.seed + SEED_STEP * k)
            case = dataclasses.replace(base, withheld=w)
        else:
            case = dataclasses.replace(base, seed=base.seed + SEED_STEP * k)
        z, j = seed_z(case, a.with_effects)
        rms = float(np.sqrt(np.mean(z**2))) if z.size else float("nan")
        worst = float(np.abs(z).max()) if z.size else float("nan")
        print(f"seed +{SEED_STEP * k}: determined {z.size}, z rms {rms:.2f} max {worst:.2f}, "
              f"wrong {j['determined_wrong']}", flush=True)
        pooled.append(z)
    allz = np.concatenate(pooled) if pooled else np.zeros(0)
    if allz.size:
        print(f"all: rows {allz.size}, rms z {np.sqrt(np.mean(allz**2)):.2f}, beyond 2: "
              f"{np.mean(np.abs(allz) > 2):.3f}, beyond 3: {np.mean(np.abs(allz) > 3):.3f}")
    else:
        print("all: no determined rows")
    return 0


if __name__ == "__main__":
    sys.exit(main())
