"""Tests of bayesdrag.track: reading, validating and writing tracks (CSV) and rounds (TOML)."""
import math
import time

import numpy as np
import pytest

from bayesdrag.air.atmosphere import Atmosphere
from bayesdrag.drag import ReferenceTable
from bayesdrag.io.drag_tables import read_drag_table
from bayesdrag.errors import InputError
from bayesdrag.track import CHANNELS, RadarTrack
from bayesdrag.round import DEFAULT_ELEVATION_SD_DEG, DEFAULT_POSITION_SD, DEFAULT_VELOCITY_SD, Launch, Projectile, Radar, Round
from bayesdrag.io.csv import read_csv_columns
from bayesdrag.io.rounds import read_round, write_round
from bayesdrag.io.tracks import read_track, write_track

G = 9.80665
#: write_track keeps 6 decimals of t and 4 of the channels
T_TOL_S = 1e-6
POS_TOL_M = 1e-4

EXAMPLE_TRACK = """\
# radar track, SI units
t,x,y,z,v
0.000,0.00,0.00,0.00,818.00
0.027,21.90,0.00,2.69,816.70
0.054,43.76,0.01,5.37,815.41
"""


def vacuum_track(n=200, dt=0.027, v0=818.0, elev_deg=15.0, t0=0.0):
    """A drag-free trajectory: exact positions and speed (m, m/s)."""
    t = t0 + dt * np.arange(n)
    th = math.radians(elev_deg)
    vx, vz0 = v0 * math.cos(th), v0 * math.sin(th)
    x = vx * t
    z = vz0 * t - 0.5 * G * t**2
    v = np.hypot(vx, vz0 - G * t)
    return t, {"x": x, "y": 0.01 * x, "z": z, "v": v}


def write_csv(tmp_path, text, name="track.csv"):
    p = tmp_path / name
    p.write_text(text, encoding="utf-8")
    return p


def csv_of(t, cols, names=None):
    names = names or list(cols)
    lines = [",".join(["t", *names])]
    for i in range(len(t)):
        lines.append(",".join([f"{t[i]:.6f}", *(f"{cols[k][i]:.4f}" for k in names)]))
    return "\n".join(lines) + "\n"


# ------------------------------------------------------------------------------------------
# reading and writing tracks
# ------------------------------------------------------------------------------------------
def test_read_example_track(tmp_path):
    tr = read_track(write_csv(tmp_path, EXAMPLE_TRACK))
    assert tr.names == CHANNELS
    assert tr.n == len(tr) == 3
    np.testing.assert_array_equal(tr.t, [0.0, 0.027, 0.054])
    np.testing.assert_array_equal(tr.x, [0.0, 21.9, 43.76])
    np.testing.assert_array_equal(tr.y, [0.0, 0.0, 0.01])
    np.testing.assert_array_equal(tr.z, [0.0, 2.69, 5.37])
    np.testing.assert_array_equal(tr.v, [818.0, 816.7, 815.41])
    assert tr.extra == {} and tr.notes == ()
    assert tr.source.endswith("track.csv")


def test_partial_channels_and_column_order(tmp_path):
    tr = read_track(write_csv(tmp_path, "v,t,z\n818,0.0,0\n817,0.1,8\n816,0.2,16\n"))
    assert tr.names == ("z", "v")  # canonical order whatever the file order
    assert tr.x is None and tr.y is None
    np.testing.assert_array_equal(tr.t, [0.0, 0.1, 0.2])
    np.testing.assert_array_equal(tr.z, [0.0, 8.0, 16.0])


def test_comments_blank_lines_crlf_bom_and_spaces(tmp_path):
    text = "\ufeff# header comment\r\n\r\n t , v \r\n0.0, 818.0\r\n# mid comment\r\n0.5 ,817.5\r\n\r\n"
    tr = read_track(write_csv(tmp_path, text))
    np.testing.assert_array_equal(tr.t, [0.0, 0.5])
    np.testing.assert_array_equal(tr.v, [818.0, 817.5])


def test_extra_columns_kept_with_note(tmp_path):
    tr = read_track(write_csv(tmp_path, "t,x,gain,rdot\n0,0,20,800\n0.1,80,19.5,799\n"))
    assert tr.names == ("x",)
    assert set(tr.extra) == {"gain", "rdot"}
    np.testing.assert_array_equal(tr.extra["gain"], [20.0, 19.5])
    assert len(tr.notes) == 1 and "gain, rdot" in tr.notes[0] and "ignored" in tr.notes[0]
    # an snr column is not ignored: it weights each sample (docs/radar.md)
    tr = read_track(write_csv(tmp_path, "t,x,snr,rdot\n0,0,20,800\n0.1,80,19.5,799\n"))
    assert [n for n in tr.notes if "ignored" in n] == [f"{tr.source}: extra column(s) rdot kept but ignored by the fit"]
    assert any("snr give each sample's noise" in n for n in tr.notes)


