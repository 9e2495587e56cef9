"""Self-contained HTML reports (jinja2): figures embedded as base64 PNG, no external files,
scripts or fonts, so a report opens offline and can be mailed as one file.

No physics and no fitting here: the caller passes plain values and matplotlib figures."""
from __future__ import annotations

import base64
import io
import platform
from importlib.resources import files
from pathlib import Path


def figure_to_base64(fig, dpi=100):
    """PNG bytes of a matplotlib figure as a base64 string (the figure is closed)."""
    import matplotlib.pyplot as plt

    buf = io.BytesIO()
    try:
        fig.savefig(buf, format="png", dpi=dpi)
    finally:
        plt.close(fig)
    return base64.b64encode(buf.getvalue()).decode("ascii")


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


def render_report(path, context, template="report.html.j2"):
    """Render ``template`` (in ``bayesdrag/templates``) with ``context`` to ``path``
    atomically.

    ``context['figures']`` is a list of ``{"title", "caption", "png"}`` with ``png`` a base64
    string (see :func:`figure_to_base64`). Returns the HTML text.
    """
    import jinja2

    from .outputs import atomic_write

    env = jinja2.Environment(loader=jinja2.FunctionLoader(_load_template), autoescape=True,
                             undefined=jinja2.StrictUndefined)
    env.filters["fmt"] = fmt
    html = env.get_template(template).render(**context)
    atomic_write(path, lambda tmp: Path(tmp).write_text(html, encoding="utf-8"))
    return html


def _load_template(name):
    return (files("bayesdrag") / "templates" / name).read_text(encoding="utf-8")
