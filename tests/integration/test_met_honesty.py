"""Met files never give a confident wrong Cd (issue 44, the met items of its catalogue).

Each case was found by an adversarial pass over 697b642 and fails there:

1. a met CSV with per-level winds disabled the model check (a shifted copy of the profile could
   not be made), so a track flown in warmer air than the file was a clean answer; the same file
   made ``diagnose``, ``--with temperature``, ``temperature_sd`` and ``plan`` end in an internal
   error;
2. a met profile on another datum (a METCM datum height in metres instead of tens of metres, a
   met CSV above another datum) flew the gun in impossible air: refused now, naming both heights;
   600 m too low (inside real weather) the answer is not clean;
10. a dense sounding (20 000 levels) is thinned to what a flight resolves;
12. a METCM after 70 kB of comments is read as a METCM; a METCM wind of 999 knots is refused in
    knots;
and the one rule for air the track contradicts (docs/fitting.md).

The flights are flown by an integrator apart from bayesdrag's (tests/fixtures/met_flight.py).
"""
import re

import numpy as np
import pytest

import bayesdrag
from bayesdrag.cli import main
from bayesdrag.io.met import MAX_MET_LEVELS
from bayesdrag.io.rounds import read_round
from bayesdrag.io.tracks import read_track
from fixtures import met_flight as M
from fixtures.judge import wrong_rows

#: a warmer day than the met file says [K]: the file's air ICAO + 8 K, the flight's + 11 K
FILE_DT, WARMER_DT = 8.0, 11.0
#: the radar's sample interval [s]: 0.1 s keeps each fit to seconds (the flight lasts 35 s)
FLIGHT_DT = 0.1


def _cli(argv, capsys):
    capsys.readouterr()
    code = main([str(a) for a in argv])
    out = capsys.readouterr()
    assert "Traceback" not in out.err and "internal error" not in out.err, out.err
    return code, out.err.strip().splitlines()


@pytest.fixture(scope="module")
def warm_day(tmp_path_factory):
    """The 155 mm flight 3 K warmer than its met CSV (which has winds per level)."""
    folder = tmp_path_factory.mktemp("warm")
    t, pos, v, mach, cd = M.fly(M.linear_wind(), WARMER_DT, dt=FLIGHT_DT)
    M.write_track(folder, t, pos, v, np.random.default_rng(1))
    M.write_met_csv(folder, FILE_DT, wind=True)
    return folder, M.write_round(folder, "met.csv")


def _not_confidently_wrong(res):
    """No determined row wrong by DESIGN's rule, or the answer is not clean (and says why)."""
    bad = wrong_rows(res.cd, M.Truth(), keep=res.cd.determined)
    head = res.to_dict()["headline"]
    assert not bad or (not head["clean"] and head["not_clean_because"]), (head, bad[:3])


def test_a_met_csv_with_winds_keeps_the_model_check(warm_day):
    folder, rnd_path = warm_day
    rnd = read_round(rnd_path)
    assert rnd.atmosphere.wind is not None
    res = bayesdrag.fit(read_track(folder / "track.csv"), rnd, mcmc=False)
    me = res.to_dict()["ml"]["quality"]["model_error"]
    assert "diagnosis_failed" not in me, me.get("diagnosis_failed")
    assert "temperature" in me["verdict"], me["verdict"]
    _not_confidently_wrong(res)


@pytest.mark.parametrize("argv, extra", [
    (["diagnose"], ""),
    (["fit", "--no-mcmc", "--with", "temperature"], ""),
    (["fit", "--no-mcmc"], "temperature_sd = 2.0"),
    (["plan"], "temperature_sd = 2.0"),
])
def test_every_command_takes_a_met_csv_with_winds(warm_day, tmp_path, capsys, argv, extra):
    folder, _ = warm_day
    rnd = M.write_round(tmp_path, str(folder / "met.csv"), extra=extra)
    track = [] if argv[0] == "plan" else [folder / "track.csv"]
    code, err = _cli([argv[0], *track, rnd, "-o", tmp_path / "out", *argv[1:], "-q"], capsys)
    assert code == 0, err


