"""Round values: the declared systematic sources (``*_sd`` keys) read, checked and written back."""
import pytest

from bayesdrag.errors import InputError
from bayesdrag.io.rounds import read_round, write_round
from bayesdrag.round import Projectile, Round, Systematics

BASE = """[projectile]
mass = 42.6
diameter = 0.155
{proj}
[atmosphere]
{atm}
[radar]
{radar}
"""


def _write(tmp_path, proj="", atm="", radar=""):
    p = tmp_path / "r.toml"
    p.write_text(BASE.format(proj=proj, atm=atm, radar=radar))
    return p


def test_declared_sources_round_trip(tmp_path):
    p = _write(tmp_path, "mass_sd = 0.05\ndiameter_sd = 0.0002", "density_sd = 0.002\ntemperature_sd = 0.5",
               "position_scale_sd = 1e-4\nvelocity_scale_sd = 2e-4\ntime_offset_sd = 0.002")
    rnd = read_round(p)
    want = {"mass": 0.05, "diameter": 0.0002, "density": 0.002, "temperature": 0.5,
            "position_scale": 1e-4, "velocity_scale": 2e-4, "time_offset": 0.002}
    assert rnd.systematics.declared() == want
    assert rnd.systematics.undeclared() == []
    write_round(tmp_path / "back.toml", rnd)
    assert read_round(tmp_path / "back.toml").systematics.declared() == want


def test_nothing_declared_by_default(tmp_path):
    rnd = read_round(_write(tmp_path))
    assert rnd.systematics.declared() == {}
    assert len(rnd.systematics.undeclared()) == 7


@pytest.mark.parametrize("sec,key,val,match", [
    ("atm", "density_sd", "0.5", r"\[atmosphere\] density_sd = 0.5 relative is larger .* 0.003 means 0.3 %"),
    ("atm", "temperature_sd", "-1", r"\[atmosphere\] temperature_sd"),
    ("radar", "time_offset_sd", "true", r"\[radar\] time_offset_sd"),
    ("proj", "mass_sd", "20", r"\[projectile\] mass_sd = 20 is more than 20% of the mass"),
    ("radar", "clock_sd", "0.1", r"unknown key in \[radar\] 'clock_sd'"),
])
def test_bad_sd_named(tmp_path, sec, key, val, match):
    p = _write(tmp_path, **{sec: f"{key} = {val}"}) if sec != "proj" else _write(tmp_path, proj=f"{key} = {val}")
    with pytest.raises(InputError, match=match):
        read_round(p)


def test_systematics_type_checked():
    with pytest.raises(ValueError, match="systematics must be a Systematics"):
        Round(Projectile("p", 10.0, 0.1), systematics={"density": 0.01})
    assert Systematics(density=0.01).declared() == {"density": 0.01}
