"""The wind a diagnosis found (``diagnosis_wind.png``): the verdict's wind against height or
downrange distance, each layer's wx and wy with +-1 sd, from ``diagnosis.json`` alone."""
from __future__ import annotations

import numpy as np

from .common import new_axes
from ..effects import WIND, WIND_PROFILE

__all__ = ["plot_found_wind", "wind_layer_table"]


def wind_layer_table(s):
    """The verdict's wind as rows of a table: ``[{"layer", "from", "to", "wx", "sd_wx", "wy",
    "sd_wy"}]`` [m, m/s] (one row for a constant wind, ``from``/``to`` None), with the axis
    (``"altitude"``, ``"downrange"`` or None) -- or ``([], None)`` without a wind in the verdict.

    Parameters
    ----------
    s : dict
        ``diagnosis.json``.

    Returns
    -------
    (list of dict, str or None)
    """
    rows = {r["name"]: r for r in s.get("effects") or []}
    verdict = s.get("verdict") or []
    if WIND_PROFILE.name in verdict:
        r = rows[WIND_PROFILE.name]
        pv = r.get("params_joint") or r["params"]
        sd = r.get("sd_joint") or r["sd"]
        e = r["layers"]["edges"]
        out = []
        for k in range(1, len(e)):
            wy_key = f"wy_{k}" if f"wy_{k}" in pv else "wy_1"
            out.append({"layer": k, "from": e[k - 1], "to": e[k], "wx": pv.get(f"wx_{k}"), "sd_wx": sd.get(f"wx_{k}"),
                        "wy": pv.get(wy_key), "sd_wy": sd.get(wy_key)})
        return out, r["layers"]["axis"]
    if WIND.name in verdict:
        r = rows[WIND.name]
        pv = r.get("params_joint") or r["params"]
        sd = r.get("sd_joint") or r["sd"]
        return [{"layer": 1, "from": None, "to": None, "wx": pv["wx"], "sd_wx": sd.get("wx"), "wy": pv.get("wy"),
                 "sd_wy": sd.get("wy")}], None
    return [], None


def plot_found_wind(s, ax=None):
    """The verdict's wind: wx and wy of each layer (steps) with +-1 sd shaded, against height
    above sea level (a wind by height: height on the vertical axis, as met profiles are drawn) or
    against downrange distance; a constant wind as one band.

    Parameters
    ----------
    s : dict
        ``diagnosis.json``.
    ax : matplotlib Axes, optional

    Returns
    -------
    matplotlib Axes (empty, titled so, without a wind in the verdict)
    """
    ax = new_axes(ax, (6, 4.5))
    table, axis = wind_layer_table(s)
    if not table:
        ax.set(title="no wind in the verdict")
        ax.set_axis_off()
        return ax
    if axis is None:
        r = table[0]
        for key, c in (("wx", "C0"), ("wy", "C1")):
            v, e = r[key] or 0.0, r[f"sd_{key}"] or 0.0
            ax.axvspan(v - e, v + e, color=c, alpha=0.25)
            ax.axvline(v, color=c, label=f"{key} = {v:.3g} m/s")
        ax.set(xlabel="wind [m/s] (constant)", yticks=[], title="wind found (constant)")
        ax.legend(fontsize="small")
        return ax
    edges = np.array([table[0]["from"]] + [r["to"] for r in table], float)
    for key, c in (("wx", "C0"), ("wy", "C1")):
        v = np.array([r[key] if r[key] is not None else np.nan for r in table], float)
        e = np.array([r[f"sd_{key}"] if r[f"sd_{key}"] is not None else 0.0 for r in table], float)
        vs, es = np.repeat(v, 2), np.repeat(e, 2)
        pos = np.repeat(edges, 2)[1:-1]
        label = {"wx": "wx (tail +)", "wy": "wy (toward +y, right)"}[key]
        if axis == "altitude":
            ax.fill_betweenx(pos, vs - es, vs + es, color=c, alpha=0.25)
            ax.plot(vs, pos, color=c, label=label)
        else:
            ax.fill_between(pos, vs - es, vs + es, color=c, alpha=0.25)
            ax.plot(pos, vs, color=c, label=label)
    if axis == "altitude":
        ax.axvline(0.0, color="0.5", lw=0.8)
        ax.set(xlabel="wind [m/s]", ylabel="height above sea level [m]", title="wind found, by height (+-1 sd)")
    else:
        ax.axhline(0.0, color="0.5", lw=0.8)
        ax.set(xlabel="downrange distance [m]", ylabel="wind [m/s]", title="wind found, by downrange distance (+-1 sd)")
    ax.grid(alpha=0.3)
    ax.legend(fontsize="small")
    return ax
