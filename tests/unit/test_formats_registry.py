"""The registry of track formats (bayesdrag.io.formats): what it lists, how a file's format is
sniffed, how an unknown name is refused, and that a new format is one module registered through
the documented extension point (``formats.register``), with no other module edited."""
import importlib
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

import bayesdrag
from bayesdrag.errors import InputError
from bayesdrag.io import formats
from bayesdrag.io.formats import labradar

ROOT = Path(__file__).resolve().parents[2]
EXAMPLE = ROOT / "examples" / "radar_export" / "Shot0001 Track.csv"
PLAIN_TRACK = "# t,v of a 155 mm shell\nt,v\n0.0,818.0\n0.1,816.7\n0.2,815.3\n"


def test_the_registry_lists_the_builtin_formats():
    assert formats.names() == ("auto", "csv", "labradar")
    (fmt,) = formats.available()
    assert fmt.name == "labradar" and fmt.read is labradar.read_labradar and fmt.sniff is labradar.sniff
    assert fmt.module == "bayesdrag.io.formats.labradar" and "LabRadar" in fmt.description
    assert formats.BUILTIN == (labradar,) and dict(formats.FORMATS) == {"labradar": fmt}


@pytest.mark.parametrize("head", [
    "sep=;\nDevice ID;LBR-0013797;;\nSeries No;0047\n",
    "\ufeffsep=;\r\nDevice ID;LBR-1;;\r\n",
    "Device ID;LBR-1;;\nTime (s);Vel (fps);Dist (m);SNR\n",
    "Time (s);Vel (m/s);SNR\n0.1;800;30\n",
    "  time (ms) ; vel (fps)\n",
])
def test_labradar_heads_are_sniffed(head):
    assert labradar.sniff(head)
    assert formats.detect_text(head) == "labradar"


@pytest.mark.parametrize("head", [
    PLAIN_TRACK,
    "t,x,y,z,v\n0,0,0,0,818\n",
    "t;x;z\n0;0;0\n",                                      # semicolons, but not a LabRadar export
    "# converted from Shot0001 Track.csv (sep=; Device ID; Time (s);Vel)\nt,range_rate\n0.1,800\n",
    "",
])
def test_other_heads_are_the_plain_track_csv(head):
    assert not labradar.sniff(head)
    assert formats.detect_text(head) == formats.PLAIN == "csv"


def test_detect_reads_only_the_start_through_the_guard(tmp_path):
    assert formats.detect(EXAMPLE) == "labradar"
    padded = tmp_path / "padded.csv"
    padded.write_bytes(EXAMPLE.read_bytes().replace(b"\n", b"\x00\x00\x00\n"))
    assert formats.detect(padded) == "labradar"
    plain = tmp_path / "t.csv"
    plain.write_text(PLAIN_TRACK)
    assert formats.detect(plain) == "csv"
    with pytest.raises(InputError, match="track is a device, not a regular file"):
        formats.detect("/dev/zero")
    with pytest.raises(InputError, match="not found"):
        formats.detect(tmp_path / "missing.csv")


def test_read_track_dispatches_by_sniffing_and_by_name(tmp_path):
    tr = bayesdrag.read_track(EXAMPLE)
    assert tr.names == ("range_rate",) and tr.n == 137
    named = bayesdrag.read_track(EXAMPLE, format="LabRadar")                 # names ignore case
    np.testing.assert_array_equal(named.channels["range_rate"], tr.channels["range_rate"])
    plain = tmp_path / "t.csv"
    plain.write_text(PLAIN_TRACK)
    assert bayesdrag.read_track(plain).names == ("v",) == bayesdrag.read_track(plain, format="csv").names
    with pytest.raises(InputError, match="separated by ';'"):               # a name overrides the sniffing
        bayesdrag.read_track(EXAMPLE, format="csv")
    with pytest.raises(InputError, match="no 'Time \\(s\\);Vel"):
        bayesdrag.read_track(plain, format="labradar")
    with pytest.raises(InputError, match="--columns maps the columns of a track CSV; this is a labradar export"):
        bayesdrag.read_track(EXAMPLE, columns={"v": "Vel"})


@pytest.mark.parametrize("name", ["weibel", "", "auto ", 3, None])
def test_an_unknown_format_is_refused_listing_the_valid_ones(name, tmp_path):
    missing = tmp_path / "missing.csv"        # refused by its name before the file is looked at
    if name == "auto ":
        with pytest.raises(InputError, match="not found"):                  # " auto " is auto
            bayesdrag.read_track(missing, format=name)
        return
    with pytest.raises(InputError, match=rf"^{missing}: unknown track format .*; allowed: auto, csv, labradar$"):
        bayesdrag.read_track(missing, format=name)
    with pytest.raises(InputError, match="allowed: auto, csv, labradar"):
        formats.get(name)


