"""Declared systematic sources: the budget adds up (GUM), the temperature interpolation is exact
enough, and a declared density sd sets a floor under the Cd band (Cd is proportional to 1/rho)."""
from dataclasses import replace

import numpy as np
import pytest

from bayesdrag.air.atmosphere import Atmosphere
from bayesdrag.dynamics.pointmass import atmosphere_table
from bayesdrag.effects import temperature_nodes
from bayesdrag.estimate.cd.budget import uncertainty_budget
from bayesdrag.estimate.build import sources as S

#: interpolated temperature tables against exact ones, relative [-]
TABLE_TOL = 1e-6


def test_budget_squares_plus_cross_give_the_total():
    rng = np.random.default_rng(0)
    A = rng.standard_normal((12, 12))
    cov = A @ A.T
    B = rng.standard_normal((7, 5))
    b = uncertainty_budget(cov, B, slice(0, 5), [9, 10, 11], ["density", "temperature", "mass"])
    acc = b["by_source"]["statistical"] ** 2 + b["by_source"]["cross"]
    for k in ("density", "temperature", "mass"):
        acc = acc + b["by_source"][k] ** 2
    assert acc == pytest.approx(b["total_sd"] ** 2, rel=1e-10)
    none = uncertainty_budget(cov, B, slice(0, 5), [], [])
    assert none["by_source"]["statistical"] == pytest.approx(none["total_sd"])


def test_independent_source_share_is_its_linear_effect():
    """A source uncorrelated with the statistical part and entering Cd linearly: its share is
    |dCd/ds| sd(s) and cross is zero."""
    cov = np.diag([4e-6, 1e-6, 1e-6, 1e-6, 1e-6, 1e-6, 1e-6, 9e-6])
    cov[0, 7] = cov[7, 0] = 0.5 * np.sqrt(4e-6 * 9e-6)
    B = np.array([[1.0]])
    b = uncertainty_budget(cov, B, slice(0, 1), [7], ["density"])
    A = cov[0, 7] / cov[7, 7]
    assert b["by_source"]["density"][0] == pytest.approx(abs(A) * 3e-3)
    assert b["by_source"]["cross"][0] == pytest.approx(0.0, abs=1e-18)


def test_temperature_tables_interpolate_the_shifted_atmosphere():
    atm = Atmosphere()
    _, tabs = temperature_nodes(atm, 1.5)
    x = 0.7 / 1.5
    interp = tabs[1] + 0.5 * x * (tabs[2] - tabs[0]) + 0.5 * x * x * (tabs[2] - 2 * tabs[1] + tabs[0])
    exact = atmosphere_table(replace(atm, temperature_offset=0.7))[2]
    assert np.max(np.abs(interp / exact - 1.0)) < TABLE_TOL


def test_with_effects_leave_out_confounded_and_duplicate_quantities():
    from bayesdrag.round import Launch, Projectile, Round, Systematics

    plain = Round(Projectile(mass=42.6, diameter=0.155))
    keep, skipped = S.plan_effects(["wind", "density", "drag_scale", "coriolis", "temperature"], plain)
    assert keep == ("wind", "temperature")
    assert set(skipped) == {"density", "drag_scale", "coriolis"}
    assert "density_sd" in skipped["density"] and "latitude" in skipped["coriolis"]
    declared = Round(Projectile(mass=42.6, diameter=0.155), Launch(latitude_deg=45.0),
                     systematics=Systematics(temperature=0.5, time_offset=0.001))
    keep, skipped = S.plan_effects(["temperature", "radar_time", "coriolis"], declared)
    assert keep == ("coriolis",)
    assert "temperature_sd" in skipped["temperature"] and "time_offset_sd" in skipped["radar_time"]


def test_a_multi_parameter_effect_is_one_source():
    rng = np.random.default_rng(4)
    A = rng.standard_normal((10, 10))
    cov = A @ A.T
    B = rng.standard_normal((4, 5))
    b = uncertainty_budget(cov, B, slice(0, 5), [7, 8, 9], ["wind", "wind", "density"])
    assert set(b["by_source"]) == {"statistical", "wind", "density", "cross"}
    acc = b["by_source"]["statistical"] ** 2 + b["by_source"]["wind"] ** 2 + b["by_source"]["density"] ** 2
    assert acc + b["by_source"]["cross"] == pytest.approx(b["total_sd"] ** 2, rel=1e-10)
