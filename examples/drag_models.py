"""Figure and numbers for docs/foundation.md: how each drag model follows the M101 curve.

    python examples/drag_models.py   # writes docs/figures/drag_models_m101.png, prints errors
"""
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from bayesdrag.io.drag_tables import load_m101
from bayesdrag.drag import make_drag_model


def main(out=Path(__file__).resolve().parents[1] / "docs" / "figures" / "drag_models_m101.png"):
    m101 = load_m101()
    m = np.linspace(0.5, 2.6, 2101)
    cd = m101.value(m)
    fig, (a1, a2) = plt.subplots(2, 1, figsize=(7, 7), sharex=True, layout="constrained")
    a1.plot(m, cd, "k", lw=2.5, label="M101 (BRL MR-1167)")
    for name in ("poly2", "poly2-split", "spline"):
        mod = make_drag_model(name, mach_range=(0.5, 2.6))
        if name == "spline":
            theta, _ = mod.fit_curve(m, cd)
        else:  # least squares in relative error
            theta = np.linalg.lstsq(mod.basis(m) / cd[:, None], np.ones_like(cd), rcond=None)[0]
        rel = mod.cd(theta, m) / cd - 1
        print(f"{name:12s} {mod.n_params:2d} parameters: max |relative error| {np.abs(rel).max():.4f}")
        a1.plot(m, mod.cd(theta, m), label=f"{name} ({mod.n_params} par.)")
        a2.plot(m, 100 * rel, label=name)
    for k in make_drag_model("spline", mach_range=(0.5, 2.6)).knots:
        a2.axvline(k, color="C2", lw=0.5, alpha=0.5)
    a1.set(ylabel="Cd", title="drag models fitted to the M101 curve")
    a1.legend(fontsize="small")
    a2.set(xlabel="Mach", ylabel="model / M101 - 1 [%]", ylim=(-5, 5))
    a2.axhspan(-0.3, 0.3, color="0.8", label="±0.3 %")
    a2.legend(fontsize="small")
    fig.savefig(out, dpi=110)
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
