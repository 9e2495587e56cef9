"""The one CSV reader: numeric tables with ``#`` comments and a header row (tracks, drag tables,
met profiles, radar exports all use it).

Every failure raises :class:`bayesdrag.errors.InputError` with one line naming the file, the line
(file line numbers are 1-based and count comments and the header), what was found and what is
allowed.
"""
from __future__ import annotations

import os
import re
import stat
from pathlib import Path

import numpy as np

from ..errors import InputError

__all__ = ["read_bytes", "read_text", "read_table", "read_csv_columns", "MAX_BYTES"]

#: the largest file of each role read [bytes]: a bound on the memory a file can take (a track of a
#: million samples is ~50 MB of text; nothing a fit needs comes near these); reading stops there
MAX_BYTES = {"track": 256 << 20, "round file": 1 << 20, "campaign file": 1 << 20, "drag table": 16 << 20,
             "met profile": 16 << 20}
DEFAULT_MAX_BYTES = 256 << 20
_ADVICE = {"track": "thin it (every k-th row) or split it",
           "round file": "a round file holds a few sections of keys"}


def _kind(mode):
    if stat.S_ISCHR(mode) or stat.S_ISBLK(mode):
        return "a device"
    if stat.S_ISFIFO(mode):
        return "a pipe"
    if stat.S_ISSOCK(mode):
        return "a socket"
    return "not a regular file"


def _open_regular(path, what):
    """(binary file object, stat) of a regular file, opened without blocking so a device, pipe
    or socket is refused before anything is read."""
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK)
    except FileNotFoundError:
        raise InputError(f"{path}: {what} not found") from None
    except IsADirectoryError:
        raise InputError(f"{path}: {what} expected, found a directory") from None
    except OSError as exc:
        raise InputError(f"{path}: cannot read {what}: {exc.strerror or exc}") from None
    st = os.fstat(fd)                 # before fdopen, which refuses a directory with its own error
    if not stat.S_ISREG(st.st_mode):
        os.close(fd)
        if stat.S_ISDIR(st.st_mode):
            raise InputError(f"{path}: {what} expected, found a directory")
        raise InputError(f"{path}: {what} is {_kind(st.st_mode)}, not a regular file; give a file")
    return os.fdopen(fd, "rb"), st


def _too_large(path, what, size, limit):
    return InputError(f"{path}: {what} is {size} bytes, more than the {limit} allowed"
                      + (f"; {_ADVICE[what]}" if what in _ADVICE else ""))


def read_bytes(path, what, max_bytes=None, *, head=False):
    """The bytes of a regular file, at most ``max_bytes`` (default by role, :data:`MAX_BYTES`).

    A device (``/dev/zero``), pipe or socket is refused before anything is read (opened without
    blocking), and a file larger than the bound is refused by its size, never read to the end.
    With ``head=True`` the first ``max_bytes`` are returned whatever the file's size.

    Raises
    ------
    InputError
        Not found, a directory, not a regular file, unreadable, or too large.
    """
    path = Path(path)
    limit = int(max_bytes or MAX_BYTES.get(what, DEFAULT_MAX_BYTES))
    fh, st = _open_regular(path, what)
    with fh:
        if not head and st.st_size > limit:
            raise _too_large(path, what, st.st_size, limit)
        try:
            raw = fh.read(limit if head else limit + 1)
        except OSError as exc:
            raise InputError(f"{path}: cannot read {what}: {exc.strerror or exc}") from None
    if len(raw) > limit:
        raise InputError(f"{path}: {what} is more than the {limit} bytes allowed")
    return raw


def _decode(path, what, raw, newlines_before=0):
    """UTF-8 text of ``raw`` (one whole file or a block of whole lines of it; ``newlines_before``
    counts the file's newlines before the block, for the line named in a message)."""
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        line = newlines_before + raw[:exc.start].count(b"\n") + 1
        raise InputError(f"{path}: {what} is not UTF-8 text: undecodable byte 0x{raw[exc.start]:02x} "
                         f"at line {line} (binary file?); expected a CSV text file") from None
    if "\x00" in text:
        line = newlines_before + text[:text.index("\x00")].count("\n") + 1
        raise InputError(f"{path}: {what} contains NUL bytes at line {line} (binary file?); "
                         f"expected a CSV text file")
    return text


