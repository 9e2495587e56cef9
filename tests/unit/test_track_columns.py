"""Track headers other than t, x, y, z, v (issue 26): the aliases of docs/formats.md, read with a
note, and the ``--columns`` mapping; ``range_m`` is never read as ``x``."""
import re
from pathlib import Path

import pytest

from bayesdrag.cli import main
from bayesdrag.errors import InputError
from bayesdrag.io.tracks import ALIASES, read_track

DOCS = Path(__file__).resolve().parents[2] / "docs" / "formats.md"
ROWS = "0.0,818.0\n0.5,800.1\n1.0,783.0\n1.5,767.2\n"


def _csv(tmp_path, header, rows=ROWS, name="t.csv"):
    p = tmp_path / name
    p.write_text(header + "\n" + rows)
    return p


@pytest.mark.parametrize("header, names", [("time,speed", ("v",)), ("t_s,v_mps", ("v",)),
                                           ("Time,Speed", ("v",)), ("time_s,speed_mps", ("v",))])
def test_aliases_are_read_with_a_note(tmp_path, header, names):
    tr = read_track(_csv(tmp_path, header))
    assert tr.names == names and tr.t[1] == 0.5 and tr.v[0] == 818.0
    assert len(tr.notes) == 2 and all("read as" in n for n in tr.notes)


def test_a_bare_velocity_is_read_as_v_with_a_note_that_doppler_velocity_is_radial(tmp_path):
    tr = read_track(_csv(tmp_path, "time,velocity"))
    assert tr.names == ("v",)
    assert any("'velocity' read as v" in n and "radial speed" in n for n in tr.notes), tr.notes


def test_an_alias_beside_its_channel_stays_an_extra_column(tmp_path):
    tr = read_track(_csv(tmp_path, "t,v,speed", "0,818,818\n0.5,800,800\n1,783,783\n"))
    assert tr.names == ("v",) and "speed" in tr.extra


def test_two_columns_for_one_channel_are_refused(tmp_path):
    with pytest.raises(InputError, match=r"columns 'speed' and 'velocity' both read as v; keep one, or say which "
                                         r"with --columns v=NAME"):
        read_track(_csv(tmp_path, "t,speed,velocity", "0,818,818\n0.5,800,800\n"))


def test_range_is_not_x(tmp_path):
    with pytest.raises(InputError, match=r"'range_m' is not read as x: a chronograph's distance is integrated"):
        read_track(_csv(tmp_path, "t,range_m", "0,0\n0.5,400\n"))
    tr = read_track(_csv(tmp_path, "t,range_m", "0,0\n0.5,400\n1,790\n"), columns={"x": "range_m"})
    assert tr.names == ("x",)


def test_columns_mapping_and_its_errors(tmp_path):
    p = _csv(tmp_path, "Zeit,Geschwindigkeit")
    tr = read_track(p, columns={"t": "Zeit", "v": "Geschwindigkeit"})
    assert tr.names == ("v",) and tr.notes == ()
    with pytest.raises(InputError, match=r"--columns t=tim: the track has no column 'tim'; header has Zeit"):
        read_track(p, columns={"t": "tim", "v": "Geschwindigkeit"})
    with pytest.raises(InputError, match=r"--columns v=speed: the header already has a column 'v'"):
        read_track(_csv(tmp_path, "t,v,speed", "0,818,818\n0.5,800,800\n", "b.csv"), columns={"v": "speed"})


def test_the_formats_page_states_the_aliases_the_reader_has():
    text = DOCS.read_text()
    table = text[text.index("| alias | read as |"):text.index("An alias is not used")]
    stated = {}
    for row in table.splitlines()[2:]:
        cells = [c.strip() for c in row.strip().strip("|").split("|")]
        if len(cells) == 2:
            names = re.findall(r"`([a-z_]+)`", cells[0])
            targets = re.findall(r"`([a-z_]+)`", cells[1])
            for n, tgt in zip(names, targets * len(names) if len(targets) == 1 else targets):
                stated[n] = tgt
    assert stated == ALIASES
    assert "`range` and `range_m` are\n  **not** read as `x`" in text


def test_fit_command_reads_a_doppler_export_with_columns(tmp_path, capsys):
    """CLI: ``--columns t=time,v=velocity`` fits a Doppler export without editing it; without it
    the aliases read the same file, with the radial-speed note on stderr."""
    import shutil
    from importlib.resources import files

    import numpy as np

    from bayesdrag.io.rounds import read_round
    from bayesdrag.synthetic import simulate_round

    shutil.copy(files("bayesdrag") / "data" / "cd_m101.csv", tmp_path / "cd.csv")
    (tmp_path / "r.toml").write_text('[projectile]\nname = "155"\nmass = 42.6\ndiameter = 0.155\n'
                                     'reference_drag = "cd.csv"\n[launch]\nelevation = 15.0\nvelocity = 818.0\n'
                                     '[radar]\nsigma = {v = 0.3}\n')
    tr = simulate_round(read_round(tmp_path / "r.toml"), dt=0.5)
    rows = "".join(f"{t:.3f},{v:.4f}\n" for t, v in zip(tr.t, tr.v + np.random.default_rng(1).normal(0, 0.3, tr.n)))
    track = _csv(tmp_path, "time,velocity", rows, "doppler.csv")
    capsys.readouterr()
    assert main(["fit", str(track), str(tmp_path / "r.toml"), "-o", str(tmp_path / "o"), "--no-mcmc",
                 "--columns", "t=time,v=velocity"]) == 0
    cap = capsys.readouterr()
    assert cap.out.startswith("fit: converged") and "read as" not in cap.err
    assert main(["fit", str(track), str(tmp_path / "r.toml"), "-o", str(tmp_path / "o2"), "--no-mcmc"]) == 0
    err = capsys.readouterr().err
    assert "column 'time' read as t (s)" in err and "radial speed" in err
    assert main(["fit", str(track), str(tmp_path / "r.toml"), "-o", str(tmp_path / "o3"), "--columns", "w=time"]) == 2
    assert "--columns" in capsys.readouterr().err