def test_write_read_round_trip(tmp_path):
    t, ch = vacuum_track(n=500)
    ch["y"] = ch["y"] - 0.123456  # needs 4 decimals
    track = RadarTrack(t, ch, {"snr": np.linspace(10, 20, t.size)}, source="sim")
    p = tmp_path / "out.csv"
    write_track(p, track, comment="synthetic\nsecond line")
    text = p.read_text()
    assert text.startswith("# synthetic\n# second line\nt,x,y,z,v,snr\n")
    back = read_track(p)
    assert back.names == CHANNELS
    np.testing.assert_allclose(back.t, t, atol=T_TOL_S, rtol=0)
    for k in CHANNELS:
        np.testing.assert_allclose(back.channels[k], ch[k], atol=POS_TOL_M, rtol=0)
    np.testing.assert_allclose(back.extra["snr"], track.extra["snr"], rtol=1e-9)
    # without extras and with fewer channels
    write_track(p, track.with_channels(["z", "v"]), extra=False)
    back = read_track(p)
    assert back.names == ("z", "v") and back.extra == {} and back.notes == ()
    np.testing.assert_allclose(back.z, ch["z"], atol=POS_TOL_M, rtol=0)


def test_write_track_microsecond_and_millimetre_precision(tmp_path):
    track = RadarTrack([0.0, 1.000001], {"x": [0.0, 800.0005]})
    p = tmp_path / "p.csv"
    write_track(p, track)
    back = read_track(p)
    assert back.t[1] == pytest.approx(1.000001, abs=1e-9)
    assert back.x[1] == pytest.approx(800.0005, abs=1e-9)


def test_subset_and_with_channels():
    t, ch = vacuum_track(n=10)
    tr = RadarTrack(t, ch, {"snr": np.arange(10.0)}, source="s", notes=("n",))
    sub = tr.subset(tr.t > 0.1)
    assert sub.n == 6 and sub.names == CHANNELS and sub.source == "s" and sub.notes == ("n",)
    np.testing.assert_array_equal(sub.x, ch["x"][4:])
    np.testing.assert_array_equal(sub.extra["snr"], np.arange(4.0, 10.0))
    sl = tr.subset(slice(2, 5))
    np.testing.assert_array_equal(sl.t, t[2:5])
    idx = tr.subset(np.array([0, 3, 9]))
    np.testing.assert_array_equal(idx.v, ch["v"][[0, 3, 9]])
    only_v = tr.with_channels("v")
    assert only_v.names == ("v",) and only_v.x is None and "snr" in only_v.extra
    assert tr.with_channels(["v", "x"]).names == ("x", "v")
    with pytest.raises(ValueError, match="channel.*z.*not in the track"):
        only_v.with_channels(["z"])
    with pytest.raises(ValueError, match="mask has shape"):
        tr.subset(np.ones(3, dtype=bool))


def test_radartrack_constructor_checks():
    with pytest.raises(ValueError, match="t must increase strictly"):
        RadarTrack([0.0, 0.0], {"v": [1.0, 2.0]})
    with pytest.raises(ValueError, match="unknown channel.*w"):
        RadarTrack([0.0, 1.0], {"w": [1.0, 2.0]})
    with pytest.raises(ValueError, match="at least one of the channels"):
        RadarTrack([0.0, 1.0], {})
    with pytest.raises(ValueError, match=r"shape \(3,\), expected \(2,\)"):
        RadarTrack([0.0, 1.0], {"v": [1.0, 2.0, 3.0]})
    with pytest.raises(ValueError, match="non-finite"):
        RadarTrack([0.0, 1.0], {"v": [1.0, np.nan]})


def test_read_large_track_is_fast(tmp_path):
    # 10^5 rows must read in well under a second; 2 s leaves room for a slow CI machine
    t, ch = vacuum_track(n=100_000, dt=0.001)
    p = tmp_path / "big.csv"
    write_track(p, RadarTrack(t, ch))
    start = time.perf_counter()
    tr = read_track(p)
    elapsed = time.perf_counter() - start
    assert tr.n == 100_000
    assert elapsed < 2.0


# ------------------------------------------------------------------------------------------
# track errors: one test per path
# ------------------------------------------------------------------------------------------
def test_missing_track_file(tmp_path):
    with pytest.raises(InputError, match=r"nope\.csv: track not found"):
        read_track(tmp_path / "nope.csv")


def test_track_is_directory(tmp_path):
    with pytest.raises(InputError, match="found a directory"):
        read_track(tmp_path)