def _strip_bom(path, what, raw):
    if raw.startswith((b"\xff\xfe", b"\xfe\xff")):
        raise InputError(f"{path}: {what} is UTF-16 encoded; save it as UTF-8 (or ASCII) text")
    return raw[3:] if raw.startswith(b"\xef\xbb\xbf") else raw


def read_text(path: Path, what: str, max_bytes=None) -> str:
    """The UTF-8 text of a regular file (:func:`read_bytes`), refusing UTF-16 and binary files."""
    path = Path(path)
    return _decode(path, what, _strip_bom(path, what, read_bytes(path, what, max_bytes)))


#: bytes read at a time by the table reader: the text of one block is held at once, the file never
#: (a whole file's text takes several times its size; benchmarks/resources.py)
BLOCK_BYTES = 8 << 20


def _line_blocks(path, what, max_bytes=None, block_bytes=None):
    """The lines of a text file in blocks of whole lines: yields (number of the block's first line
    (1-based), list of str), the lines as ``str.splitlines`` splits the whole text.

    A block ends after a newline, so no line (and no UTF-8 character, whose bytes never include
    a newline) is cut; a file without newlines is one block. The size bound of
    :func:`read_bytes` holds for the bytes read; decoding problems are found block by block, so
    in a file of several blocks a problem of an earlier block is reported first.
    """
    limit = int(max_bytes or MAX_BYTES.get(what, DEFAULT_MAX_BYTES))
    step = int(block_bytes or BLOCK_BYTES)
    fh, st = _open_regular(path, what)
    with fh:
        if st.st_size > limit:
            raise _too_large(path, what, st.st_size, limit)
        first_line, newlines, total, buf, first = 1, 0, 0, bytearray(), True
        while True:
            try:
                block = fh.read(step)
            except OSError as exc:
                raise InputError(f"{path}: cannot read {what}: {exc.strerror or exc}") from None
            total += len(block)
            if total > limit:
                raise InputError(f"{path}: {what} is more than the {limit} bytes allowed")
            buf += block
            if block:
                cut = buf.rfind(b"\n") + 1
                if cut == 0:
                    continue
            elif not buf:
                return
            else:
                cut = len(buf)
            raw = buf[:cut]
            del buf[:cut]
            if first:
                raw, first = _strip_bom(path, what, raw), False
            text = _decode(path, what, raw, newlines)
            newlines += text.count("\n")
            lines = text.splitlines()
            del text, raw
            yield first_line, lines
            first_line += len(lines)
            if not block:
                return


def read_toml(path: Path, what: str, holds: str) -> dict:
    """A TOML file (``what``: "round file", ...) as a dict: its text by :func:`read_text`, one
    line naming the file for invalid TOML and for nesting too deep to parse (``holds`` says what
    such a file should contain)."""
    import tomllib

    path = Path(path)
    text = read_text(path, what)
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise InputError(f"{path}: not valid TOML: {exc}") from None
    except RecursionError:
        raise InputError(f"{path}: not a {what}: arrays or tables nested too deeply for TOML to be read "
                         f"({holds})") from None


#: a number in a table: ASCII decimal or scientific notation with an optional sign, or a NaN or
#: infinity (read, then refused by name). Python's ``float`` also takes ``81_5.5`` (815.5) and
#: Arabic-Indic or fullwidth digits: a typing slip or a foreign locale's file would be read as a
#: different number, so only this form is a number.
_NUMBER = re.compile(r"[+-]?(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][+-]?[0-9]+)?|[+-]?(?:nan|inf|infinity)",
                     re.ASCII | re.IGNORECASE)


def parse_number(s: str):
    """The float of a field (surrounding white space allowed), or None when it is not a number
    of :data:`_NUMBER`'s form."""
    s = s.strip()
    return float(s) if _NUMBER.fullmatch(s) else None


def _is_number(s: str) -> bool:
    return parse_number(s) is not None


def _clean_name(s: str) -> str:
    s = s.strip()
    if len(s) >= 2 and s[0] == s[-1] and s[0] in "\"'":
        s = s[1:-1].strip()
    return s


#: the largest magnitude a number in any table may have: far beyond anything physical here, and
#: small enough that squares and sums of squares stay finite (1e300 overflowed inside the fit)
MAX_MAGNITUDE = 1e15


