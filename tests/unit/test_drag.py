"""Drag models: values, linearity, kernel tables, the spline's fit of the M101 curve."""
import numpy as np
import pytest

from bayesdrag.drag import MachGrid, Poly2, Poly2Split, ReferenceScale, ReferenceTable, Spline, default_spline_knots, make_drag_model
from bayesdrag.io.drag_tables import read_drag_table
from bayesdrag.errors import InputError

KERNEL_TABLE_ATOL = 1e-10   # Cd: the kernel's cubic cells reproduce each model exactly
SPLINE_M101_RTOL = 0.003    # issue 3: the spline follows M101 to 0.3 %


def _eval_table(tab, grid, m):
    k = np.clip(((m - grid.m0) / grid.dm).astype(int), 0, grid.n_cells - 1)
    u = np.clip(m - (grid.m0 + k * grid.dm), 0, grid.dm)
    c = tab[..., k, :]
    return c[..., 0] + u * (c[..., 1] + u * (c[..., 2] + u * c[..., 3]))


def test_poly2_values():
    assert Poly2().cd([0.5, -0.1, 0.02], 2.0) == pytest.approx(0.5 - 0.2 + 0.08)


def test_poly2_split_pieces_and_jump():
    th = [0.15, 0.0, 0.0, 0.6, -0.2, 0.03]
    mod = Poly2Split()
    assert mod.cd(th, 0.8) == pytest.approx(0.15)
    assert mod.cd(th, 1.5) == pytest.approx(0.6 - 0.3 + 0.0675)
    grid = MachGrid(0.0, 0.01, 300)
    m = np.array([0.999999, 1.0, 1.000001])
    assert np.allclose(_eval_table(mod.kernel_table(th, grid), grid, m), mod.cd(th, m), atol=1e-5)


@pytest.mark.parametrize("name", ["poly2", "poly2-split", "spline", "reference-scale"])
def test_kernel_table_exact(name, m101):
    mod = make_drag_model(name, reference=m101, mach_range=(0.5, 2.6))
    grid = MachGrid.covering(0.5, 2.6)
    th = mod.initial_params(m101)
    m = np.linspace(0.5, 2.6, 7777)
    assert np.max(np.abs(_eval_table(mod.kernel_table(th, grid), grid, m) - mod.cd(th, m))) < KERNEL_TABLE_ATOL
    # batched tables agree with single ones
    th2 = np.stack([th, th * 1.01])
    tabs = mod.kernel_table(th2, grid)
    assert tabs.shape == (2, grid.n_cells, 4)
    assert np.allclose(_eval_table(tabs[1], grid, m), mod.cd(th * 1.01, m), atol=KERNEL_TABLE_ATOL)


def test_reference_table_kernel_exact(m101):
    grid = MachGrid.covering(0.5, 2.6)
    m = np.linspace(0.3, 3.0, 5001)
    assert np.max(np.abs(_eval_table(m101.kernel_table((), grid), grid, m) - m101.value(m))) < KERNEL_TABLE_ATOL
    # held constant outside the table
    assert m101.value(0.2) == pytest.approx(m101.value(0.5))
    assert m101.value(3.0) == pytest.approx(m101.value(2.6))


@pytest.mark.parametrize("name", ["poly2", "poly2-split", "spline", "reference-scale"])
def test_linear_in_parameters(name, m101, rng):
    mod = make_drag_model(name, reference=m101, mach_range=(0.6, 2.4))
    m = np.linspace(0.6, 2.4, 50)
    a, b = rng.normal(size=mod.n_params), rng.normal(size=mod.n_params)
    assert np.allclose(mod.cd(a + 2 * b, m), mod.cd(a, m) + 2 * mod.cd(b, m))
    assert np.allclose(mod.jacobian(m) @ a, mod.cd(a, m))
    # batch evaluation
    assert mod.cd(np.stack([a, b]), m).shape == (2, 50)
    # the scalar curve used by the scipy backend agrees
    f = mod.curve(a)
    assert f(1.37) == pytest.approx(float(mod.cd(a, 1.37)), rel=1e-12)