def test_empty_track(tmp_path):
    with pytest.raises(InputError, match="track is empty"):
        read_track(write_csv(tmp_path, ""))


def test_only_comments(tmp_path):
    with pytest.raises(InputError, match="only comments"):
        read_track(write_csv(tmp_path, "# just a comment\n\n# another\n"))


def test_no_header(tmp_path):
    with pytest.raises(InputError, match="line 2: track has no header row; found numbers"):
        read_track(write_csv(tmp_path, "# c\n0.0,1.0,2.0\n0.1,2.0,3.0\n"))


def test_no_t_column(tmp_path):
    with pytest.raises(InputError, match="line 1: track needs a time column 't'.*header has clock, x"):
        read_track(write_csv(tmp_path, "clock,x\n0,0\n1,800\n"))     # (time, t_s are read as t)


def test_t_upper_case_hint(tmp_path):
    with pytest.raises(InputError, match="case-sensitive: found 'T'"):
        read_track(write_csv(tmp_path, "T,x\n0,0\n1,800\n"))


def test_t_but_no_channel(tmp_path):
    msg = "line 1: track has 't' but none of the channels x, y, z, v; header has t, snr"
    with pytest.raises(InputError, match=msg):
        read_track(write_csv(tmp_path, "t,snr\n0,20\n1,21\n"))


def test_duplicate_columns(tmp_path):
    with pytest.raises(InputError, match="duplicate column name 'x'"):
        read_track(write_csv(tmp_path, "t,x,x\n0,0,0\n1,800,800\n"))


def test_empty_column_name(tmp_path):
    with pytest.raises(InputError, match=r"empty column name in header \(column 3 of 3\)"):
        read_track(write_csv(tmp_path, "t,x,\n0,0,0\n1,800,800\n"))


def test_semicolon_separated(tmp_path):
    with pytest.raises(InputError, match="separated by ';'.*comma-separated"):
        read_track(write_csv(tmp_path, "t;x\n0;0\n1;800\n"))


def test_ragged_row(tmp_path):
    text = "# comment\nt,x,v\n0,0,800\n0.1,80\n"
    with pytest.raises(InputError, match=r"line 4: 2 fields, but the header has 3 \(t,x,v\)"):
        read_track(write_csv(tmp_path, text))


def test_non_numeric_field(tmp_path):
    text = "t,x,v\n0,0,800\n0.1,8O.0,799\n"
    with pytest.raises(InputError, match="line 3, column 'x': '8O.0' is not a number"):
        read_track(write_csv(tmp_path, text))


def test_empty_field(tmp_path):
    with pytest.raises(InputError, match="line 3, column 'v': empty field"):
        read_track(write_csv(tmp_path, "t,x,v\n0,0,800\n0.1,80,\n"))


@pytest.mark.parametrize("bad", ["nan", "inf", "-Infinity"])
def test_non_finite(tmp_path, bad):
    text = f"t,x,v\n0,0,800\n0.1,80,799\n0.2,{bad},798\n"
    with pytest.raises(InputError, match=f"line 4, column 'x': '{bad}' is not a finite number"):
        read_track(write_csv(tmp_path, text))


def test_time_repeats(tmp_path):
    with pytest.raises(InputError, match="line 4: t = 0.1 s repeats the previous row's time"):
        read_track(write_csv(tmp_path, "t,v\n0,800\n0.1,799\n0.1,798\n"))


def test_time_goes_back(tmp_path):
    with pytest.raises(InputError, match="line 5: t = 0.15 s goes back from 0.2 s on line 4"):
        read_track(write_csv(tmp_path, "t,v\n0,800\n0.1,799\n0.2,798\n0.15,797\n"))


def test_binary_garbage(tmp_path):
    p = tmp_path / "garbage.csv"
    p.write_bytes(b"t,x\n0,0\n\x89PNG\xff\xfe\x00\x10")
    with pytest.raises(InputError, match="not UTF-8 text: undecodable byte 0x89 at line 3"):
        read_track(p)


def test_nul_bytes(tmp_path):
    p = tmp_path / "nul.csv"
    p.write_bytes(b"t,x\n0,0\x00\x00\n")
    with pytest.raises(InputError, match="NUL bytes at line 2"):
        read_track(p)


def test_utf16(tmp_path):
    p = tmp_path / "u16.csv"
    p.write_bytes("t,x\n0,0\n1,800\n".encode("utf-16"))
    with pytest.raises(InputError, match="UTF-16"):
        read_track(p)


def test_fewer_than_two_rows(tmp_path):
    with pytest.raises(InputError, match="track has 1 data row; at least 2 are needed"):
        read_track(write_csv(tmp_path, "t,v\n0,800\n"))