TOY = textwrap.dedent('''
    """A toy device's export: a 'TOYRADAR' line, then 'ms speed_kmh' rows."""
    import numpy as np

    from bayesdrag.errors import InputError
    from bayesdrag.io.csv import read_bytes
    from bayesdrag.track import RadarTrack

    NAME = "toy"
    DESCRIPTION = "toy radar export (TOYRADAR, then ms and km/h)"
    MS = 1e-3          # s per ms
    KMH = 1 / 3.6      # m/s per km/h


    def sniff(head_text):
        return head_text.startswith("TOYRADAR")


    def read_toy(path, *, quote=True):
        lines = read_bytes(path, "toy export", 1 << 20).decode().split("\\n")[1:]
        rows = [ln.split() for ln in lines if ln.strip()]
        if len(rows) < 2:
            raise InputError(f"{path}: {len(rows)} row(s); at least 2 are needed")
        t = np.array([float(r[0]) for r in rows]) * MS
        v = np.array([float(r[1]) for r in rows]) * KMH
        return RadarTrack(t, {"range_rate": v}, {}, str(path), (f"{path}: toy export",))
''')


@pytest.fixture
def toy_module(tmp_path, monkeypatch):
    """A format written as one module outside the package, imported and registered; removed after."""
    (tmp_path / "toy_format.py").write_text(TOY)
    monkeypatch.syspath_prepend(str(tmp_path))
    module = importlib.import_module("toy_format")
    yield module
    formats.unregister("toy")
    sys.modules.pop("toy_format", None)


def test_a_new_format_is_one_module_registered_through_the_extension_point(toy_module, tmp_path):
    fmt = formats.register(toy_module)
    assert fmt.name == "toy" and fmt.description.startswith("toy radar export")
    assert formats.names() == ("auto", "csv", "labradar", "toy")
    p = tmp_path / "shot.toy"
    p.write_text("TOYRADAR\n10 2880\n20 2872.8\n30 2865.6\n")
    tr = bayesdrag.read_track(p)                                       # sniffed
    np.testing.assert_allclose(tr.t, [0.01, 0.02, 0.03])
    np.testing.assert_allclose(tr.channels["range_rate"], [800.0, 798.0, 796.0])
    assert bayesdrag.read_track(p, format="toy").n == 3
    assert bayesdrag.read_track(EXAMPLE).names == ("range_rate",)    # the others still sniffed as before
    with pytest.raises(ValueError, match="'toy' is already registered"):
        formats.register(toy_module)
    assert formats.register(toy_module, replace=True).name == "toy"
    formats.unregister("toy")
    assert formats.names() == ("auto", "csv", "labradar")
    with pytest.raises(InputError, match="separated by|header"):          # no longer claimed: a plain CSV
        bayesdrag.read_track(p)


class _Fake:
    NAME = "fake"

    @staticmethod
    def sniff(head_text):
        return False

    @staticmethod
    def read_fake(path, *, quote=True):
        raise AssertionError


@pytest.mark.parametrize("change, match", [
    ({"NAME": "Bad Name"}, "NAME must be a lower-case identifier"),
    ({"NAME": 7}, "NAME must be a lower-case identifier"),
    ({"NAME": "csv"}, "'csv' is reserved"),
    ({"NAME": "auto"}, "'auto' is reserved"),
    ({"NAME": "labradar"}, "'labradar' is already registered by bayesdrag.io.formats.labradar"),
    ({"read_fake": None}, "needs a function read_fake"),
    ({"sniff": "yes"}, "needs a function sniff"),
])
def test_a_malformed_format_module_is_refused(change, match):
    fake = type("FakeFormat", (_Fake,), change)
    with pytest.raises(ValueError, match=match):
        formats.register(fake)
    assert formats.names() == ("auto", "csv", "labradar")


def test_the_shim_uses_the_registry():
    from bayesdrag.io import radar_formats

    assert radar_formats.FORMATS == ("bayesdrag", "labradar")
    assert radar_formats.sniff_format(EXAMPLE) == "labradar"
    assert radar_formats.read_labradar_track(EXAMPLE).n == bayesdrag.read_track(EXAMPLE).n
