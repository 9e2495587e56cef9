"""LabRadar exports read through the format registry (issue 44 item 6): the guarded reader's
protections hold for them (devices, pipes, huge files refused before reading), bad values are
refused with one line naming the file and the line, and real exports read directly with
``bayesdrag.read_track`` give the numbers the converter gave.

The cases that would exhaust memory or block with an unguarded reader (``/dev/zero``, a FIFO, a
3 GB file) run in a subprocess under a memory limit and a timeout, so a regression fails the test
instead of stalling the machine."""
import hashlib
import os
import re
import resource
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import numpy as np
import pytest

import bayesdrag
from bayesdrag.errors import InputError
from bayesdrag.io.formats.labradar import MAX_BYTES, read_labradar
from bayesdrag.io.radar_formats import main

ROOT = Path(__file__).resolve().parents[2]
#: the real LabRadar exports (SOURCE.md there); tests on them are skipped where they are absent
LABRADAR = Path(os.environ.get("BAYESDRAG_LABRADAR_DATA", "/work/shared/data/labradar"))
real_data = pytest.mark.skipif(not LABRADAR.is_dir(), reason=f"real LabRadar exports not at {LABRADAR}")
HEAD = "sep=;\nDevice ID;LBR-1;;\nSeries No;0001\nShot No;0007\n\n"
TABLE = "Time (s);Vel (fps);Dist (m);SNR\n"
#: a refused read must end within this [s] (it reads a few bytes, if any)
QUICK_S = 5.0
#: a subprocess's budget [s]: import plus the read, on a loaded machine
SUBPROCESS_TIMEOUT_S = 120.0
#: address-space limit of the subprocess [bytes]: its imports take ~150 MB; an unguarded read of
#: /dev/zero or of a 3 GB file fails here instead of taking the machine's memory
MEMORY_LIMIT = 1 << 30
FT = 0.3048  # m per ft


def _export(tmp_path, rows, name="Shot0007 Track.csv", head=HEAD, table=TABLE):
    p = tmp_path / name
    p.write_text(head + table + rows)
    return p


def _rows(n=20, t0=0.008, dt=0.001, v0=2800.0):
    """A plausible measured table (fps, m, dB) after the device's extrapolated row."""
    body = f"0.000000;{v0 + 10:.2f};0.00;-\n"
    for i in range(n):
        t = t0 + i * dt
        body += f"{t:.6f};{v0 - 2 * i:.2f};{v0 * FT * t:.2f};{30 + i % 5:.2f}\n"
    return body


# --- refused before reading: devices, pipes, huge files (in a subprocess) -----------------------

_PROBE = textwrap.dedent("""
    import sys, time
    from bayesdrag.errors import InputError
    path, how = sys.argv[1], sys.argv[2]
    t0 = time.monotonic()
    try:
        if how == "read_track":
            import bayesdrag
            bayesdrag.read_track(path)
        elif how == "labradar":
            from bayesdrag.io.radar_formats import read_labradar_track
            read_labradar_track(path)
        else:
            from bayesdrag.io.radar_formats import main
            code = main([path, "-o", sys.argv[3]])
            print(f"exit {code} after {time.monotonic() - t0:.3f} s")
            sys.exit(0)
    except InputError as exc:
        print(f"refused after {time.monotonic() - t0:.3f} s: {exc}")
        sys.exit(0)
    print("read")
    sys.exit(1)
""")


def _limit_memory():
    resource.setrlimit(resource.RLIMIT_AS, (MEMORY_LIMIT, MEMORY_LIMIT))


def _probe(path, how, out=None):
    """(stdout, stderr) of reading ``path`` one way in a subprocess under the limits."""
    try:
        r = subprocess.run([sys.executable, "-c", _PROBE, str(path), how, str(out)], capture_output=True, text=True,
                           timeout=SUBPROCESS_TIMEOUT_S, preexec_fn=_limit_memory, cwd=ROOT)
    except subprocess.TimeoutExpired:
        pytest.fail(f"reading {path} ({how}) blocked for {SUBPROCESS_TIMEOUT_S:g} s")
    assert r.returncode == 0, (r.stdout, r.stderr[-2000:])
    return r.stdout.strip(), r.stderr.strip()