def test_header_without_rows(tmp_path):
    with pytest.raises(InputError, match=r"has a header \(line 2\) but no data rows"):
        read_track(write_csv(tmp_path, "# c\nt,v\n# nothing\n"))


def test_negative_speed(tmp_path):
    with pytest.raises(InputError, match="line 3: v = -799 m/s is negative"):
        read_track(write_csv(tmp_path, "t,v\n0,800\n0.1,-799\n"))


# ---- unit mistakes ------------------------------------------------------------------------
@pytest.mark.parametrize("scale, expect", [
    (1e-3, "kilometres"),
    (1 / 0.3048, "feet"),
    (1e3, "millimetres"),
])
def test_position_units_wrong(tmp_path, scale, expect):
    t, ch = vacuum_track()
    for k in "xyz":
        ch[k] = ch[k] * scale
    with pytest.raises(InputError, match=f"units look wrong.*{expect}"):
        read_track(write_csv(tmp_path, csv_of(t, ch)))


@pytest.mark.parametrize("scale, expect", [(1 / 0.3048, "ft/s"), (3.6, "km/h")])
def test_speed_units_wrong(tmp_path, scale, expect):
    t, ch = vacuum_track()
    ch["v"] = ch["v"] * scale
    with pytest.raises(InputError, match=f"v looks like {expect}"):
        read_track(write_csv(tmp_path, csv_of(t, ch)))


def test_time_in_milliseconds(tmp_path):
    t, ch = vacuum_track(n=100)
    with pytest.raises(InputError, match="t looks like milliseconds"):
        read_track(write_csv(tmp_path, csv_of(t * 1000.0, ch)))


def test_x_only_in_km(tmp_path):
    t, ch = vacuum_track()
    with pytest.raises(InputError, match=r"positions \(x\).*kilometres"):
        read_track(write_csv(tmp_path, csv_of(t, {"x": ch["x"] / 1000, "v": ch["v"]})))


def test_units_no_false_alarm_noisy_tracks(tmp_path):
    rng = np.random.default_rng(1)
    # coarse and very fast sampling with 1 m position noise and 0.3 m/s speed noise
    for dt, n in ((0.027, 400), (0.001, 3000)):
        t, ch = vacuum_track(n=n, dt=dt, elev_deg=45.0)
        noisy = {k: a + rng.normal(0, 1.0 if k != "v" else 0.3, a.size) for k, a in ch.items()}
        tr = read_track(write_csv(tmp_path, csv_of(t, noisy)))
        assert tr.names == CHANNELS


def test_units_no_false_alarm_partial_positions(tmp_path):
    # y alone or z alone moves much slower than v: legitimate, not a unit error
    t, ch = vacuum_track(n=100, elev_deg=2.0)
    for keep in (["y", "v"], ["z", "v"]):
        tr = read_track(write_csv(tmp_path, csv_of(t, {k: ch[k] for k in keep})))
        assert tr.names == tuple(keep)
    # high-angle fire: x alone is well below v but plausible
    t, ch = vacuum_track(n=100, elev_deg=80.0)
    assert read_track(write_csv(tmp_path, csv_of(t, {"x": ch["x"], "v": ch["v"]}))).names == ("x", "v")


#: positions and speed that disagree by less than this are accepted (track.UNIT_REL_LIMIT is 5 %)
UNIT_AGREEMENT_OK = 0.02


def test_units_small_disagreement_not_flagged(tmp_path):
    # a 2 % disagreement between the speed channel and the positions is not a unit mistake
    t, ch = vacuum_track()
    ch["v"] = ch["v"] * (1.0 + UNIT_AGREEMENT_OK)
    assert read_track(write_csv(tmp_path, csv_of(t, ch))).n == t.size


def test_channels_that_disagree_are_refused(tmp_path):
    # a factor 2 between the speed from the positions and v matches no unit: the channels
    # disagree, and a fit of them would be meaningless (exit 2 with the check to make)
    t, ch = vacuum_track()
    ch["v"] = ch["v"] * 2.0
    with pytest.raises(InputError, match=r"0\.5 times v .*check the units of x, y, z \(m\), v \(m/s\)"):
        read_track(write_csv(tmp_path, csv_of(t, ch)))


def test_positions_in_yards_beside_speed_in_m_s(tmp_path):
    t, ch = vacuum_track()
    for c in ("x", "y", "z"):
        ch[c] = ch[c] / 0.9144
    with pytest.raises(InputError, match=r"1\.094 times v.*x, y, z look like yards"):
        read_track(write_csv(tmp_path, csv_of(t, ch)))


def test_units_v_alone_not_checked(tmp_path):
    t, ch = vacuum_track()
    tr = read_track(write_csv(tmp_path, csv_of(t, {"v": ch["v"] / 0.3048})))  # ft/s, undetectable
    assert tr.names == ("v",)