def test_a_check_that_could_not_run_makes_the_answer_not_clean(warm_day, monkeypatch):
    """Whatever stops the diagnosis, the answer is not clean and the reason is a warning (shown
    with ``-q``), not a note."""
    import bayesdrag.diagnosis as diagnosis

    def broken(*a, **k):
        raise ValueError("a planted failure")

    monkeypatch.setattr(diagnosis, "diagnose", broken)
    folder, rnd_path = warm_day
    res = bayesdrag.fit(read_track(folder / "track.csv"), read_round(rnd_path), mcmc=False)
    head = res.to_dict()["headline"]
    assert not head["clean"] and "could not run" in head["not_clean_because"], head
    assert any("could not run the diagnosis (ValueError: a planted failure)" in str(w) for w in res.warnings)


@pytest.mark.parametrize("how", ["metcm", "csv"])
def test_a_profile_on_another_datum_is_refused_naming_both_heights(tmp_path, capsys, how):
    """A METCM's datum height typed in metres (120 -> '120': 1 200 m) or a met CSV 1 080 m high."""
    if how == "metcm":
        profile = M.write_metcm(tmp_path, M.linear_wind(), FILE_DT, datum_typed="120")
    else:
        profile = M.write_met_csv(tmp_path, FILE_DT, shift=1080.0)
    rnd = M.write_round(tmp_path, profile)
    code, err = _cli(["simulate", rnd, "-o", tmp_path / "t.csv"], capsys)
    assert code == 2 and len(err) == 1, err
    assert re.search(r"the gun at 150 m .* lies 10\d\d m below the profile's lowest level 1[12]\d\d m"
                     r"|times the standard pressure there, beyond real weather", err[0]), err[0]


def test_a_gun_a_little_below_the_levels_is_extrapolated_with_a_note(tmp_path):
    profile = M.write_met_csv(tmp_path, FILE_DT, shift=300.0, levels=(150.0, 500.0, 1000.0, 2000.0),
                              wx=(0, 0, 0, 0), wy=(0, 0, 0, 0))
    rnd = read_round(M.write_round(tmp_path, profile))
    assert any(re.match(r"the gun at 150 m lies 300 m below the profile's lowest level 450 m", n)
               for n in rnd.atmosphere.notes), rnd.atmosphere.notes


def test_a_datum_600_m_low_is_not_a_clean_answer(tmp_path):
    """7 % in pressure is inside real weather, so the file is read; the track contradicts the
    measured air and the table is the shell's own: not clean (the one rule for air)."""
    t, pos, v, mach, cd = M.fly(M.linear_wind(), FILE_DT, dt=FLIGHT_DT)
    M.write_track(tmp_path, t, pos, v, np.random.default_rng(2))
    M.write_met_csv(tmp_path, FILE_DT, shift=-600.0)
    res = bayesdrag.fit(read_track(tmp_path / "track.csv"), read_round(M.write_round(tmp_path, "met.csv")),
                        mcmc=False)
    head = res.to_dict()["headline"]
    assert not head["clean"], head
    _not_confidently_wrong(res)


def test_a_dense_sounding_is_thinned_to_what_a_flight_resolves(tmp_path):
    """Structural: whatever the file holds, at most MAX_MET_LEVELS levels are flown."""
    for n in (20_000, 200_000):
        z = np.linspace(150.0, 5000.0, n)
        from bayesdrag.air.atmosphere import standard_atmosphere
        s = standard_atmosphere(z, temperature_offset=FILE_DT, gun_altitude=150.0)
        body = "".join(f"{a:.2f},{b:.2f},{c:.1f},-3,1\n" for a, b, c in zip(z, s.temperature, s.pressure))
        (tmp_path / "met.csv").write_text("altitude,temperature,pressure,wind_x,wind_y\n" + body)
        rnd = read_round(M.write_round(tmp_path, "met.csv"))
        assert len(rnd.atmosphere.altitude) <= MAX_MET_LEVELS and len(rnd.atmosphere.wind.levels) <= MAX_MET_LEVELS
        assert any(f"{n} levels thinned to" in note for note in rnd.atmosphere.notes)
        # the thinned air is the file's: the kept levels are its own rows
        assert set(rnd.atmosphere.altitude) <= set(np.round(z, 2))