def _assert_refused(path, how, match, tmp_path):
    """Refused with ``match`` quickly (in-process reading) or exit 2 with one line (the command)."""
    out, err = _probe(path, how, tmp_path / "out.csv")
    if how == "command":
        assert out.startswith("exit 2 "), (out, err)
        assert len(err.splitlines()) == 1 and err.startswith("bayesdrag: error: "), err
        text, took = err, float(out.split()[3])
        assert not (tmp_path / "out.csv").exists()
    else:
        assert out.startswith("refused after "), (out, err)
        text, took = out, float(out.split()[2])
    assert took < QUICK_S, out
    assert str(path) in text and match in text, text


HOW = ("read_track", "labradar", "command")


@pytest.mark.parametrize("how", HOW)
def test_a_device_is_refused_before_anything_is_read(how, tmp_path):
    _assert_refused("/dev/zero", how, "is a device, not a regular file", tmp_path)


@pytest.mark.parametrize("how", HOW)
def test_a_fifo_is_refused_without_blocking(how, tmp_path):
    fifo = tmp_path / "Shot0001 Track.csv"
    os.mkfifo(fifo)
    _assert_refused(fifo, how, "is a pipe, not a regular file", tmp_path)


@pytest.mark.parametrize("how", HOW)
def test_a_sparse_3_gb_export_is_refused_by_its_size_without_being_read(how, tmp_path):
    big = _export(tmp_path, _rows(5))
    os.truncate(big, 3 << 30)          # sparse: no disk used, 3 GB to a reader
    _assert_refused(big, how, f"is {3 << 30} bytes, more than the {MAX_BYTES} allowed", tmp_path)


# --- refused values, one line naming the file and the line ---------------------------------------

REFUSED = {
    "empty header cell": (TABLE.replace(";Vel", ";;Vel"), _rows(), r"line 6: empty column name in the LabRadar "
                                                                   r"header \(column 2 of 5\)"),
    "repeated column": ("Time (s);Vel (fps);Vel (m/s);SNR\n", "0.008;2800;853;30\n0.009;2790;850;30\n",
                        r"line 6: column 'vel' appears twice"),
    "velocity 1e308": (TABLE, _rows(3) + "0.100;1e308;80;30\n",
                       r"line 11: velocity '1e308' \(fps\) is 3.048e\+307 m/s, outside \(0, 2000\] m/s"),
    "velocity inf": (TABLE, _rows(3) + "0.100;inf;80;30\n", r"line 11: velocity 'inf' is not finite"),
    "velocity 0": (TABLE, _rows(3) + "0.100;0;80;30\n", r"line 11: velocity '0' \(fps\) is 0 m/s, outside"),
    "velocity negative": (TABLE, _rows(3) + "0.100;-2700;80;30\n", r"line 11: velocity '-2700'"),
    "velocity above the bound": ("Time (s);Vel (m/s);SNR\n", "0.008;2100;30\n0.009;2099;30\n",
                                 r"line 7: velocity '2100' \(m/s\) is 2100 m/s, outside"),
    "time in ms": (TABLE, "".join(f"{8 + i};{2800 - i};{5 + 0.85 * i:.2f};30\n" for i in range(300)),
                   r"line 306: t = 307 s at velocities near 807.9 m/s puts the projectile ~248 km from the device; "
                   r".*the time column looks like milliseconds"),
    "time not a number": (TABLE, "0.008;2800;5;30\nabc;2790;6;30\n", r"line 8: time 'abc' is not a number"),
    "time nan": (TABLE, "0.008;2800;5;30\nnan;2790;6;30\n", r"line 8: time 'nan' is not finite"),
    "time backwards": (TABLE, "0.009;2800;5;30\n0.008;2790;6;30\n",
                       r"line 8: t = 0.008 s after 0.009 s on line 7; time must increase strictly"),
    "negative time": (TABLE, "-0.009;2800;5;30\n0.008;2790;6;30\n", r"line 7: t = -0.009 s"),
    "SNR absurd": (TABLE, "0.008;2800;5;30\n0.009;2790;6;1e5\n", r"line 8: SNR = 100000 dB"),
    "distance absurd": (TABLE, "0.008;2800;5;30\n0.009;2790;1e9;30\n", r"line 8: distance '1e9' is 1e\+09 m"),
    "short row": (TABLE, "0.008;2800;5;30\n0.009;2790\n", r"line 8: 2 fields, the header has 4"),
    "units disagree": (TABLE, _rows(), r"velocity column 'Vel \(fps\)' says 'fps' but the 'Units velocity' line "
                                      r"says 'm/s'"),
    "one measured row": (TABLE, "0.000;2800;0;-\n0.008;2790;5;30\n", r"1 measured row\(s\) after the header"),
}


