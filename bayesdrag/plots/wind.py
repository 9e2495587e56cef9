"""The wind a diagnosis found (``diagnosis_wind.png``, from ``diagnosis.json`` alone) and the wind
a fit found and fitted (``wind.png``, from ``result.json``'s ``ml.with_effects.wind_layers``, beside
the met file's wind when the round has one): each layer's wx and wy with +-1 sd against height or
downrange distance."""
from __future__ import annotations

import numpy as np

from .common import new_axes
from ..effects import WIND, WIND_PROFILE

__all__ = ["plot_found_wind", "plot_fitted_wind", "wind_layer_table"]


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
    _draw_layers(ax, table, axis, "wind found")
    return ax


def plot_fitted_wind(wind_layers, met=None, ax=None):
    """The layers of wind a fit found and fitted (``ml.with_effects.wind_layers`` of
    ``result.json``): wx and wy of each layer with +-1 sd (the sd the fit stands by), and the met
    file's wind dashed beside them when the round has one. The layers are fitted beyond the
    round's own wind, so with a met file each is drawn as the met's mean over the layer plus what
    the fit found there: the wind the shell flew through.

    Parameters
    ----------
    wind_layers : dict
        ``axis``, ``layers`` (``from``, ``to``, ``wx``, ``wx_sd``, ``wy``, ``wy_sd``) [m, m/s].
    met : (altitudes (n,), wx (n,), wy (n,)) arrays, optional
        The round's met profile's wind [m above sea level, m/s] (drawn for a wind by height).
    ax : matplotlib Axes, optional

    Returns
    -------
    matplotlib Axes
    """
    ax = new_axes(ax, (6, 4.5))
    table = [{"layer": k + 1, "from": r["from"], "to": r["to"], "wx": r["wx"], "sd_wx": r.get("wx_sd"),
              "wy": r["wy"], "sd_wy": r.get("wy_sd")} for k, r in enumerate(wind_layers.get("layers") or [])]
    if not table:
        ax.set(title="no layers of wind fitted")
        ax.set_axis_off()
        return ax
    axis = wind_layers.get("axis")
    title = "wind found and fitted"
    if met is not None and axis == "altitude":
        z, wx, wy = (np.asarray(a, float) for a in met)
        top = float(table[-1]["to"])
        keep = z <= top + 0.25 * (top - float(table[0]["from"]))
        ax.plot(wx[keep], z[keep], color="C0", ls="--", lw=1.2, label="wx, met file")
        ax.plot(wy[keep], z[keep], color="C1", ls="--", lw=1.2, label="wy, met file")
        for r in table:        # the met's mean over the layer plus the fitted departure
            hs = np.linspace(float(r["from"]), float(r["to"]), 21)
            r["wx"] = r["wx"] + float(np.mean(np.interp(hs, z, wx)))
            r["wy"] = r["wy"] + float(np.mean(np.interp(hs, z, wy)))
        title = "met file + the wind fitted beyond it"
    _draw_layers(ax, table, axis, title)
    return ax


def _draw_layers(ax, table, axis, title):
    """Steps of each layer's wx and wy with +-1 sd shaded, against height (vertical axis, as met
    profiles are drawn) or downrange distance, on ``ax``."""
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
        ax.set(xlabel="wind [m/s]", ylabel="height above sea level [m]", title=f"{title}, by height (+-1 sd)")
    else:
        ax.axhline(0.0, color="0.5", lw=0.8)
        ax.set(xlabel="downrange distance [m]", ylabel="wind [m/s]", title=f"{title}, by downrange distance (+-1 sd)")
    ax.grid(alpha=0.3)
    ax.legend(fontsize="small")