# ------------------------------------------------------------------------------------------
# generic CSV reader (used by drag.read_drag_table)
# ------------------------------------------------------------------------------------------
def test_read_csv_columns(tmp_path):
    p = write_csv(tmp_path, "# table\nmach,cd,note\n0.5,0.15,1\n1.0,0.34,2\n", "cd.csv")
    cols = read_csv_columns(p, required=("mach", "cd"), what="drag table")
    assert list(cols) == ["mach", "cd", "note"]
    np.testing.assert_array_equal(cols["cd"], [0.15, 0.34])


def test_read_csv_columns_missing_required(tmp_path):
    p = write_csv(tmp_path, "Mach,cd\n0.5,0.15\n", "cd.csv")
    with pytest.raises(InputError, match=r"drag table needs column\(s\) mach, cd; missing mach; "
                                         r"header has Mach, cd \(column names are case-sensitive: found 'Mach'\)"):
        read_csv_columns(p, required=("mach", "cd"), what="drag table")


def test_read_csv_columns_allowed(tmp_path):
    p = write_csv(tmp_path, "mach,cd,note\n0.5,0.15,1\n", "cd.csv")
    with pytest.raises(InputError, match=r"unknown column\(s\) note in table; allowed: mach, cd"):
        read_csv_columns(p, what="table", allowed=("mach", "cd"))


def test_read_drag_table_uses_reader(tmp_path):
    p = write_csv(tmp_path, "mach,cd\n0.5,0.15\n1.0,abc\n", "cd.csv")
    with pytest.raises(InputError, match=r"cd\.csv: line 3, column 'cd': not a number"):
        read_drag_table(p)


# ------------------------------------------------------------------------------------------
# rounds
# ------------------------------------------------------------------------------------------
DRAG_CSV = "# test drag\nmach,cd\n0.5,0.15\n0.9,0.16\n1.1,0.38\n2.0,0.30\n2.6,0.25\n"

FULL_ROUND = """\
[projectile]
name = "155 mm shell"
mass = 42.6                      # kg
diameter = 0.155                 # m
reference_drag = "cd_m101.csv"

[launch]
elevation = 15.0
velocity = 818.0
azimuth = 90.0
latitude = 50.0
altitude = 120.0
velocity_sd = 4.0
elevation_sd = 0.1
position_sd = 0.5

[atmosphere]
model = "icao"
temperature_offset = 5.0
pressure_ratio = 0.98

[radar]
sigma = {x = 1.0, y = 1.0, z = 1.0, v = 0.3}
"""

MINIMAL = '[projectile]\nmass = 42.6\ndiameter = 0.155\n'


def write_round_text(tmp_path, text, name="round.toml", drag=True):
    if drag:
        (tmp_path / "cd_m101.csv").write_text(DRAG_CSV)
    p = tmp_path / name
    p.write_text(text, encoding="utf-8")
    return p


def test_read_full_round(tmp_path):
    r = read_round(write_round_text(tmp_path, FULL_ROUND))
    p, la = r.projectile, r.launch
    assert (p.name, p.mass, p.diameter) == ("155 mm shell", 42.6, 0.155)
    assert p.area == pytest.approx(math.pi * 0.155**2 / 4)
    assert isinstance(r.reference_drag, ReferenceTable)
    assert r.reference_drag.mach == (0.5, 0.9, 1.1, 2.0, 2.6)
    assert p.reference_drag_path == str(tmp_path / "cd_m101.csv")
    assert (la.elevation_deg, la.velocity, la.azimuth_deg) == (15.0, 818.0, 90.0)
    assert (la.latitude_deg, la.altitude) == (50.0, 120.0)
    assert (la.velocity_sd, la.elevation_sd_deg, la.position_sd) == (4.0, 0.1, 0.5)
    assert la.elevation == pytest.approx(math.radians(15.0))
    assert r.atmosphere == Atmosphere(5.0, 0.98, 1.0, gun_altitude=120.0)
    assert r.radar.sigma == {"x": 1.0, "y": 1.0, "z": 1.0, "v": 0.3}
    assert r.path == str(tmp_path / "round.toml")


def test_minimal_round_defaults(tmp_path):
    r = read_round(write_round_text(tmp_path, MINIMAL, name="shot7.toml", drag=False))
    assert r.projectile.name == "shot7"  # defaults to the file stem
    assert r.reference_drag is None and r.projectile.reference_drag_path is None
    la = r.launch
    assert la.elevation_deg is None and la.velocity is None and la.latitude_deg is None
    assert la.azimuth_deg == 0.0 and la.altitude == 0.0
    assert la.velocity_sd == DEFAULT_VELOCITY_SD == 5.0
    assert la.elevation_sd_deg == DEFAULT_ELEVATION_SD_DEG == 0.2
    assert la.position_sd == DEFAULT_POSITION_SD == 1.0
    assert r.atmosphere == Atmosphere()
    assert r.radar.sigma == {}


