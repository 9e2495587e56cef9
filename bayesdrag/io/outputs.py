"""The output folder: a run's outputs are one consistent set (docs/formats.md, docs/security.md).

:class:`OutputRun` is the one way a command writes ``DIR``::

    with OutputRun(out, "fit", inputs={"track": t, "round": r}) as run:   # checks, lock, staging
        ...the work...                                # the sampler may write DIR/chain.partial.h5
        result.write_files(run.staging)               # every output goes to the staging folder
        run.adopt("chain.partial.h5", "chain.h5")     # a file already in DIR that becomes an output
    # on success: superseded files moved aside, the new ones moved in, manifest.json last

Decisions written down (and why):

* **Checks before any work.** Entering the run creates ``DIR`` (and parents), takes the lock and
  creates the staging folder, so a folder that cannot be written is refused (exit 2, one line)
  before a fit spends minutes, not after it.
* **A lock that a killed run does not leave behind.** The folder itself is locked with
  ``fcntl.flock`` for the whole run; the kernel releases the lock when the process ends however
  it ends, so ``--resume`` after a kill is never blocked, and no lock file is left (a refused or
  failed run changes nothing in ``DIR``). A second run on the same folder gets
  :class:`~bayesdrag.errors.InputError` "DIR is in use by another bayesdrag run (pid N)" (exit 2;
  the pid is read from the holder's staging folder name). On a file system that cannot lock a
  folder the lock is taken on a hidden ``DIR/.bayesdrag.lock`` instead (kept, never in a manifest).
* **Staging, then a journalled swap.** Outputs are written into ``DIR/.staging-<run>/`` (the same
  file system, so moving them in is a rename). Committing first writes a journal ``.commit.json`` into the
  staging folder (the commit point, itself written by rename), then executes its renames: the
  earlier files out to ``DIR/superseded/<earlier run>/``, the new ones in, ``manifest.json``
  last. Moving an earlier file out is done only when it exists and its target does not, moving a
  new file in only while it is still in the staging folder, so replaying the plan is harmless;
  a run killed during the swap is completed by the next run on the folder
  (under the lock, before it does anything else), and a run killed before its commit point
  leaves only its staging folder, which the next run removes. A failed run never touches the
  files already in ``DIR``. The plan is signed and only plans of this user's bayesdrag, of the
  shapes a commit makes, are carried out again (:mod:`bayesdrag.io.commit`).
* **No symbolic link is followed inside DIR.** ``DIR`` is resolved once (the user's own ``-o``
  may pass links above it); before any work, an output's name that is a link or not a regular
  file, and a ``superseded`` that is not a real folder of the user, are refused (one line, exit
  2), and every rename checks its folders again. Round folders of a campaign are made by
  :meth:`OutputRun.subfolder`, which refuses anything else with their name. Someone who can
  write ``DIR`` cannot make a run write, move or read outside it (docs/security.md).
* **What is superseded.** Each manifest lists the runs whose files are current: the run that
  wrote it, and earlier runs of *other* commands on the *same inputs* (a ``diagnose`` beside a
  ``fit`` of the same track and round is consistent with it; ``batch`` runs both into one
  folder). A new run supersedes an earlier run when it is the same command, when its inputs
  differ, or when the two share a file name; a superseded run's files go to
  ``superseded/<its run id>/`` together. In a folder without a manifest (written by an earlier
  version) every file with a name bayesdrag writes (:data:`KNOWN_OUTPUTS`) is superseded. Files
  bayesdrag never writes (the user's own), the unfinished chain ``chain.partial.h5``, folders
  and the run's input files are never moved.
* **Modes follow the umask.** Files are created as ``0666 & ~umask`` like any other program's
  (temporary files are not made with ``mkstemp``, whose 0600 hid outputs from Dask workers
  running under another user).
* **A full disk is one line, exit 1, nothing lost.** An ``ENOSPC``, ``EDQUOT`` or ``EFBIG`` while
  writing (or a library error that wraps one) becomes :class:`~bayesdrag.io.space.DiskFullError`;
  the staging folder is removed and the earlier outputs are untouched
  (:mod:`bayesdrag.io.space`, whose checks let a writer stop before a block it could not finish).
* **Inputs are never moved.** A run whose output has the name of one of its inputs in ``DIR``
  refuses (exit 2) rather than move the input aside.
* **Nothing read here is evaluated.** Manifests and plans are JSON, read with a size bound, and
  every name in them is checked to be a plain file name inside ``DIR`` before it is used.
"""
from __future__ import annotations

