"""The one jinja2 environment of the reports, the one figure-embedding helper, number
formatting and the versions table."""
from __future__ import annotations

import base64
import functools
import io
import platform
from importlib.resources import files
from pathlib import Path

from ..io.outputs import atomic_write

__all__ = ["figure_png", "png_base64", "versions", "fmt", "render_report"]

#: resolution of figures written and embedded [dots per inch]
DPI = 110


def figure_png(fig, dpi=DPI):
    """PNG bytes of a matplotlib figure (rendered in memory)."""
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=dpi)
    return buf.getvalue()


def png_base64(png):
    """Base64 text of PNG bytes, for ``<img src="data:image/png;base64,...">``."""
    return base64.b64encode(png).decode("ascii")


def versions():
    """Versions of Python and the libraries a result depends on."""
    import importlib.metadata as md

    out = {"python": platform.python_version()}
    for pkg in ("bayesdrag", "numpy", "scipy", "numba", "emcee", "arviz", "corner", "matplotlib"):
        try:
            out[pkg] = md.version(pkg)
        except md.PackageNotFoundError:
            out[pkg] = "not installed"
    return out


def fmt(v, digits=5):
    """Number formatting for tables: significant digits, '—' for None/NaN."""
    if v is None:
        return "—"
    if isinstance(v, str):
        return v
    try:
        x = float(v)
    except (TypeError, ValueError):
        return str(v)
    if x != x:
        return "—"
    return f"{x:.{digits}g}"


@functools.lru_cache(maxsize=1)
def _environment():
    """The reports' jinja2 environment: templates from ``bayesdrag/templates``, autoescaped,
    undefined names are errors (a template and its context never drift apart silently)."""
    import jinja2

    env = jinja2.Environment(loader=jinja2.FunctionLoader(_load_template), autoescape=True,
                             undefined=jinja2.StrictUndefined)
    env.filters["fmt"] = fmt
    return env


def _load_template(name):
    return (files("bayesdrag") / "templates" / name).read_text(encoding="utf-8")


def render_report(path, context, template="report.html.j2"):
    """Render ``template`` with ``context`` to ``path`` atomically.

    ``context['figures']`` is a list of ``{"title", "caption", "png"}`` with ``png`` a base64
    string (:func:`png_base64`). Returns the HTML text.
    """
    html = _environment().get_template(template).render(**context)
    atomic_write(path, lambda tmp: Path(tmp).write_text(html, encoding="utf-8"))
    return html
