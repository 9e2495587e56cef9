"""Hypothesis fuzzing of the track and round readers (issue 7): any input gives a result or
:class:`~bayesdrag.errors.InputError` (the one documented error), never another exception.

Default run: a small budget (``FAST`` examples per test). The slow run (``pytest -m slow``)
repeats each property with ``SLOW`` examples.
"""
import string

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from bayesdrag.io.met import read_met_profile
from bayesdrag.errors import InputError
from bayesdrag.track import CHANNELS, RadarTrack
from bayesdrag.round import Round
from bayesdrag.io.rounds import read_round
from bayesdrag.io.tracks import read_track

FAST = 60
SLOW = 3000
_COMMON = dict(deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture,
                                                        HealthCheck.too_slow])


def _only_input_error(reader, path, kind):
    try:
        out = reader(path)
    except InputError as exc:
        msg = str(exc)
        assert msg.strip(), "empty error message"
        assert str(path) in msg, f"error does not name the file: {msg!r}"
        return None
    assert isinstance(out, kind)
    return out


# --- raw bytes ------------------------------------------------------------------------------
def _bytes_property(reader, name, kind):
    def prop(tmp_path_factory, data):
        p = tmp_path_factory.mktemp("fz") / name
        p.write_bytes(data)
        _only_input_error(reader, p, kind)
    return prop


BYTES = st.one_of(st.binary(max_size=400),
                  st.text(max_size=300).map(lambda s: s.encode("utf-8", "ignore")))


# --- structured: valid-looking CSV with perturbations ----------------------------------------
NUM = st.one_of(st.floats(allow_nan=True, allow_infinity=True, width=64).map(repr),
                st.integers(-10**6, 10**6).map(str),
                st.sampled_from(["", " ", "1e400", "-0", "0x10", "1,5", "1.2.3", "nan", "NaN", "+inf",
                                 "1_000", "１２", "12abc", '"3.5"', "\t4"]))
COLNAMES = st.lists(st.sampled_from(["t", "x", "y", "z", "v", "snr", "T", " x", "x ", "", '"v"']),
                    min_size=1, max_size=7)


@st.composite
def csv_text(draw, names=COLNAMES):
    cols = draw(names)
    nrow = draw(st.integers(0, 12))
    good = draw(st.booleans())
    rows = []
    t = 0.0
    for i in range(nrow):
        t += draw(st.floats(-0.5, 2.0)) if not good else draw(st.floats(0.01, 1.0))
        row = []
        for c in cols:
            if good and c == "t":
                row.append(repr(t))
            elif good:
                row.append(repr(draw(st.floats(0.0, 2000.0))))
            else:
                row.append(draw(NUM))
        if draw(st.integers(0, 9)) == 0:
            row = row[:-1]  # ragged
        rows.append(",".join(row))
    lines = [",".join(cols)] + rows
    if draw(st.booleans()):
        k = draw(st.integers(0, len(lines)))
        lines.insert(k, draw(st.sampled_from(["# comment", "", "   ", "#", "t,x", ";;", "\x00"])))
    sep = draw(st.sampled_from(["\n", "\r\n", "\r"]))
    return sep.join(lines) + draw(st.sampled_from(["", "\n"]))


@st.composite
def toml_text(draw):
    vals = st.one_of(st.floats(allow_nan=True, allow_infinity=True).map(repr),
                     st.integers(-10**9, 10**9).map(str), st.booleans().map(lambda b: str(b).lower()),
                     st.text(string.ascii_letters + ".-_ /", max_size=8).map(lambda s: f'"{s}"'),
                     st.just("[1, 2]"), st.just("{x = 1.0}"), st.just("{x = -1.0, q = 2}"),
                     st.just('"cd.csv"'), st.just('"met.csv"'), st.just("1979-05-27"))
    keys = {"projectile": ["name", "mass", "diameter", "reference_drag", "reference_extrapolate", "masss"],
            "launch": ["elevation", "velocity", "azimuth", "latitude", "altitude", "velocity_sd",
                       "elevation_sd", "position_sd", "speed"],
            "atmosphere": ["model", "profile", "temperature_offset", "pressure_ratio", "density_ratio"],
            "radar": ["sigma"], "weather": ["wind"]}
    out = []
    for sec in draw(st.lists(st.sampled_from(list(keys)), unique=True, max_size=5)):
        out.append(f"[{sec}]")
        for k in draw(st.lists(st.sampled_from(keys[sec]), unique=True, max_size=6)):
            v = draw(vals)
            if sec == "projectile" and k in ("mass", "diameter") and draw(st.booleans()):
                v = {"mass": "42.6", "diameter": "0.155"}[k]
            out.append(f"{k} = {v}")
    text = "\n".join(out) + "\n"
    if draw(st.integers(0, 4)) == 0:  # break it somewhere
        i = draw(st.integers(0, len(text)))
        text = text[:i] + draw(st.sampled_from(["=", "[", "]", '"', "\n[[", "\x00", "é", " = = "])) + text[i:]
    return text


def _setup_round_dir(d):
    (d / "cd.csv").write_text("mach,cd\n0.5,0.13\n1.0,0.3\n3.0,0.25\n")
    (d / "met.csv").write_text("altitude,temperature,pressure\n0,288.15,101325\n1000,281.65,89876\n")


def _props(n):
    s = settings(max_examples=n, **_COMMON)

    @s
    @given(data=BYTES)
    def track_bytes(tmp_path_factory, data):
        _bytes_property(read_track, "t.csv", RadarTrack)(tmp_path_factory, data)

    @s
    @given(data=BYTES)
    def round_bytes(tmp_path_factory, data):
        _bytes_property(read_round, "r.toml", Round)(tmp_path_factory, data)

    @s
    @given(text=csv_text())
    def track_structured(tmp_path_factory, text):
        p = tmp_path_factory.mktemp("fz") / "t.csv"
        p.write_bytes(text.encode("utf-8"))
        tr = _only_input_error(read_track, p, RadarTrack)
        if tr is not None:  # what the reader accepts obeys the RadarTrack contract
            assert tr.n >= 2 and set(tr.names) <= set(CHANNELS) and tr.names
            assert (tr.t[1:] > tr.t[:-1]).all()

    @s
    @given(text=csv_text(st.lists(st.sampled_from(["altitude", "temperature", "pressure", "wind_x",
                                                   "wind_y", "alt"]), min_size=1, max_size=6)))
    def profile_structured(tmp_path_factory, text):
        p = tmp_path_factory.mktemp("fz") / "met.csv"
        p.write_bytes(text.encode("utf-8"))
        try:
            read_met_profile(p)
        except InputError as exc:
            assert str(p) in str(exc)

    @s
    @given(text=toml_text())
    def round_structured(tmp_path_factory, text):
        d = tmp_path_factory.mktemp("fz")
        _setup_round_dir(d)
        p = d / "r.toml"
        p.write_bytes(text.encode("utf-8"))
        _only_input_error(read_round, p, Round)

    return dict(track_bytes=track_bytes, round_bytes=round_bytes, track_structured=track_structured,
                profile_structured=profile_structured, round_structured=round_structured)


_FAST, _SLOW = _props(FAST), _props(SLOW)


@pytest.mark.parametrize("name", list(_FAST))
def test_fuzz(name, tmp_path_factory):
    _FAST[name](tmp_path_factory)


@pytest.mark.slow
@pytest.mark.parametrize("name", list(_SLOW))
def test_fuzz_slow(name, tmp_path_factory):
    _SLOW[name](tmp_path_factory)
