"""The table reader reads a file in blocks of lines (issue 25): the numbers, line numbers and
messages are those of reading the file whole, wherever the blocks end; a number is ASCII
decimal or scientific notation only."""
import numpy as np
import pytest

from bayesdrag.errors import InputError
from bayesdrag.io import csv as csv_module
from bayesdrag.io.csv import parse_number, read_table
from bayesdrag.io.tracks import read_track

#: block sizes [bytes] that cut a small file at every kind of place: inside a line, right after
#: a newline, between \r and \n, inside a multi-byte character's line
BLOCKS = (1, 2, 3, 7, 13, 64, 4096)


def _read(path, block, monkeypatch, **kw):
    monkeypatch.setattr(csv_module, "BLOCK_BYTES", block)
    try:
        p, names, data, line_no = read_table(path, "track", **kw)
    except InputError as exc:
        return ("error", str(exc))
    return ("ok", names, data.tolist(), line_no.tolist())


VALID = {
    "plain": "t,x,v\n0,0,800\n0.1,80,799\n0.2,160,798\n",
    "comments and blanks": "# head\n\n# more\nt,x,v\n0,0,800\n# mid\n\n0.1,80,799\n   \n0.2,160,798\n# end\n",
    "crlf": "t,x,v\r\n0,0,800\r\n0.1,80,799\r\n0.2,160,798\r\n",
    "bare cr": "t,x,v\r0,0,800\r0.1,80,799\r",
    "no final newline": "t,x,v\n0,0,800\n0.1,80,799",
    "bom": "\ufefft,x,v\n0,0,800\n0.1,80,799\n",
    "non-ascii comment": "# Größe: 155 mm — Ø\nt,x,v\n0,0,800\n# ✓ über\n0.1,80,799\n",
    "white space and forms": "t , x ,v\n 0 ,+0.0e0, 8e2\n.1,80.,7.99E+02\n",
    "quoted header": "\"t\",'x',v\n0,0,800\n0.1,80,799\n",
}

INVALID = {
    "ragged late": "t,x,v\n0,0,800\n0.1,80,799\n0.2,160\n",
    "not a number late": "# c\nt,x,v\n0,0,800\n0.1,80,799\n0.2,16x0,798\n",
    "nan late": "t,x,v\n0,0,800\n0.1,80,799\n0.2,nan,798\n",
    "big late": "t,x,v\n0,0,800\n0.1,80,799\n0.2,1e16,798\n",
    "nan before big": "t,x,v\n0,1e16,800\n0.1,80,799\n0.2,inf,798\n",
    "header only": "# c\nt,x,v\n# nothing\n\n",
    "only comments": "# a\n\n# b\n",
    "empty": "  \n\n",
    "nul late": "t,x,v\n0,0,800\n0.1,80,7\x0099\n",
    "no header": "0,0,800\n0.1,80,799\n",
}


@pytest.mark.parametrize("name", sorted(VALID))
def test_blocks_read_a_valid_file_as_the_whole_file(tmp_path, monkeypatch, name):
    p = tmp_path / "t.csv"
    p.write_bytes(VALID[name].encode("utf-8"))
    whole = _read(p, 1 << 20, monkeypatch)
    assert whole[0] == "ok", whole
    for block in BLOCKS:
        assert _read(p, block, monkeypatch) == whole, f"block {block} B"


@pytest.mark.parametrize("name", sorted(INVALID))
def test_blocks_give_the_same_message_as_the_whole_file(tmp_path, monkeypatch, name):
    p = tmp_path / "t.csv"
    p.write_bytes(INVALID[name].encode("utf-8"))
    whole = _read(p, 1 << 20, monkeypatch)
    assert whole[0] == "error", whole
    for block in BLOCKS:
        assert _read(p, block, monkeypatch) == whole, f"block {block} B"


def test_an_undecodable_byte_is_named_with_its_line_in_any_block(tmp_path, monkeypatch):
    p = tmp_path / "t.csv"
    p.write_bytes(b"t,x,v\n0,0,800\n0.1,80,799\n0.2,1\xff60,798\n")
    for block in BLOCKS:
        monkeypatch.setattr(csv_module, "BLOCK_BYTES", block)
        with pytest.raises(InputError, match=r"undecodable byte 0xff at line 4"):
            read_table(p, "track")


def test_a_utf16_file_is_refused_in_any_block(tmp_path, monkeypatch):
    p = tmp_path / "t.csv"
    p.write_bytes("t,x,v\n0,0,800\n".encode("utf-16"))
    for block in BLOCKS:
        monkeypatch.setattr(csv_module, "BLOCK_BYTES", block)
        with pytest.raises(InputError, match="UTF-16"):
            read_table(p, "track")


def test_a_random_track_reads_identically_in_small_blocks(tmp_path, monkeypatch):
    """Several hundred rows with comments scattered in: every block size gives the same
    numbers and line numbers, and the columns are contiguous (no copy per column)."""
    rng = np.random.default_rng(7)
    n = 400
    t = np.cumsum(rng.uniform(0.01, 0.05, n))
    lines = ["# random track", "t,x,z,v"]
    for i in range(n):
        if rng.random() < 0.1:
            lines.append("# note " + "é" * int(rng.integers(0, 5)))
        lines.append(f"{t[i]:.6f},{800 * t[i]:.4f},{300 * t[i]:.4f},{854.4:.4f}")
    p = tmp_path / "t.csv"
    p.write_text("\n".join(lines) + "\n", encoding="utf-8")
    whole = _read(p, 1 << 20, monkeypatch)
    for block in (5, 100, 1000):
        assert _read(p, block, monkeypatch) == whole
    monkeypatch.setattr(csv_module, "BLOCK_BYTES", 1000)
    tr = read_track(p)
    assert tr.n == n and np.array_equal(tr.t, np.array(whole[2])[:, 0])


@pytest.mark.parametrize("text", ["81_5.5", "1_000", "١٢", "１２", "1\u20095", "0x10", "1d5", "12abc", "1.2.3",
                                  "+-1", "e5", ".", "- 1"])
def test_only_ascii_decimal_notation_is_a_number(tmp_path, text):
    assert parse_number(text) is None
    p = tmp_path / "t.csv"
    p.write_text(f"t,x\n0,0\n0.1,{text}\n", encoding="utf-8")
    with pytest.raises(InputError, match=r"line 3, column 'x': .* is not a number; expected a decimal number"):
        read_track(p)


@pytest.mark.parametrize("text,value", [("815.5", 815.5), (" +.5 ", 0.5), ("5.", 5.0), ("-1.25E+03", -1250.0),
                                        ("\t4", 4.0), ("1e-3", 1e-3), ("0", 0.0)])
def test_decimal_and_scientific_notation_are_numbers(text, value):
    assert parse_number(text) == value


@pytest.mark.parametrize("text", ["nan", "NaN", "-inf", "+Infinity", "1e400"])
def test_non_finite_numbers_are_read_then_refused_by_name(tmp_path, text):
    p = tmp_path / "t.csv"
    p.write_text(f"t,x\n0,0\n0.1,{text}\n", encoding="utf-8")
    with pytest.raises(InputError, match=r"line 3, column 'x': .* not a finite number"):
        read_track(p)