def test_a_metcm_after_70_kb_of_comments_is_a_metcm(tmp_path):
    profile = M.write_metcm(tmp_path, M.linear_wind(), FILE_DT)
    text = (tmp_path / profile).read_text()
    (tmp_path / profile).write_text("".join(f"# comment line {k:06d} of a long preamble\n" for k in range(2000))
                                    + text)
    assert (tmp_path / profile).stat().st_size > 70_000
    rnd = read_round(M.write_round(tmp_path, profile))
    assert rnd.atmosphere.wind is not None and "METCM" in rnd.atmosphere.stated_error.why


def test_a_metcm_wind_of_999_knots_is_refused_in_knots(tmp_path, capsys):
    profile = M.write_metcm(tmp_path, M.linear_wind(), FILE_DT)
    lines = (tmp_path / profile).read_text().splitlines()
    lines[3] = lines[3][:5] + "999" + lines[3][8:]
    (tmp_path / profile).write_text("\n".join(lines) + "\n")
    code, err = _cli(["simulate", M.write_round(tmp_path, profile), "-o", tmp_path / "t.csv"], capsys)
    assert code == 2 and len(err) == 1 and re.search(r"line 4: wind speed 999 knots .* in knots", err[0]), err


def test_a_met_files_own_error_is_stated(tmp_path):
    """A METCM states its resolution and the default wind sd; a met CSV the resolution its
    numbers were written to."""
    from bayesdrag.air.atmosphere import MET_WIND_SD_DEFAULT

    rnd = read_round(M.write_round(tmp_path, M.write_metcm(tmp_path, M.linear_wind(), FILE_DT)))
    err = rnd.atmosphere.stated_error
    assert err.wind_sd == MET_WIND_SD_DEFAULT
    assert err.temperature_sd == pytest.approx(0.1 / 12 ** 0.5)
    assert err.density_sd == pytest.approx(100.0 / 12 ** 0.5 / rnd.atmosphere.pressure[0])
    rnd = read_round(M.write_round(tmp_path, M.write_met_csv(tmp_path, FILE_DT, wind=False)))
    err = rnd.atmosphere.stated_error
    assert err.wind_sd is None and err.temperature_sd == pytest.approx(0.01 / 12 ** 0.5)


def test_a_metcms_own_error_is_in_the_band(tmp_path):
    """Item 13: a head wind growing with height, fitted with the day's METCM and no wind_sd. The
    band carries the message's winds (1 m/s), temperatures and pressures (its resolution), and
    holds the truth (the slow suite, run_met_bands.py, measures its coverage)."""
    def growing(alt):
        h = min(max(alt - M.GUN_ALTITUDE, 0.0), 3000.0)
        return (-2.0 - 10.0 * (1.0 - np.cos(np.pi * h / 3000.0)) / 2.0, 1.0)

    t, pos, v, mach, cd = M.fly(growing, FILE_DT, qe=40.0, dt=FLIGHT_DT)
    M.write_track(tmp_path, t, pos, v, np.random.default_rng(4))
    rnd = read_round(M.write_round(tmp_path, M.write_metcm(tmp_path, growing, FILE_DT), qe=40.0))
    res = bayesdrag.fit(read_track(tmp_path / "track.csv"), rnd, mcmc=False)
    budget = res.to_dict()["uncertainty_budget"]
    assert {"wind_profile", "density", "temperature"} <= set(budget["by_source"]), budget["by_source"].keys()
    assert budget["met_file"]["sources"] == ["density", "temperature", "wind_profile"]
    assert not set(budget["met_file"]["sources"]) & set(budget["conditional_on"])
    assert not wrong_rows(res.cd, M.Truth(), keep=res.cd.determined)