@pytest.mark.parametrize("az, expect", [(450.0, 90.0), (-90.0, 270.0), (360.0, 0.0), (725, 5.0)])
def test_azimuth_normalised(tmp_path, az, expect):
    r = read_round(write_round_text(tmp_path, MINIMAL + f"[launch]\nazimuth = {az}\n", drag=False))
    assert r.launch.azimuth_deg == pytest.approx(expect)


def test_reference_drag_relative_to_toml(tmp_path):
    sub = tmp_path / "rounds"
    sub.mkdir()
    (tmp_path / "tables").mkdir()
    (tmp_path / "tables" / "cd.csv").write_text(DRAG_CSV)
    p = sub / "r.toml"
    p.write_text(MINIMAL + 'reference_drag = "../tables/cd.csv"\n')
    r = read_round(p)
    assert r.reference_drag.cd_values[2] == 0.38


def test_write_read_round_file_round_trip(tmp_path):
    r = read_round(write_round_text(tmp_path, FULL_ROUND))
    out = tmp_path / "copy" / "r2.toml"
    out.parent.mkdir()
    write_round(out, r, comment="copied")
    assert out.read_text().startswith("# copied\n")
    assert 'reference_drag = "../cd_m101.csv"' in out.read_text()
    r2 = read_round(out)
    assert r2.projectile.name == r.projectile.name
    assert (r2.projectile.mass, r2.projectile.diameter) == (r.projectile.mass, r.projectile.diameter)
    assert r2.reference_drag.mach == r.reference_drag.mach
    assert r2.reference_drag.cd_values == r.reference_drag.cd_values
    assert vars(r2.launch) == vars(r.launch)
    assert r2.atmosphere == r.atmosphere
    assert r2.radar.sigma == r.radar.sigma


def test_write_round_programmatic_with_table(tmp_path):
    table = ReferenceTable((0.5, 1.0, 2.0), (0.15, 0.35, 0.3), source="made up")
    rnd = Round(Projectile("p", 10.0, 0.105, table), Launch(elevation_deg=45.0, velocity=500.0))
    assert rnd.atmosphere == Atmosphere()  # built from launch.altitude
    out = tmp_path / "p.toml"
    write_round(out, rnd)
    assert (tmp_path / "p_reference_drag.csv").exists()
    back = read_round(out)
    assert back.reference_drag.cd_values == table.cd_values
    assert back.launch.elevation_deg == 45.0 and back.launch.velocity == 500.0
    assert back.launch.latitude_deg is None
    assert back.radar.sigma == {}


def test_round_atmosphere_follows_launch_altitude():
    rnd = Round(Projectile("p", 10.0, 0.105), Launch(altitude=800.0))
    assert rnd.atmosphere.gun_altitude == 800.0
    assert rnd.reference_drag is None


# ------------------------------------------------------------------------------------------
# round errors: one test per path
# ------------------------------------------------------------------------------------------
def round_error(tmp_path, text, match, drag=True):
    with pytest.raises(InputError, match=match):
        read_round(write_round_text(tmp_path, text, drag=drag))


def test_missing_round_file(tmp_path):
    with pytest.raises(InputError, match=r"nope\.toml: round file not found"):
        read_round(tmp_path / "nope.toml")


def test_broken_toml(tmp_path):
    round_error(tmp_path, "[projectile]\nmass = 42.6\ndiameter = = 0.155\n",
                r"round\.toml: not valid TOML: .*line 3")


def test_binary_round(tmp_path):
    p = tmp_path / "r.toml"
    p.write_bytes(b"\x89PNG\r\n\x1a\n\xff")
    with pytest.raises(InputError, match="round file is not UTF-8 text"):
        read_round(p)


def test_unknown_section(tmp_path):
    round_error(tmp_path, MINIMAL + "[lanuch]\nvelocity = 800.0\n",
                r"unknown section 'lanuch' \(did you mean 'launch'\?\); "
                r"allowed: projectile, launch, atmosphere, radar")


def test_unknown_top_level_key(tmp_path):
    round_error(tmp_path, "velocity = 800.0\n" + MINIMAL, "unknown top-level key 'velocity'")


def test_unknown_key_typo(tmp_path):
    round_error(tmp_path, MINIMAL + "[launch]\nelevaton = 15.0\n",
                r"unknown key in \[launch\] 'elevaton' \(did you mean 'elevation'\?\); "
                r"allowed: elevation, velocity")


def test_unknown_key_projectile(tmp_path):
    round_error(tmp_path, MINIMAL + "caliber = 155\n",
                r"unknown key in \[projectile\] 'caliber'.*allowed: name, mass, diameter, reference_drag")