def _refused_file(tmp_path, case):
    table, rows, _ = REFUSED[case]
    head = HEAD + "Units velocity;m/s;;\n" if case == "units disagree" else HEAD
    return _export(tmp_path, rows, head=head, table=table)


@pytest.mark.parametrize("case", list(REFUSED))
def test_bad_values_are_refused_naming_the_file_and_line(case, tmp_path):
    p = _refused_file(tmp_path, case)
    with pytest.raises(InputError, match=REFUSED[case][2]) as err:
        bayesdrag.read_track(p)
    assert str(err.value).startswith(f"{p}: ") and "\n" not in str(err.value)
    with pytest.raises(InputError, match=REFUSED[case][2]):
        read_labradar(p)


@pytest.mark.parametrize("case", list(REFUSED))
def test_the_command_refuses_them_with_exit_2_and_one_line(case, tmp_path, capsys):
    p = _refused_file(tmp_path, case)
    assert main([str(p), "-o", str(tmp_path / "out.csv")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"bayesdrag: error: {p}: "), err
    assert not (tmp_path / "out.csv").exists()


def test_quote_false_never_repeats_the_files_content(tmp_path):
    p = _export(tmp_path, _rows(3) + "0.100;1e308;80;30\n")
    with pytest.raises(InputError, match=r"line 11: velocity \(fps\) is 3.048e\+307 m/s") as err:
        bayesdrag.read_track(p, quote=False)
    assert "1e308" not in str(err.value)


def test_a_time_column_in_ms_named_so_is_converted(tmp_path):
    rows = "".join(f"{8 + i};{2800 - i};{5 + 0.85 * i:.2f};30\n" for i in range(100))
    tr = bayesdrag.read_track(_export(tmp_path, rows, table=TABLE.replace("Time (s)", "Time (ms)")))
    np.testing.assert_allclose(tr.t, (8 + np.arange(100)) * 1e-3)
    assert any("time from ms to s" in n for n in tr.notes)


# --- the command's own guard ------------------------------------------------------------------------

@pytest.mark.parametrize("spelling", ["same", "dot", "symlink", "hardlink"])
def test_output_equal_to_the_input_is_refused_and_the_export_kept(spelling, tmp_path, capsys):
    p = _export(tmp_path, _rows())
    before = p.read_bytes()
    out = {"same": p, "dot": tmp_path / "." / p.name, "symlink": tmp_path / "link.csv",
           "hardlink": tmp_path / "hard.csv"}[spelling]
    if spelling == "symlink":
        out.symlink_to(p)
    elif spelling == "hardlink":
        os.link(p, out)
    assert main([str(p), "-o", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "-o names the export being converted" in err[0], err
    assert p.read_bytes() == before


def test_the_command_still_runs_as_a_module(tmp_path):
    p = _export(tmp_path, _rows())
    r = subprocess.run([sys.executable, "-m", "bayesdrag.io.radar_formats", str(p), "-o", str(tmp_path / "t.csv")],
                       capture_output=True, text=True, timeout=SUBPROCESS_TIMEOUT_S, cwd=ROOT)
    assert r.returncode == 0 and r.stdout.startswith(f"wrote {tmp_path / 't.csv'}: 20 samples"), r
    r = subprocess.run([sys.executable, "-m", "bayesdrag.io.radar_formats", str(p), "-o", str(p)],
                       capture_output=True, text=True, timeout=SUBPROCESS_TIMEOUT_S, cwd=ROOT)
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1, r


# --- read fine: NUL padding, nan rows, short tracks -------------------------------------------------

def test_nul_padding_and_nan_rows_read_fine(tmp_path):
    rows = ("0.000000;nan;0.00;-\n0.008021;2800.00;6.84;30.00\n0.009021;nan;7.69;nan\n"
            "0.010021;2798.00;8.55;31.00\n0.011021;2797.00;9.40;32.00\n")
    p = tmp_path / "Shot0002 Track.csv"
    p.write_bytes((HEAD + TABLE + rows).encode().replace(b"\n", b"\x00" * 7 + b"    \r\n"))
    tr = bayesdrag.read_track(p)
    np.testing.assert_array_equal(tr.t, [0.008021, 0.010021, 0.011021])
    np.testing.assert_array_equal(tr.channels["range_rate"], np.array([2800.0, 2798.0, 2797.0]) * FT)
    np.testing.assert_array_equal(tr.extra["snr"], [30.0, 31.0, 32.0])
    assert any("dropped 1 row(s) whose velocity is 'nan'" in n and "line 9" in n for n in tr.notes), tr.notes
    assert any("dropped 1 row(s) without SNR" in n for n in tr.notes), tr.notes
    kept = read_labradar(p, keep_extrapolated=True)       # the extrapolated row has no value: not kept either
    assert kept.n == 3 and any("line 7, 9" in n for n in kept.notes), kept.notes


@real_data
def test_a_track_of_four_rows_is_read(tmp_path, capsys):
    p = LABRADAR / "2020-2021" / "SR0010" / "TRK" / "Shot0001 Track.csv"
    assert len(p.read_text().strip().splitlines()) == 10          # 6 lines of head, 4 rows
    tr = bayesdrag.read_track(p)
    assert tr.n == 3 and tr.names == ("range_rate",) and tr.source == str(p)
    assert main([str(p), "-o", str(tmp_path / "t.csv")]) == 0
    out = capsys.readouterr().out.strip().splitlines()
    assert out == [f"wrote {tmp_path / 't.csv'}: 3 samples, channels range_rate, extra range_m, snr"]


# --- real exports read directly, with the converter's numbers ---------------------------------------

#: sha256 of t, range_rate, range_m, snr (little-endian float64, in that order) that the converter
#: of 697b642 (bayesdrag.io.radar_formats.read_labradar_track) gave for these real exports; the
#: registry's reader gives the same for all 729 (and with keep_extrapolated, except the 4 whose
#: extrapolated row is 'nan', which that converter refused)
OLD_CONVERTER_SHA256 = {
    "2020-2021/SR0047/TRK/Shot0001 Track.csv": "bfbd18ed00931d43a190654e833643893fd7eecbf335c5bbc3b6d5a5dab63bb7",
    "2020-2021/SR0047/TRK/Shot0002 Track.csv": "20fad0c311671ce691ae92425428e476e4863b5fdb084f6c81102b7c2f7abbe8",
    "2020-2021/SR0032/TRK/Shot0002 Track.csv": "9a3ef4d3e3f6251b7b74dde7a9841f1d14bf1a5dc020eb5c1fbc1832a7f404cf",
    "2020-2021/SR0010/TRK/Shot0001 Track.csv": "f6fe0adc0ce27f676508600630000fb030732733e2c2866c9773a01b2468ff27",
    "2022/LBR0013797201909141617/SR0001/TRK/Shot0001 Track.csv":
        "79d5f6b3645156c905391c0695de079c2ef8933a165527535adf8f68db8055cb",
}


def _digest(tr):
    h = hashlib.sha256()
    for a in (tr.t, tr.channels["range_rate"], tr.extra["range_m"], tr.extra["snr"]):
        h.update(np.ascontiguousarray(a, dtype="<f8").tobytes())
    return h.hexdigest()


def _reference(path):
    """The export's table the plain way: rows after the first, Vel fps -> m/s, Dist in m."""
    lines = path.read_text().splitlines()
    at = next(i for i, ln in enumerate(lines) if ln.startswith("Time (s)"))
    rows = [ln.split(";") for ln in lines[at + 2:] if ln.strip()]
    return {"t": np.array([float(r[0]) for r in rows]), "v": np.array([float(r[1]) * FT for r in rows]),
            "dist": np.array([float(r[2]) for r in rows]), "snr": np.array([float(r[3]) for r in rows])}


@real_data
@pytest.mark.parametrize("name", list(OLD_CONVERTER_SHA256))
def test_real_exports_read_directly_give_the_converters_numbers(name):
    p = LABRADAR / name
    tr = bayesdrag.read_track(p)
    assert tr.names == ("range_rate",) and set(tr.extra) == {"range_m", "snr"}
    assert _digest(tr) == OLD_CONVERTER_SHA256[name]
    ref = _reference(p)
    np.testing.assert_array_equal(tr.t, ref["t"])
    np.testing.assert_array_equal(tr.channels["range_rate"], ref["v"])
    np.testing.assert_array_equal(tr.extra["range_m"], ref["dist"])
    np.testing.assert_array_equal(tr.extra["snr"], ref["snr"])
    np.testing.assert_array_equal(read_labradar(p).channels["range_rate"], ref["v"])


@real_data
def test_a_series_reads_shot_by_shot_in_mixed_units():
    """SR0047 (6.5 mm 142 gr SMK): ``Vel (fps);Dist (m)``: velocity converted, distance not."""
    shots = sorted((LABRADAR / "2020-2021" / "SR0047" / "TRK").glob("Shot*Track.csv"))
    assert len(shots) >= 5
    for p in shots:
        assert "Time (s);Vel (fps);Dist (m);SNR" in p.read_text()
        tr = bayesdrag.read_track(p)
        ref = _reference(p)
        np.testing.assert_array_equal(tr.channels["range_rate"], ref["v"])
        np.testing.assert_array_equal(tr.extra["range_m"], ref["dist"])
        assert 700.0 < tr.channels["range_rate"].mean() < 900.0          # ~2600 fps
        assert any("velocity from fps to m/s" in n and "distance from m to m" in n for n in tr.notes)


def test_metric_velocity_with_yards_converts_only_the_distance(tmp_path):
    rows = "0.000;800.00;0.00;-\n0.008;795.00;6.00;33.00\n0.009;794.00;7.00;34.00\n"
    tr = bayesdrag.read_track(_export(tmp_path, rows, table="Time (s);Vel (m/s);Dist (yd);SNR\n"))
    np.testing.assert_array_equal(tr.channels["range_rate"], [795.0, 794.0])
    np.testing.assert_array_equal(tr.extra["range_m"], [6.0 * 0.9144, 7.0 * 0.9144])


def test_the_refusals_are_quick(tmp_path):
    """A refused export costs no more than reading it: well under a second here."""
    p = _refused_file(tmp_path, "time in ms")
    t0 = time.monotonic()
    with pytest.raises(InputError):
        bayesdrag.read_track(p)
    assert time.monotonic() - t0 < QUICK_S


@real_data
def test_fit_and_diagnose_take_a_labradar_export_and_format(tmp_path, capsys):
    """``bayesdrag fit "Shot0001 Track.csv" ROUND`` reads the export directly (issue 50); ``--format``
    names the reader, an unknown name exits 2 listing the valid ones."""
    from bayesdrag.cli import main

    shot = LABRADAR / "2020-2021" / "SR0047" / "TRK" / "Shot0001 Track.csv"
    rnd = tmp_path / "r.toml"
    rnd.write_text('[projectile]\nmass = 0.009201\ndiameter = 0.006706\nreference_drag = "G7"\n[launch]\n'
                   'elevation = 0.0\nvelocity = 830.0\n[radar]\ndevice_offset = 0.3\nposition_sd = 0.3\n')
    for fmt, code_want, pattern in (("nope", 2, r"unknown track format 'nope'; allowed: auto, csv, labradar"),
                                    ("csv", 2, r"separated by ';'")):
        capsys.readouterr()
        code = main(["diagnose", str(shot), str(rnd), "-o", str(tmp_path / "d"), "--format", fmt])
        err = capsys.readouterr().err.strip().splitlines()
        assert code == code_want and len(err) == 1 and re.search(pattern, err[0]), err
    capsys.readouterr()
    code = main(["fit", str(shot), str(rnd), "-o", str(tmp_path / "f"), "--no-mcmc", "--with", "none", "-qq",
                 "--format", "labradar"])
    assert code == 0, capsys.readouterr().err
    assert (tmp_path / "f" / "result.json").exists()