import contextlib
import errno
import fcntl
import hashlib
import json
import os
import re
import secrets
import shutil
import stat
import time
from fnmatch import fnmatch
from pathlib import Path

from .._runtime.user_cache import user_key
from ..errors import InputError, OutputError
from .commit import (NAME_RE, PLAN, PLAN_FORMAT, STAGING_PREFIX, SUPERSEDED, check_signature, execute,
                     not_own_folder, plan_moves, safe_rel, signature)
from .space import (DISK_FULL, MIN_FREE_BYTES, DiskFullError, ensure_file_size, ensure_space, file_size_limit,
                    free_bytes, is_disk_full, space_problem)

__all__ = ["OutputRun", "atomic_write", "write_json", "write_bytes", "write_figure", "ensure_output_dir",
           "read_json", "sha256_file", "describe_inputs", "ensure_space", "is_disk_full", "space_problem",
           "DiskFullError", "DISK_FULL", "file_size_limit", "ensure_file_size", "MANIFEST",
           "SUPERSEDED", "LOCK_NAME", "KNOWN_OUTPUTS", "MANIFEST_FORMAT"]

#: the manifest of the run whose outputs are in ``DIR``
MANIFEST = "manifest.json"
MANIFEST_FORMAT = "bayesdrag-manifest/1"
#: the lock file (hidden; held with flock)
LOCK_NAME = ".bayesdrag.lock"
#: what bayesdrag writes into an output folder (glob patterns): superseded in a folder that has
#: no manifest (written by a version before manifests)
KNOWN_OUTPUTS = ("manifest.json", "result.json", "posterior.nc", "chain.h5", "report.html", "summary.json",
                 "pooling.json", "done.*.json", "diagnosis.json", "diagnosis.html", "diagnosis_*.png",
                 "campaign.json", "campaign.html", "campaign_*.png", "cd.png", "cd_*.png", "corner.png",
                 "traces.png", "residuals.png", "residuals_*.png", "windows.png", "track_vs_pointmass.png",
                 "differences.png", "reference_cd.png", "plan.json", "plan.html", "plan.png",
                 "plan_*.png")
#: the unfinished chain: resume state, never an output of a finished run, never moved by a commit
PARTIAL_CHAIN = "chain.partial.h5"
#: largest manifest or plan read back [bytes]
MAX_JSON_BYTES = 8 << 20
_RUN_RE = re.compile(r"^[A-Za-z0-9][A-Za-z0-9._-]{0,100}$")


# ============================================================================ small writers
def _tmp_name(path):
    """A temporary name beside ``path`` that says whose it is (pid), so a later run can remove
    the leftovers of a killed one."""
    return path.with_name(f".{path.name}.{os.getpid()}.{secrets.token_hex(4)}.part")


def _remove_stale_parts(path):
    """Remove ``.NAME.<pid>.<hex>.part`` files beside ``path`` whose process is gone."""
    pat = re.compile(rf"^\.{re.escape(path.name)}\.(\d+)\.[0-9a-f]+\.part$")
    try:
        entries = list(os.scandir(path.parent))
    except OSError:
        return
    for e in entries:
        m = pat.match(e.name)
        if m and e.is_file(follow_symlinks=False) and not _pid_alive(int(m.group(1))):
            with contextlib.suppress(OSError):
                os.unlink(e.path)


