"""Fixed figure layouts and figures rendered in a forked process (issue 31)."""
import os

import numpy as np
import pytest

from bayesdrag.plots.common import Margins, fixed_figure
from bayesdrag.report import render

#: axes positions agree with the margins to this many inches (float round-off only)
POSITION_TOL_IN = 1e-9
PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def test_fixed_figure_places_the_axes_by_the_margins_in_inches():
    m = Margins(left=1.0, right=0.5, bottom=0.6, top=0.4, wgap=0.7, hgap=0.3)
    fig = fixed_figure((10, 6), 2, 3, m)
    assert fig.get_layout_engine() is None                   # nothing solved at draw time
    boxes = np.array([ax.get_position().bounds for ax in fig.axes]) * [10, 6, 10, 6]   # inches
    left, bottom, width, height = boxes.T
    assert left.min() == pytest.approx(m.left, abs=POSITION_TOL_IN)
    assert (left + width).max() == pytest.approx(10 - m.right, abs=POSITION_TOL_IN)
    assert bottom.min() == pytest.approx(m.bottom, abs=POSITION_TOL_IN)
    assert (bottom + height).max() == pytest.approx(6 - m.top, abs=POSITION_TOL_IN)
    assert left[1] - (left[0] + width[0]) == pytest.approx(m.wgap, abs=POSITION_TOL_IN)
    assert bottom[0] - (bottom[3] + height[3]) == pytest.approx(m.hgap, abs=POSITION_TOL_IN)


def test_fixed_figure_refuses_margins_larger_than_the_figure():
    with pytest.raises(ValueError, match="too small"):
        fixed_figure((2, 2), 3, 3, Margins(wgap=1.0))


def _line_figure():
    fig = fixed_figure((4, 3))
    fig.axes[0].plot([0, 1, 2], [1, 0, 2])
    return fig


@pytest.mark.skipif(not hasattr(os, "fork"), reason="no fork on this platform")
def test_forked_rendering_writes_the_same_png_as_rendering_here(tmp_path, monkeypatch):
    monkeypatch.setattr(render, "free_core", lambda: True)
    with render.rendered_elsewhere([("a.png", _line_figure, None), ("none.png", lambda: None, None)],
                                   tmp_path) as pngs:
        pass
    here = render.figure_png(_line_figure())
    assert pngs["a.png"].startswith(PNG_SIGNATURE)
    assert pngs["a.png"] == here == (tmp_path / "a.png").read_bytes()
    assert pngs["none.png"] is None and not (tmp_path / "none.png").exists()


@pytest.mark.skipif(not hasattr(os, "fork"), reason="no fork on this platform")
def test_a_figure_the_child_cannot_draw_is_drawn_here(tmp_path, monkeypatch):
    parent = os.getpid()

    def only_here():
        if os.getpid() != parent:
            raise RuntimeError("the forked renderer fails")
        return _line_figure()

    monkeypatch.setattr(render, "free_core", lambda: True)
    with render.rendered_elsewhere([("b.png", only_here, None)], tmp_path) as pngs:
        pass
    assert pngs["b.png"] == (tmp_path / "b.png").read_bytes() == render.figure_png(_line_figure())


def test_without_a_free_core_the_figures_are_drawn_after_the_body(tmp_path, monkeypatch):
    monkeypatch.setattr(render, "free_core", lambda: False)
    order = []

    def make():
        order.append("figure")
        return _line_figure()

    with render.rendered_elsewhere([("c.png", make, None)], tmp_path) as pngs:
        order.append("body")
    assert order == ["body", "figure"] and pngs["c.png"].startswith(PNG_SIGNATURE)


@pytest.mark.skipif(not hasattr(os, "fork"), reason="no fork on this platform")
def test_an_error_in_the_body_stops_the_renderer_and_propagates(tmp_path, monkeypatch):
    monkeypatch.setattr(render, "free_core", lambda: True)
    with pytest.raises(KeyError, match="body"):
        with render.rendered_elsewhere([("d.png", _line_figure, None)], tmp_path):
            raise KeyError("body")


@pytest.mark.skipif(not hasattr(os, "fork"), reason="no fork on this platform")
def test_a_hung_renderer_is_killed_and_its_figures_drawn_here(tmp_path, monkeypatch):
    import time

    parent = os.getpid()

    def hangs_in_child():
        if os.getpid() != parent:
            time.sleep(60)
        return _line_figure()

    monkeypatch.setattr(render, "free_core", lambda: True)
    monkeypatch.setattr(render, "FORK_WAIT_SECONDS", 0.5)
    t0 = time.monotonic()
    with render.rendered_elsewhere([("e.png", hangs_in_child, None)], tmp_path) as pngs:
        pass
    assert time.monotonic() - t0 < 30          # s: far below the child's sleep
    assert pngs["e.png"] == (tmp_path / "e.png").read_bytes()


def test_no_fork_beside_other_python_threads(monkeypatch):
    import threading

    monkeypatch.setattr(os, "getloadavg", lambda: (0.0, 0.0, 0.0))
    monkeypatch.setattr(os, "cpu_count", lambda: 2)
    alone = render.free_core()
    stop = threading.Event()
    t = threading.Thread(target=stop.wait)
    t.start()
    try:
        assert render.free_core() is False
    finally:
        stop.set()
        t.join()
    assert alone is (hasattr(os, "fork") and os.sys.platform.startswith("linux") and threading.active_count() == 1)


@pytest.mark.skipif(not hasattr(os, "fork") or not os.sys.platform.startswith("linux"), reason="fork on Linux only")
def test_work_done_meanwhile_that_fails_leaves_no_child_drawing(tmp_path, monkeypatch):
    import time as _time

    monkeypatch.setattr(render, "free_core", lambda: True)
    forked = []
    fork = render._fork_renderer
    monkeypatch.setattr(render, "_fork_renderer", lambda jobs, out: forked.append(fork(jobs, out)) or forked[-1])

    def slow_figure():
        _time.sleep(30)                     # the child is still drawing when meanwhile runs

    def meanwhile():
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        with render.rendered_elsewhere([("m.png", slow_figure, None)], tmp_path, meanwhile=meanwhile):
            pass
    assert forked and forked[0]
    with pytest.raises(ChildProcessError):   # the child was killed and reaped
        os.waitpid(forked[0], os.WNOHANG)
    assert not (tmp_path / "m.png").exists()