def read_table(path, what, required=(), allowed=None, header_check=None, quote=True):
    """Parse a strict numeric CSV. Returns (path, names, data (N, K), line numbers (N,)).

    The file is read in blocks of lines (:func:`_line_blocks`), each parsed to numbers before the
    next is read, so the memory is the numbers (``data`` is the transpose of a (K, N) array: each
    column is contiguous) plus one block's text, not the file's text and its lines.

    ``quote=False`` for a file named inside another file (a round's reference table or met
    profile): its content is then not repeated in a message (a round pointing at any readable
    file would otherwise echo that file's first line): a header problem is shown with the names
    only when the line is a few plain column names, else the message names the file, the line
    and the header expected; values are never quoted."""
    path = Path(path)
    names, hline, any_text = None, None, False
    blocks, line_blocks = [], []
    non_finite = big = None           # the first of each, reported after a full parse (as before)
    for first_line, lines in _line_blocks(path, what):
        body, body_no = [], []
        for j, ln in enumerate(lines):
            if not ln.strip():
                continue
            any_text = True
            if ln.lstrip().startswith("#"):
                continue
            if names is None:
                hline = first_line + j
                names = _checked_header(path, what, hline, ln, required, allowed, header_check, quote)
                continue
            body.append(ln)
            body_no.append(first_line + j)
        del lines
        if not body:
            continue
        block = _parse_block(path, body, body_no, names, quote)      # (n, K)
        finite = np.isfinite(block)
        if non_finite is None and not finite.all():
            r, c = np.argwhere(~finite)[0]
            non_finite = (body_no[r], names[c], body[r].split(",")[c].strip())
        if big is None:
            over = np.abs(np.where(finite, block, 0.0)) > MAX_MAGNITUDE
            if over.any():
                r, c = np.argwhere(over)[0]
                big = (body_no[r], names[c], block[r, c])
        blocks.append(np.ascontiguousarray(block.T))
        line_blocks.append(np.asarray(body_no, dtype=np.int64))
        del body, block, finite
    if names is None:
        if not any_text:
            raise InputError(f"{path}: {what} is empty; expected a header row and rows of numbers")
        raise InputError(f"{path}: {what} has only comments; expected a header row and rows of numbers")
    if not blocks:
        raise InputError(f"{path}: {what} has a header (line {hline}) but no data rows")
    if non_finite is not None:
        line, name, field_text = non_finite
        shown = f"{field_text!r} is" if quote else "the value is"
        raise InputError(f"{path}: line {line}, column {name!r}: {shown} not a "
                         f"finite number; NaN and infinity are not allowed (drop the row instead)")
    if big is not None:
        line, name, value = big
        shown = f"{value:.6g}" if quote else "the value"
        raise InputError(f"{path}: line {line}, column {name!r}: {shown} is out of range; numbers "
                         f"in a {what} must be within +-{MAX_MAGNITUDE:g} (a unit or typing mistake?)")
    columns = blocks[0] if len(blocks) == 1 else np.concatenate(blocks, axis=1)
    del blocks
    line_no = line_blocks[0] if len(line_blocks) == 1 else np.concatenate(line_blocks)
    return path, names, columns.T, line_no


def _checked_header(path, what, hline, header, required, allowed, header_check, quote):
    """The names of the header line, checked (:func:`_header`, then ``header_check``). With
    ``quote=False`` (a file another file names) a refusal says what is wrong, never what the line
    holds: such a file may be anything its author can read (a key, a password file)."""
    try:
        names = _header(path, what, hline, header, required, allowed, quote)
        if header_check is not None:
            header_check(path, hline, names)
    except InputError as exc:
        if quote or getattr(exc, "content_free", False):
            raise
        need = f"the columns {','.join(required)}" if required else "column names"
        raise InputError(f"{path}: line {hline}: not a {what}: the first line that is not a comment must be a "
                         f"header naming {need}"
                         + (f" (allowed: {','.join(allowed)})" if allowed else "")
                         + "; the line is not shown") from None
    return names


def _content_free(message):
    """An InputError whose message holds nothing of the file (only the names the reader asks for)."""
    exc = InputError(message)
    exc.content_free = True
    return exc


def _parse_block(path, body, body_no, names, quote):
    """Numbers (n, K) of the data lines ``body`` (file line numbers ``body_no``)."""
    try:  # fast path (C parser, whose numbers are a subset of _NUMBER's); the slow path locates a problem
        data = np.loadtxt(body, delimiter=",", ndmin=2, comments=None, dtype=float)
        if data.shape[1] != len(names):
            raise ValueError
        return data
    except ValueError:
        return _slow_parse(path, list(zip(body_no, body)), names, quote)