def _pid_alive(pid):
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def atomic_write(path, write_fn):
    """Call ``write_fn(tmp_path)`` then rename the finished file to ``path``.

    The temporary file is created ``0666 & ~umask`` (not 0600) beside ``path``; it is removed when
    ``write_fn`` fails, and leftovers of a killed process are removed by the next write to the
    same path. A full disk raises :class:`~bayesdrag.errors.OutputError`.
    """
    path = Path(path)
    if path.exists() and path.is_dir():
        raise InputError(f"{path}: output path is a directory; give a file name such as {path / 'track.csv'}")
    if not path.parent.exists():
        raise InputError(f"{path}: output folder {path.parent} does not exist")
    if os.path.lexists(path) and not path.is_symlink() and not stat.S_ISREG(os.lstat(path).st_mode):
        raise InputError(f"{path}: output path exists and is not a regular file (a device or pipe); "
                         f"give the name of a file to write")
    if os.path.lexists(path) and not path.is_symlink() and not os.lstat(path).st_mode & 0o222:
        raise InputError(f"{path}: the output file is read-only; bayesdrag does not replace it: remove it or "
                         f"give another name")
    _remove_stale_parts(path)
    tmp = _tmp_name(path)
    try:
        os.close(os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_NOFOLLOW, 0o666))
    except OSError as exc:
        if exc.errno in (errno.EACCES, errno.EPERM, errno.EROFS):
            raise InputError(f"{path.parent}: the output folder is not writable ({exc.strerror})") from None
        if exc.errno == errno.ENAMETOOLONG:
            raise InputError(f"{path}: the name is too long ({exc.strerror}); give a shorter one") from None
        raise
    try:
        write_fn(str(tmp))
        os.replace(tmp, path)
    except BaseException as exc:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        why = space_problem(exc, path.parent) if isinstance(exc, Exception) else None
        if why is not None:
            raise DiskFullError(f"{path.parent}: {why} while writing {path.name}; nothing was written: free some "
                                f"space and run again", reason=why) from None
        raise


def write_json(path, obj):
    """Write ``obj`` as indented JSON (no NaN or infinity) atomically."""
    atomic_write(path, lambda tmp: Path(tmp).write_text(json.dumps(obj, indent=2, allow_nan=False)))


def write_bytes(path, data):
    """Write bytes atomically."""
    atomic_write(path, lambda tmp: Path(tmp).write_bytes(data))


def write_figure(path, fig, dpi=110):
    """Save a matplotlib figure atomically in the format of ``path``'s suffix (PNG by default)."""
    fmt = Path(path).suffix.lstrip(".") or "png"
    atomic_write(path, lambda tmp: fig.savefig(tmp, dpi=dpi, format=fmt))


def ensure_output_dir(out):
    """Create the output folder (and parents); refuse a path that is an existing file or a
    folder that cannot be created."""
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise InputError(f"{out}: output path exists and is not a folder")
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise InputError(f"{out}: cannot create the output folder ({exc.strerror or exc})") from None
    return out


# ============================================================================ reading back
def read_json(path, what="JSON file", max_bytes=MAX_JSON_BYTES):
    """A JSON document read with a size bound (a regular file only, never evaluated).

    Raises
    ------
    InputError
        Not a regular file, larger than ``max_bytes``, not UTF-8 JSON, or nested too deeply.
    """
    path = Path(path)
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | os.O_NOFOLLOW)
    except OSError as exc:
        raise InputError(f"{path}: cannot read the {what} ({exc.strerror or exc})") from None
    if not stat.S_ISREG(os.fstat(fd).st_mode):      # before fdopen, which refuses a directory itself
        os.close(fd)
        raise InputError(f"{path}: the {what} is not a regular file")
    with os.fdopen(fd, "rb") as fh:
        raw = fh.read(max_bytes + 1)
    if len(raw) > max_bytes:
        raise InputError(f"{path}: the {what} is larger than {max_bytes} bytes")
    try:
        return json.loads(raw.decode("utf-8"))
    except (UnicodeDecodeError, ValueError, RecursionError) as exc:
        detail = "nested too deeply" if isinstance(exc, RecursionError) else type(exc).__name__
        raise InputError(f"{path}: not a valid {what} ({detail})") from None


