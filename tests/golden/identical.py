"""Bit-for-bit check of a refactor: the golden cases fitted by this tree and by another commit,
in this one environment, must give identical ``result.json`` (timing keys aside).

The committed golden test (``tests/integration/test_golden.py``) compares each number by its own
uncertainty so that it passes on every processor; a change meant to move code and change nothing
should meet the stricter test here, on one machine, before and after::

    python tests/golden/identical.py            # this tree against HEAD
    python tests/golden/identical.py main~3     # ... against any commit
    python tests/golden/identical.py HEAD demo-ml p40-g8-pos    # only these cases

Both trees run in fresh processes with code loaded from numba's cache
(:func:`make_golden.fit_cases_loaded`), the other commit from a temporary ``git worktree``.
Exit status 0 when identical, 1 with the first differences listed otherwise.
"""
from __future__ import annotations

import subprocess
import sys
import tempfile
from pathlib import Path

HERE = Path(__file__).resolve().parent
REPO = HERE.parents[1]
sys.path.insert(0, str(HERE))
import make_golden  # noqa: E402

#: keys whose values are wall-clock times (never identical)
TIMING_KEYS = {"seconds", "timing"}


def differences(a, b, path=""):
    """Paths where two ``result.json`` documents differ at all (list of str)."""
    if isinstance(a, dict) and isinstance(b, dict):
        out = []
        for k in sorted(set(a) | set(b)):
            if k in TIMING_KEYS:
                continue
            if k not in a or k not in b:
                out.append(f"{path}.{k}: only in {'the other commit' if k in b else 'this tree'}")
            else:
                out += differences(a[k], b[k], f"{path}.{k}")
        return out
    if isinstance(a, list) and isinstance(b, list) and len(a) == len(b):
        return [d for i, (x, y) in enumerate(zip(a, b)) for d in differences(x, y, f"{path}[{i}]")]
    return [] if a == b and type(a) is type(b) else [f"{path}: {a!r} (this tree) != {b!r}"]


def main(argv):
    rev = argv[0] if argv else "HEAD"
    names = argv[1:] or list(make_golden.FITS)
    here = make_golden.fit_cases_loaded(names, root=REPO)
    with tempfile.TemporaryDirectory() as tmp:
        tree = Path(tmp) / "tree"
        subprocess.run(["git", "-C", str(REPO), "worktree", "add", "--detach", str(tree), rev],
                       check=True, capture_output=True)
        try:
            there = make_golden.fit_cases_loaded(names, root=tree)
        finally:
            subprocess.run(["git", "-C", str(REPO), "worktree", "remove", "--force", str(tree)], check=False)
    bad = 0
    for name in names:
        diff = differences(here[name], there[name])
        bad += bool(diff)
        print(f"{name}: {'identical' if not diff else f'{len(diff)} differences'}")
        for line in diff[:10]:
            print("   ", line)
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
