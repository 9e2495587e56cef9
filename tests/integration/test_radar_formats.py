"""Reading a LabRadar per-shot track export (examples/radar_export) into a RadarTrack."""
from pathlib import Path

import numpy as np
import pytest

from bayesdrag.errors import InputError
from bayesdrag.io.radar_formats import convert, main, read_labradar_track, read_radar_export, sniff_format
from bayesdrag.io.tracks import read_track

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "radar_export" / "Shot0001 Track.csv"
HEAD = "sep=;\nDevice ID;LBR-1;;\nSeries No;0001\nShot No;0007\n\n"


def test_example_file_is_read_in_si_with_extras_and_notes():
    tr = read_radar_export(EXAMPLE)
    # a chronograph radar's velocity is its range rate from its own site (docs/radar.md)
    assert tr.names == ("range_rate",)
    assert tr.n == 137 and tr.t[0] > 0  # the extrapolated muzzle row dropped
    assert tr.channels["range_rate"][0] == pytest.approx(3109.51 * 0.3048, abs=1e-9)
    assert tr.extra["range_m"][0] == pytest.approx(7.28 * 0.9144, abs=1e-9)
    assert set(tr.extra) == {"range_m", "snr"}
    assert any("dropped 1 row" in n for n in tr.notes) and any("fps to m/s" in n for n in tr.notes)
    kept = read_labradar_track(EXAMPLE, keep_extrapolated=True)
    assert kept.n == 138 and kept.t[0] == 0.0 and kept.extra["extrapolated"][0] == 1.0


def test_metric_units_decimal_comma_and_nul_padding(tmp_path):
    p = tmp_path / "Shot0007 Track.csv"
    body = HEAD + "Time (s);Vel (m/s);Dist (m);SNR\n0.000000;800,00;0,00;-\n0.007021;795,00;5,37;33,07\n" \
                  "0.008021;793.00;6.14;40.15\n"
    p.write_bytes(body.encode().replace(b"\n", b"\x00\x00\n"))
    assert sniff_format(p) == "labradar"
    tr = read_labradar_track(p)
    np.testing.assert_allclose(tr.channels["range_rate"], [795.0, 793.0])
    np.testing.assert_allclose(tr.extra["range_m"], [5.37, 6.14])
    np.testing.assert_allclose(tr.extra["snr"], [33.07, 40.15])


def test_round_trip_through_the_bayesdrag_csv(tmp_path):
    out = tmp_path / "t.csv"
    tr = convert(EXAMPLE, out)
    back = read_track(out)
    np.testing.assert_allclose(back.channels["range_rate"], tr.channels["range_rate"], atol=1e-4)   # 4 decimals
    np.testing.assert_allclose(back.t, tr.t, atol=1e-6)
    assert set(back.extra) == {"range_m", "snr"}
    assert any("snr give each sample's noise" in n for n in back.notes)
    assert sniff_format(out) == "bayesdrag"


@pytest.mark.parametrize("table, match", [
    ("Vel (fps);Dist (yd)\n1;2\n", "no 'Time \\(s\\);Vel"),
    ("Time (s);Vel (knots);SNR\n0.1;800;30\n0.2;790;30\n", "unit 'knots' is not one of"),
    ("Time (s);Vel (m/s);SNR\n0.1;abc;30\n0.2;790;30\n", "line 7: velocity 'abc' is not a number"),
    ("Time (s);Vel (m/s);SNR\n0.2;800;30\n0.1;790;30\n", "time must increase strictly"),
    ("Time (s);Vel (m/s);SNR\n0.0;800;-\n0.1;790;30\n", "1 measured row"),
    ("Time (s);Dist (m);SNR\n0.1;5;30\n", "no 'Vel"),
])
def test_bad_exports_raise_input_error_naming_the_problem(tmp_path, table, match):
    p = tmp_path / "bad.csv"
    p.write_text(HEAD + table)
    with pytest.raises(InputError, match=match):
        read_labradar_track(p)


def test_command_line_converts_and_reports_errors_in_one_line(tmp_path, capsys):
    assert main([str(EXAMPLE), "-o", str(tmp_path / "a.csv")]) == 0
    assert "137 samples" in capsys.readouterr().out
    bad = tmp_path / "bad.csv"
    bad.write_text(HEAD + "Time (s);Vel (furlongs);SNR\n0.1;1;2\n0.2;1;2\n")
    assert main([str(bad), "-o", str(tmp_path / "b.csv")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "furlongs" in err[0]
    assert not (tmp_path / "b.csv").exists()