def test_spline_follows_m101(m101):
    """Default knots (double at the drag-rise onset, steepest part and top) follow M101 to
    0.3 % over Mach 0.5-2.6 with 18 coefficients (minimax fit)."""
    mod = make_drag_model("spline", mach_range=(0.5, 2.6))
    m = np.linspace(0.5, 2.6, 1051)
    theta, err = mod.fit_curve(m, m101.value(m))
    fine = np.linspace(0.5, 2.6, 20001)
    rel = np.abs(mod.cd(theta, fine) / m101.value(fine) - 1)
    assert rel.max() < SPLINE_M101_RTOL
    assert mod.n_params <= 18
    # and the quadratic cannot: it errs by tens of percent across the transonic rise
    p2 = Poly2()
    th2 = np.linalg.lstsq(p2.basis(fine) / m101.value(fine)[:, None], np.ones_like(fine), rcond=None)[0]
    assert np.max(np.abs(p2.cd(th2, fine) / m101.value(fine) - 1)) > 0.15


def test_default_knots_inside_span():
    k = default_spline_knots(1.2, 2.4)
    assert k[0] == pytest.approx(1.2) and k[-1] == pytest.approx(2.4)
    assert np.all(np.diff(k) >= 0)
    assert np.allclose(np.round(k / 0.01) * 0.01, k)


@pytest.mark.parametrize("knots, match", [
    ((1.0,), ">= 2 finite"),
    ((1.0, 0.5), "non-decreasing"),
    ((0.5, 0.9, 0.9, 0.9, 2.0), "at most twice"),
])
def test_spline_bad_knots(knots, match):
    with pytest.raises(ValueError, match=match):
        Spline(knots)


def test_reference_scale(m101):
    mod = ReferenceScale(m101)
    assert mod.cd([1.1], 2.0) == pytest.approx(1.1 * float(m101.value(2.0)))
    with pytest.raises(ValueError, match="needs a reference drag table"):
        ReferenceScale(None)
    with pytest.raises(ValueError, match="reference_drag"):
        make_drag_model("reference-scale")


def test_unknown_model():
    with pytest.raises(ValueError, match="allowed: poly2, poly2-split, spline, reference-scale"):
        make_drag_model("g7")


@pytest.mark.parametrize("text, match", [
    ("mach,cd\n0.5,0.2\n0.5,0.3\n", "increase strictly"),
    ("mach,cd\n0.5,0.2\n0.6,-0.3\n", "0 < cd"),
    ("mach,cd\n0.5,0.2\n", "at least|>= 2"),
    ("mach,cdx\n0.5,0.2\n0.6,0.3\n", "cd"),
])
def test_bad_drag_tables(tmp_path, text, match):
    f = tmp_path / "cd.csv"
    f.write_text(text)
    with pytest.raises(InputError, match=match):
        read_drag_table(f)


def test_read_m101(m101):
    assert isinstance(m101, ReferenceTable)
    assert m101.mach_range == (0.5, 2.6)
    assert m101.value(0.7) == pytest.approx(0.147462, rel=1e-6)


def test_shaped_table_is_a_class_and_the_table_cells_are_memoised(m101):
    """A decorator left above a moved class made ``ShapedTable`` a cached function (isinstance
    failed) and the table's kernel cells were rebuilt on every simulation."""
    from bayesdrag.drag import ShapedTable, _cached_reference_cells
    from bayesdrag.effects.drag import drag_shape_model

    shape = drag_shape_model(m101, (0.8, 2.2))
    assert isinstance(shape, ShapedTable)
    grid = MachGrid.covering(0.8, 2.2)
    assert _cached_reference_cells(m101, grid) is _cached_reference_cells(m101, grid)
    assert not _cached_reference_cells(m101, grid).flags.writeable
