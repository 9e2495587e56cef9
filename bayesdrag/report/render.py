"""The one jinja2 environment of the reports, the one figure-embedding helper, number
formatting and the versions table."""
from __future__ import annotations

import base64
import contextlib
import functools
import io
import os
import platform
import signal
import warnings
from importlib.resources import files
from pathlib import Path

from .._runtime.beside import free_core
from .._runtime.garbage import paused_gc
from ..io.outputs import atomic_write, write_bytes

__all__ = ["figure_png", "png_base64", "versions", "fmt", "render_report", "rendered_elsewhere"]

#: resolution of figures written and embedded [dots per inch]
DPI = 110


def figure_png(fig, dpi=DPI):
    """PNG bytes of a matplotlib figure (rendered in memory)."""
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=dpi)
    return buf.getvalue()


@contextlib.contextmanager
def rendered_elsewhere(jobs, out, *, meanwhile=None):
    """Draw and save figures in a forked process while the body of the ``with`` runs.

    ``jobs`` is a list of ``(file name, make, dpi)``: ``make()`` returns a Figure (or None:
    nothing to draw). The ``with`` yields a dict that holds, once the body has finished,
    ``{file name: PNG bytes or None}``, each also written to ``out/<file name>``. The process
    is forked (it inherits the computed arrays: nothing is pickled or computed twice) only on
    Linux when a core is free (:func:`bayesdrag._runtime.beside.free_core`), and the child only draws with matplotlib
    (no compiled kernel, no threads). Without a fork, or when the child fails, the figures are
    drawn here after the body: the same files either way. ``meanwhile()``, when given, is
    called after the body if the child still draws (time this process would wait anyway).
    """
    out = Path(out)
    pid = _fork_renderer(jobs, out) if jobs and free_core() else None
    pngs = {}
    try:
        yield pngs
    except BaseException:
        if pid is not None:
            os.kill(pid, signal.SIGKILL)
            os.waitpid(pid, 0)
        raise
    code = None
    if pid is not None and meanwhile is not None:
        done, status = os.waitpid(pid, os.WNOHANG)
        if done:
            code = os.waitstatus_to_exitcode(status)
        else:
            try:
                meanwhile()
            except BaseException:            # a Ctrl-C (or a failure) here: no child left drawing
                os.kill(pid, signal.SIGKILL)
                os.waitpid(pid, 0)
                raise
    ok = pid is not None and (code == 0 if code is not None else _wait(pid, FORK_WAIT_SECONDS))
    for name, make, dpi in jobs:
        path = out / name
        if ok:
            pngs[name] = path.read_bytes() if path.is_file() else None    # None: the child drew nothing for it
        else:
            pngs[name] = _draw(name, make, dpi, out)


def _draw(name, make, dpi, out):
    """Draw one figure and write it to ``out/name``; its PNG bytes, or None (nothing to draw).
    The collector is paused: a figure's artists come by the thousand."""
    with paused_gc():
        fig = make()
        if fig is None:
            return None
        png = figure_png(fig, dpi or DPI)
    write_bytes(out / name, png)
    return png


#: the longest a forked renderer is waited for after the body [s]; then it is killed and its
#: figures are drawn here (a hung child never hangs the run)
FORK_WAIT_SECONDS = 30.0


def _wait(pid, seconds):
    """Wait up to ``seconds`` for child ``pid``; True when it exited with status 0 (a child still
    running then is killed)."""
    import time

    deadline = time.monotonic() + seconds
    while True:
        done, status = os.waitpid(pid, os.WNOHANG)
        if done:
            return os.waitstatus_to_exitcode(status) == 0
        if time.monotonic() > deadline:
            os.kill(pid, signal.SIGKILL)
            os.waitpid(pid, 0)
            return False
        time.sleep(0.005)


def _fork_renderer(jobs, out):
    """Fork a child that draws ``jobs`` into ``out`` and exits (0: all written); returns its
    pid, or None when the fork fails."""
    with warnings.catch_warnings():          # Python >= 3.12 warns about forking with threads alive
        warnings.simplefilter("ignore", DeprecationWarning)
        try:
            pid = os.fork()
        except OSError:
            return None
    if pid:
        return pid
    code = 1
    try:                                      # the child: draw, save, leave without cleanup handlers
        signal.signal(signal.SIGINT, signal.SIG_DFL)
        for name, make, dpi in jobs:
            _draw(name, make, dpi, out)
        code = 0
    finally:
        os._exit(code)


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