def sha256_file(path):
    """Hex SHA-256 of a file's bytes."""
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for chunk in iter(lambda: f.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


def describe_inputs(inputs):
    """``{role: {"path", "sha256", "bytes"}}`` of the input files ``{role: path}`` (None skipped)."""
    out = {}
    for role, p in (inputs or {}).items():
        if p is None:
            continue
        p = Path(p)
        out[str(role)] = {"path": str(p.resolve()), "sha256": sha256_file(p), "bytes": p.stat().st_size}
    return out


# ============================================================================ the run
def _new_run_id():
    return f"{time.strftime('%Y%m%dT%H%M%SZ', time.gmtime())}-{os.getpid()}-{secrets.token_hex(2)}"


class OutputRun:
    """One run of a command writing ``DIR``: checks, lock, staging, commit and manifest.

    Parameters
    ----------
    directory : path
        ``DIR``; created with its parents when missing.
    command : str
        The command (``fit``, ``diagnose``, ``demo``, ``campaign``): a later run of the same
        command supersedes this one's files.
    inputs : dict role -> path, optional
        The input files; their SHA-256 goes into the manifest and :attr:`inputs_digest`.
    options : dict, optional
        Plain JSON values recorded in the manifest.
    echo : callable, optional
        Receives one-line notes (an interrupted commit completed, leftovers removed).

    Attributes
    ----------
    folder : Path
        ``DIR``.
    staging : Path
        Where the run writes its outputs (inside ``DIR``); valid inside the ``with`` block.
    run_id : str
    manifest : dict or None
        The manifest written, after a successful commit.
    """

    def __init__(self, directory, command, *, inputs=None, options=None, echo=None):
        if not os.fspath(directory).strip():
            raise InputError("output folder: the name is empty; give a folder (. for the current one)")
        self.folder = Path(directory)
        self._real = None
        self.command = str(command)
        self.inputs = describe_inputs(inputs)
        self.options = options
        self.echo = echo
        self.run_id = _new_run_id()
        self.staging = None
        self.manifest = None
        self._lock_fd = None
        self._adopted = {}

    # -------------------------------------------------------------------- public helpers
    @property
    def inputs_digest(self):
        """Hex digest of the inputs' bytes (their SHA-256 by role; paths left out, so a moved
        folder keeps its digest): what an unfinished chain must have been made from."""
        doc = sorted((k, v["sha256"]) for k, v in self.inputs.items())
        return hashlib.sha256(json.dumps(doc).encode()).hexdigest()[:16]

    def adopt(self, name, as_name):
        """At commit, the file ``DIR/name`` (already written there, e.g. the finished chain)
        becomes the output ``DIR/as_name``."""
        safe_rel(name), safe_rel(as_name)
        self._adopted[str(as_name)] = str(name)

    def subfolder(self, name, what):
        """``DIR/name`` (``name`` a plain name, ``what`` says what it holds in a message), made
        here when missing; refused (:class:`~bayesdrag.errors.InputError`, exit 2) when something
        else is there: a symbolic link, a file, a folder of another user. Valid inside the
        ``with`` block."""
        safe_rel(name)
        path = self._real / name
        if not os.path.lexists(path):
            path.mkdir()
        why = not_own_folder(path)
        if why:
            raise InputError(f"{self.folder / name}: {what} {why}; bayesdrag makes these folders itself: "
                             f"remove it")
        return path

    # -------------------------------------------------------------------- enter / exit
    def __enter__(self):
        out = self.folder
        if out.exists() and not out.is_dir():
            raise InputError(f"{out}: output path exists and is not a folder")
        self._created = not out.exists()
        try:
            out.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise InputError(f"{out}: cannot create the output folder ({exc.strerror or exc}); "
                             f"choose another -o") from None
        # resolved once: the user's own -o may pass symbolic links; inside DIR none is followed
        self._real = Path(os.path.realpath(out))
        self._lock()
        try:
            self._recover()
            self._check_where_outputs_go()
            free = free_bytes(out)
            if free is not None and free < MIN_FREE_BYTES:
                raise DiskFullError(f"{out}: the disk is full ({free} bytes free); free some space and run again")
            staging = self._real / f"{STAGING_PREFIX}{self.run_id}"
            try:
                staging.mkdir()
            except OSError as exc:
                raise InputError(f"{out}: the output folder is not writable ({exc.strerror or exc}); "
                                 f"choose another -o") from None
            self.staging = staging
        except BaseException:
            self._unlock()
            raise
        return self

    def _check_where_outputs_go(self):
        """Refuse, before any work, what a run would write through or move its files into:
        a symbolic link or other non-file with an output's name, a ``superseded`` that is not a
        folder of this user, and an input of this run named ``manifest.json`` in ``DIR``."""
        for e in os.scandir(self._real):
            named = any(fnmatch(e.name, p) for p in KNOWN_OUTPUTS)    # (the chain file checks itself)
            if e.name == SUPERSEDED:
                why = not_own_folder(Path(e.path))
                if why:
                    raise InputError(f"{self.folder / SUPERSEDED}: {why}; bayesdrag makes this folder itself to keep "
                                     f"earlier outputs: remove or rename it")
            elif named and (e.is_symlink() or not e.is_file(follow_symlinks=False)):
                kind = "a symbolic link" if e.is_symlink() else "not a regular file"
                raise InputError(f"{self.folder / e.name}: {kind} where bayesdrag writes an output (it never writes "
                                 f"through one); remove it")
        for role, v in self.inputs.items():
            if Path(v["path"]).parent == self._real and Path(v["path"]).name == MANIFEST:
                raise InputError(f"{v['path']}: the {role} is named like the manifest bayesdrag writes into "
                                 f"{self.folder}; rename it or write to another folder")

    def __exit__(self, et, ev, tb):
        try:
            if et is None:
                try:
                    self._commit()
                except Exception as exc:
                    self._discard()
                    self._raise_if_full(exc)
                    raise
            else:
                self._discard()
                partial = self.folder / PARTIAL_CHAIN
                if issubclass(et, KeyboardInterrupt) and partial.exists():
                    self._note(f"the unfinished chain is in {partial}: continue it with --resume")
                if isinstance(ev, Exception):
                    self._raise_if_full(ev)
        finally:
            self._unlock()
            if et is not None and getattr(self, "_created", False):
                # a refused or failed run leaves no folder it made (an empty one only: a kept
                # unfinished chain keeps it)
                with contextlib.suppress(OSError):
                    self.folder.rmdir()
        return False

    def _raise_if_full(self, exc):
        """Re-raise running out of room as one :class:`DiskFullError` saying what was kept."""
        if isinstance(exc, DiskFullError) or not isinstance(exc, (InputError, OutputError)):
            why = space_problem(exc, self.folder)
            if why is not None:
                raise DiskFullError(self._full_message(why), reason=why) from None

    def _full_message(self, why=DISK_FULL):
        partial = self.folder / PARTIAL_CHAIN
        keep = (f"; the unfinished chain stays in {partial}: free some space and continue it with --resume"
                if partial.exists() else ": free some space and run again")
        return f"{self.folder}: {why}; nothing of this run was kept and the earlier outputs are untouched{keep}"

    # -------------------------------------------------------------------- lock
    def _lock(self):
        """``flock`` on the folder itself (no lock file: a refused or failed run leaves no trace);
        where the file system cannot lock a folder (some network file systems), on
        ``DIR/.bayesdrag.lock``."""
        try:
            fd = os.open(self._real, os.O_RDONLY | os.O_DIRECTORY)
        except OSError as exc:
            raise InputError(f"{self.folder}: cannot open the output folder ({exc.strerror or exc})") from None
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError as exc:
            os.close(fd)
            if exc.errno in (errno.EWOULDBLOCK, errno.EACCES):
                self._busy(self._holder_from_staging())
            fd = self._lock_file()
        self._lock_fd = fd

    def _busy(self, pid):
        raise InputError(f"{self.folder} is in use by another bayesdrag run (pid {pid or 'unknown'}); wait for "
                         f"it to finish or write to another folder") from None

    def _holder_from_staging(self):
        """The pid in the newest staging folder's run id (the run holding the lock)."""
        pids = []
        with contextlib.suppress(OSError):
            for e in os.scandir(self._real):
                m = re.match(rf"^{re.escape(STAGING_PREFIX)}(\d{{8}}T\d{{6}}Z)-(\d+)-", e.name)
                if m:
                    pids.append((m.group(1), m.group(2)))
        return max(pids)[1] if pids else None

    def _lock_file(self):
        path = self._real / LOCK_NAME
        try:
            fd = os.open(path, os.O_RDWR | os.O_CREAT | os.O_NOFOLLOW | os.O_NONBLOCK, 0o666)
        except OSError as exc:
            if exc.errno == errno.ELOOP:
                raise InputError(f"{path}: the lock file is a symbolic link; remove it") from None
            raise InputError(f"{self.folder}: the output folder is not writable ({exc.strerror or exc}); "
                             f"choose another -o") from None
        if not stat.S_ISREG(os.fstat(fd).st_mode):
            os.close(fd)
            raise InputError(f"{path}: the lock file is not a regular file; remove it")
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError as exc:
            holder = os.pread(fd, 64, 0).decode("ascii", "replace").split()
            os.close(fd)
            if exc.errno in (errno.EWOULDBLOCK, errno.EACCES):
                self._busy(holder[0] if holder and holder[0].isdigit() else None)
            raise InputError(f"{path}: cannot lock the output folder ({exc.strerror or exc})") from None
        os.ftruncate(fd, 0)
        os.pwrite(fd, f"{os.getpid()} {self.command} {self.run_id}\n".encode(), 0)
        return fd

    def _unlock(self):
        if self._lock_fd is not None:
            os.close(self._lock_fd)   # releases the flock
            self._lock_fd = None

    # -------------------------------------------------------------------- recovery
    def _recover(self):
        """Complete the commit of a run killed during its swap; remove stagings of runs killed
        before their commit point. Only a plan this user's bayesdrag wrote for this folder is
        carried out (:mod:`bayesdrag.io.commit`); anything else is refused before a file is
        moved: one line, exit status 2. A staging folder of another user is left alone."""
        key = None
        for entry in sorted(os.scandir(self._real), key=lambda e: e.name):
            if not entry.name.startswith(STAGING_PREFIX) or not entry.is_dir(follow_symlinks=False):
                continue
            plan = Path(entry.path) / PLAN
            owner = entry.stat(follow_symlinks=False).st_uid
            if owner != os.getuid():
                if os.path.lexists(plan):
                    raise InputError(f"{plan}: an interrupted commit in a folder of another user (uid {owner}), "
                                     f"never carried out; move {entry.name} out of {self.folder}")
                continue
            if os.path.lexists(plan):
                try:
                    doc = read_json(plan, "commit plan")
                    moves = plan_moves(doc, entry.name)
                    key = key or user_key()
                    check_signature(key, doc, self._real, entry.name)
                    execute(self._real, moves)
                except (InputError, ValueError, TypeError, KeyError, OSError) as exc:
                    detail = str(exc).split(": ", 1)[-1] if isinstance(exc, InputError) else str(exc)
                    raise InputError(f"{plan}: an interrupted commit whose plan cannot be used ({detail}); nothing "
                                     f"was moved by it: move {entry.name} out of {self.folder}") from None
                self._note(f"completed the interrupted commit of run {doc.get('run')} in {self.folder}")
            shutil.rmtree(entry.path, ignore_errors=True)

    def _note(self, msg):
        if self.echo is not None:
            self.echo(f"bayesdrag: note: {msg}")

    # -------------------------------------------------------------------- commit
    def _discard(self):
        if self.staging is not None:
            shutil.rmtree(self.staging, ignore_errors=True)

    def _staged_files(self):
        names = []
        for e in sorted(os.scandir(self.staging), key=lambda e: e.name):
            if e.name.endswith(".part") or e.name == PLAN:
                continue
            if not e.is_file(follow_symlinks=False) or not NAME_RE.match(e.name) or e.name.startswith("."):
                raise OutputError(f"{self.staging}: unexpected entry {e.name!r} in the staging folder")
            names.append(e.name)
        return names

    def _commit(self):
        out, staging = self._real, self.staging
        staged = self._staged_files()
        new = {n: staging / n for n in staged}
        for as_name, name in self._adopted.items():
            if (out / name).is_file():
                new[as_name] = out / name
        files = [{"name": n, "bytes": p.stat().st_size, "sha256": sha256_file(p)} for n, p in sorted(new.items())]
        record = {"run": self.run_id, "command": self.command, "created": _utc_now(), "version": _version(),
                  "inputs": self.inputs, "files": files}
        earlier, old_manifest_run = self._earlier_runs()
        names_new = set(new) | {MANIFEST}
        kept, superseded = [], []
        for r in earlier:
            same = r.get("command") == self.command or not _same_inputs(r.get("inputs"), self.inputs)
            overlap = bool(names_new & set(r["names"]))
            (superseded if same or overlap else kept).append(r)
        kept_names = {n for r in kept for n in r["names"]}
        inputs = {Path(v["path"]) for v in self.inputs.values()}
        moves, sup_doc = [], []
        taken = set()
        for r in superseded:
            rid = self._superseded_id(r["run"], taken)
            moved = [n for n in r["names"] if n not in kept_names and os.path.lexists(out / n)
                     and not _is_input(out / n, inputs)]
            moves += [(n, f"{SUPERSEDED}/{rid}/{n}") for n in moved]
            if r["run"] == old_manifest_run and os.path.lexists(out / MANIFEST):
                moves.append((MANIFEST, f"{SUPERSEDED}/{rid}/{MANIFEST}"))
                moved.append(MANIFEST)
            if moved:
                sup_doc.append({"run": r["run"], "command": r.get("command"), "folder": f"{SUPERSEDED}/{rid}",
                                "files": sorted(set(moved))})
        # a file this run writes that no record claims (a user's file of the same name) is moved
        # too; an earlier manifest whose runs all stay current is replaced (its records are
        # carried into the new one's also_current)
        stray = [n for n in new if os.path.lexists(out / n) and n not in {m[0] for m in moves}
                 and n not in self._adopted.values()]
        clash = [n for n in stray if _is_input(out / n, inputs)]
        if clash:
            raise InputError(f"{self.folder / clash[0]}: an input of this run has the name of an output it writes "
                             f"into {self.folder}; inputs are never moved: rename the input or write to another "
                             f"folder")
        if stray:
            rid = self._superseded_id(f"unlisted-{self.run_id}", taken)
            moves += [(n, f"{SUPERSEDED}/{rid}/{n}") for n in stray]
            sup_doc.append({"run": None, "command": None, "folder": f"{SUPERSEDED}/{rid}", "files": sorted(stray)})
        moves = [(a, b, "out") for a, b in moves]
        stage_rel = staging.name
        moves += [(f"{stage_rel}/{n}", n, "in") for n in staged]
        moves += [(name, as_name, "in") for as_name, name in self._adopted.items() if (out / name).is_file()]
        doc = dict({"format": MANIFEST_FORMAT}, **record, options=self.options, superseded=sup_doc,
                   also_current=[_public_record(r) for r in kept])
        manifest_tmp = staging / MANIFEST
        manifest_tmp.write_text(json.dumps(doc, indent=2, allow_nan=False), encoding="utf-8")
        moves.append((f"{stage_rel}/{MANIFEST}", MANIFEST, "in"))
        plan_doc = {"format": PLAN_FORMAT, "run": self.run_id, "moves": [list(m) for m in moves]}
        key = user_key()
        if key is not None:
            plan_doc["signature"] = signature(key, self._real, staging.name, self.run_id, plan_doc["moves"])
        plan_tmp = staging / f"{PLAN}.part"
        plan_tmp.write_text(json.dumps(plan_doc), encoding="utf-8")
        _fsync(plan_tmp)
        os.replace(plan_tmp, staging / PLAN)          # the commit point
        execute(self._real, [(safe_rel(a), safe_rel(b), k) for a, b, k in moves])
        shutil.rmtree(staging, ignore_errors=True)
        self.staging = None
        self.manifest = doc

    def _superseded_id(self, run, taken):
        base = run if isinstance(run, str) and _RUN_RE.match(run) else f"earlier-{self.run_id}"
        rid, k = base, 2
        while rid in taken or os.path.lexists(self._real / SUPERSEDED / rid):
            rid, k = f"{base}-{k}", k + 1
        taken.add(rid)
        return rid

    def _earlier_runs(self):
        """The runs whose files are current in ``DIR`` (from its manifest; a folder without one
        is one earlier run holding every known output name), and the manifest's own run id."""
        out = self._real
        path = out / MANIFEST
        doc = None
        if path.is_file() and not path.is_symlink():
            try:
                doc = read_json(path, "manifest")
            except InputError:
                doc = None
        runs = []
        if isinstance(doc, dict) and doc.get("format") == MANIFEST_FORMAT:
            for r in [doc] + list(doc.get("also_current") or []):
                rec = _checked_record(r)
                if rec is not None:
                    runs.append(rec)
            if runs:
                return runs, runs[0]["run"]
        names = sorted(e.name for e in os.scandir(out) if e.is_file(follow_symlinks=False)
                       and e.name != PARTIAL_CHAIN and any(fnmatch(e.name, p) for p in KNOWN_OUTPUTS))
        if names:
            runs.append({"run": f"earlier-{self.run_id}", "command": None, "inputs": None, "names": names,
                         "files": [{"name": n} for n in names]})
        return runs, None


def _checked_record(r):
    """A run record from a manifest with plain file names only (None if malformed)."""
    if not isinstance(r, dict) or not isinstance(r.get("run"), str) or not isinstance(r.get("files"), list):
        return None
    names = []
    for f in r["files"]:
        n = f.get("name") if isinstance(f, dict) else None
        if (not isinstance(n, str) or not NAME_RE.match(n) or n.startswith(".") or n == PARTIAL_CHAIN
                or not any(fnmatch(n, p) for p in KNOWN_OUTPUTS)):
            return None           # a manifest names only what bayesdrag writes: never a user's own file
        names.append(n)
    return dict(r, names=names)


def _public_record(r):
    return {k: r.get(k) for k in ("run", "command", "created", "version", "inputs", "files")}


def _same_inputs(a, b):
    """True when two manifests' inputs are the same files by content (roles and SHA-256)."""
    if not isinstance(a, dict) or not isinstance(b, dict) or set(a) != set(b):
        return False
    return all(isinstance(a[k], dict) and a[k].get("sha256") == b[k].get("sha256") for k in a)


def _is_input(path, inputs):
    return any(os.path.lexists(path) and p.exists() and os.path.samefile(path, p) for p in inputs)


def _fsync(path):
    with open(path, "rb") as f:
        os.fsync(f.fileno())


def _utc_now():
    return time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())


def _version():
    import sys

    return str(getattr(sys.modules.get("bayesdrag"), "__version__", "unknown"))