def test_section_not_a_table(tmp_path):
    round_error(tmp_path, 'launch = 5\n' + MINIMAL, r"launch must be a section \[launch\], got int 5")


def test_string_for_number(tmp_path):
    round_error(tmp_path, MINIMAL + '[launch]\nvelocity = "818"\n',
                r"\[launch\] velocity must be a number \(m/s\), got string '818'")


def test_bool_is_not_a_number(tmp_path):
    round_error(tmp_path, "[projectile]\nmass = true\ndiameter = 0.155\n",
                r"\[projectile\] mass must be a number \(kg\), got boolean true")


def test_name_not_string(tmp_path):
    round_error(tmp_path, MINIMAL + "name = 155\n", r"\[projectile\] name must be a string, got int 155")


def test_array_for_number(tmp_path):
    round_error(tmp_path, MINIMAL + "[atmosphere]\ntemperature_offset = [1, 2]\n",
                r"\[atmosphere\] temperature_offset must be a number \(K\), got an array")


def test_missing_projectile(tmp_path):
    round_error(tmp_path, "[launch]\nvelocity = 800.0\n", r"missing section \[projectile\]; it needs mass")


def test_missing_mass(tmp_path):
    round_error(tmp_path, "[projectile]\ndiameter = 0.155\n", r"\[projectile\] missing key mass \(kg\)")


def test_missing_diameter(tmp_path):
    round_error(tmp_path, "[projectile]\nmass = 42.6\n", r"\[projectile\] missing key diameter \(m\)")


@pytest.mark.parametrize("mass", ["0.0", "-1.0", "20000.0"])
def test_mass_out_of_range(tmp_path, mass):
    round_error(tmp_path, f"[projectile]\nmass = {mass}\ndiameter = 0.155\n",
                r"\[projectile\] mass = .* kg is outside \(0, 10000\] kg")


def test_diameter_in_millimetres(tmp_path):
    round_error(tmp_path, "[projectile]\nmass = 42.6\ndiameter = 155\n",
                r"diameter = 155 looks like millimetres; diameter is in metres \(0\.155\)")


@pytest.mark.parametrize("d", ["0.001", "1.5", "-0.155", "2000.0"])
def test_diameter_out_of_range(tmp_path, d):
    round_error(tmp_path, f"[projectile]\nmass = 42.6\ndiameter = {d}\n",
                r"diameter = .* m is outside the plausible range \[0\.004, 1\] m")


@pytest.mark.parametrize("el", ["-10.0", "90.0", "120.0"])
def test_elevation_out_of_range(tmp_path, el):
    round_error(tmp_path, MINIMAL + f"[launch]\nelevation = {el}\n",
                r"\[launch\] elevation = .* deg is outside \(-10, 90\) deg")


@pytest.mark.parametrize("v", ["0.0", "-5.0", "3500.0"])
def test_velocity_out_of_range(tmp_path, v):
    round_error(tmp_path, MINIMAL + f"[launch]\nvelocity = {v}\n",
                r"\[launch\] velocity = .* m/s is outside \(0, 3000\] m/s")


@pytest.mark.parametrize("lat", ["-91.0", "90.5"])
def test_latitude_out_of_range(tmp_path, lat):
    round_error(tmp_path, MINIMAL + f"[launch]\nlatitude = {lat}\n",
                r"\[launch\] latitude = .* deg is outside \[-90, 90\] deg")


def test_azimuth_not_finite(tmp_path):
    round_error(tmp_path, MINIMAL + "[launch]\nazimuth = inf\n",
                r"\[launch\] azimuth must be a finite number \(deg\), got inf")


def test_nan_value(tmp_path):
    round_error(tmp_path, MINIMAL + "[launch]\nvelocity = nan\n", r"velocity must be a finite number")


def test_altitude_out_of_range(tmp_path):
    round_error(tmp_path, MINIMAL + "[launch]\naltitude = 50000.0\n",
                r"\[launch\] altitude = 50000 m is outside \[-1000, 10000\] m")


@pytest.mark.parametrize("key, unit",
                         [("velocity_sd", "m/s"), ("elevation_sd", "deg"), ("position_sd", "m")])
@pytest.mark.parametrize("value", ["0.0", "-1.0"])
def test_sd_must_be_positive(tmp_path, key, unit, value):
    round_error(tmp_path, MINIMAL + f"[launch]\n{key} = {value}\n",
                rf"\[launch\] {key} = .* must be > 0 \({unit}\)")


def test_sigma_unknown_channel(tmp_path):
    round_error(tmp_path, MINIMAL + "[radar]\nsigma = {x = 1.0, r = 2.0}\n",
                r"\[radar\] sigma has unknown channel\(s\) r; allowed: x, y, z, v")