def _header(path, what, hline, header, required, allowed, quote=True):
    """The column names of the header line, checked. ``quote=False``: a refusal names only what
    the reader asked for (the caller replaces any other by a line that shows nothing)."""
    names = [_clean_name(s) for s in header.split(",")]
    if all(_is_number(s) for s in names):
        raise InputError(f"{path}: line {hline}: {what} has no header row; found numbers "
                         f"{header.strip()[:40]!r}, expected column names"
                         + (f" ({','.join(required)})" if required else ""))
    if len(names) == 1 and (";" in header or "\t" in header):
        sep = "';'" if ";" in header else "tab"
        raise InputError(f"{path}: line {hline}: columns are separated by {sep}; "
                         f"the {what} must be comma-separated")
    for k, n in enumerate(names):
        if not n:
            raise InputError(f"{path}: line {hline}: empty column name in header (column {k + 1} "
                             f"of {len(names)}); found {header.strip()!r}")
    seen = set()
    for n in names:
        if n in seen:
            raise InputError(f"{path}: line {hline}: duplicate column name {n!r} in header "
                             f"{header.strip()!r}; each column may appear once")
        seen.add(n)
    missing = [r for r in required if r not in seen]
    if missing:
        hint = ""
        lower = {n.lower(): n for n in names}
        near = [f"{lower[m.lower()]!r}" for m in missing if m.lower() in lower]
        if near:
            hint = f" (column names are case-sensitive: found {', '.join(near)})"
        if not quote and len(missing) < len(required):      # a header with a name wrong, not another file
            raise _content_free(f"{path}: line {hline}: {what} needs column(s) {', '.join(required)}; missing "
                                f"{', '.join(missing)}; the header is not shown")
        raise InputError(f"{path}: line {hline}: {what} needs column(s) {', '.join(required)}; "
                         f"missing {', '.join(missing)}; header has {', '.join(names)}{hint}")
    if allowed is not None:
        bad = [n for n in names if n not in allowed]
        if bad:
            raise InputError(f"{path}: line {hline}: unknown column(s) {', '.join(bad)} in {what}; "
                             f"allowed: {', '.join(allowed)}")
    return names


def _slow_parse(path, body, names, quote=True):
    ncol = len(names)
    out = np.empty((len(body), ncol))
    for r, (i, ln) in enumerate(body):
        fields = ln.split(",")
        if len(fields) != ncol:
            raise InputError(f"{path}: line {i}: {len(fields)} fields, but the header has {ncol} "
                             f"({','.join(names)})")
        for c, f in enumerate(fields):
            value = parse_number(f)
            if value is None:
                what = ("empty field" if not f.strip()
                        else f"{f.strip()!r} is not a number" if quote else "not a number")
                raise InputError(f"{path}: line {i}, column {names[c]!r}: {what}; "
                                 f"expected a decimal number like 12.5 or 1.25e3 (ASCII digits)")
            out[r, c] = value
    return out


def read_csv_columns(path, required=(), what="CSV file", allowed=None, quote=True):
    """Read a numeric CSV file into columns.

    Format: lines starting with ``#`` (and blank lines) are skipped anywhere; the first other
    line is a comma-separated header of column names; every following line holds one finite
    decimal number per column.

    Parameters
    ----------
    path : str or os.PathLike
    required : sequence of str
        Column names that must be present (case-sensitive).
    what : str
        Name of the file's role in messages, e.g. ``"drag table"``.
    allowed : sequence of str, optional
        If given, every column must be one of these.
    quote : bool
        False: never repeat the file's content in a message (:func:`read_table`).

    Returns
    -------
    dict of str -> ndarray, shape (N,)
        Float columns in header order, N >= 1.

    Raises
    ------
    bayesdrag.errors.InputError
        Missing/unreadable/binary file, no header, duplicate or missing columns, ragged rows,
        non-numeric or non-finite values, no data rows. Line numbers in messages are file
        lines, 1-based.
    """
    _, names, data, _ = read_table(path, what, tuple(required),
                                    None if allowed is None else tuple(allowed), quote=quote)
    return {n: np.ascontiguousarray(data[:, k]) for k, n in enumerate(names)}