def test_sigma_not_positive(tmp_path):
    round_error(tmp_path, MINIMAL + "[radar]\nsigma = {x = 1.0, v = 0.0}\n",
                r"\[radar\] sigma\.v = 0 must be > 0 \(m/s\)")


def test_sigma_not_a_table(tmp_path):
    round_error(tmp_path, MINIMAL + "[radar]\nsigma = 1.0\n", r"\[radar\] sigma must be a table")


def test_sigma_wrong_type(tmp_path):
    round_error(tmp_path, MINIMAL + '[radar]\nsigma = {x = "1 m"}\n',
                r"\[radar\] sigma\.x must be a number \(m\), got string '1 m'")


def test_atmosphere_model_unknown(tmp_path):
    round_error(tmp_path, MINIMAL + '[atmosphere]\nmodel = "us1962"\n',
                r"\[atmosphere\] model = 'us1962' is not supported; allowed: 'icao'")


def test_atmosphere_temperature_offset_implausible(tmp_path):
    round_error(tmp_path, MINIMAL + "[atmosphere]\ntemperature_offset = 150.0\n",
                r"\[atmosphere\] temperature_offset must be a finite number of kelvin in \(-100, 100\)")


def test_atmosphere_pressure_ratio_implausible(tmp_path):
    round_error(tmp_path, MINIMAL + "[atmosphere]\npressure_ratio = 0.0\n",
                r"\[atmosphere\] pressure_ratio must be a finite positive factor")


def test_reference_drag_missing_file(tmp_path):
    round_error(tmp_path, MINIMAL + 'reference_drag = "nope.csv"\n',
                r"round\.toml: \[projectile\] reference_drag = 'nope\.csv': .*nope\.csv: drag table not found",
                drag=False)


def test_reference_drag_malformed(tmp_path):
    (tmp_path / "bad.csv").write_text("mach,cd\n0.5,0.15\n0.4,0.16\n")
    round_error(tmp_path, MINIMAL + 'reference_drag = "bad.csv"\n',
                r"\[projectile\] reference_drag = 'bad\.csv': .*bad\.csv: mach must increase strictly",
                drag=False)


def test_reference_drag_missing_columns(tmp_path):
    (tmp_path / "bad.csv").write_text("m,c\n0.5,0.15\n0.9,0.16\n")
    round_error(tmp_path, MINIMAL + 'reference_drag = "bad.csv"\n',
                r"reference_drag = 'bad\.csv': .*bad\.csv: line 1: not a drag table: .*header naming the columns "
                r"mach,cd; the line is not shown",     # a named file: its header is never shown (issue 44)
                drag=False)


def test_reference_drag_wrong_type(tmp_path):
    round_error(tmp_path, MINIMAL + "reference_drag = 3\n",
                r"\[projectile\] reference_drag must be a CSV file path or a standard drag function \(G1, G2, "
                r"G5, G6, G7, G8, GI, GS\), got int 3",
                drag=False)


# ------------------------------------------------------------------------------------------
# dataclasses used directly raise ValueError with the same wording
# ------------------------------------------------------------------------------------------
def test_dataclass_validation_direct():
    with pytest.raises(ValueError, match="looks like millimetres"):
        Projectile("p", 42.6, 155.0)
    with pytest.raises(ValueError, match="elevation = 95"):
        Launch(elevation_deg=95.0)
    with pytest.raises(ValueError, match="sigma has unknown channel"):
        Radar({"q": 1.0})
    assert Launch(azimuth_deg=-30.0).azimuth_deg == 330.0
    assert Radar({"v": 1, "x": 2}).sigma == {"x": 2.0, "v": 1.0}


def test_reference_extrapolate_allows_short_table_and_roundtrips(tmp_path):
    (tmp_path / "cd.csv").write_text("mach,cd\n0.5,0.13\n1.0,0.3\n1.5,0.35\n")
    body = ('[projectile]\nmass = 42.6\ndiameter = 0.155\nreference_drag = "cd.csv"\n{extra}'
            '[launch]\nelevation = 15.0\nvelocity = 818.0\n')
    (tmp_path / "r.toml").write_text(body.format(extra=""))
    with pytest.raises(InputError, match=r"covers Mach 0.5-1.5 but the launch .* is Mach 2.40"):
        read_round(tmp_path / "r.toml")
    (tmp_path / "r.toml").write_text(body.format(extra="reference_extrapolate = true\n"))
    rnd = read_round(tmp_path / "r.toml")
    assert rnd.projectile.reference_extrapolate is True
    write_round(tmp_path / "r2.toml", rnd)
    assert read_round(tmp_path / "r2.toml").projectile.reference_extrapolate is True
