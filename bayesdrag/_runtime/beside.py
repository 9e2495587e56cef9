"""Work done in a forked process beside this one, its answer handed back as JSON.

Some of a fit's work does not depend on what runs meanwhile: the model check's diagnosis reads
the track and the round only, and the added effects' sizes cannot change what is sampled. On a
machine with a free core such work runs in a forked child (:func:`started_beside`,
:func:`computed_beside`) while this process fits and samples. The child inherits the fit's
arrays (nothing is pickled); its answer comes back through a pipe as JSON text, which only this
package's own child writes, and is read with ``json.loads`` (no pickle: the rule for anything
read). Without a free core, on a platform without ``fork``, or when the child fails, the work is
done here when its answer is asked for: the same answer either way.
"""
from __future__ import annotations

import contextlib
import json
import os
import signal
import sys
import threading
import warnings
from typing import Any, Callable, Iterator

from ..errors import FitWarning

__all__ = ["free_core", "started_beside", "BesideJob", "computed_beside", "Beside", "plain_json"]


#: the child's scheduling niceness: it yields the cores to the caller, whose work is the one
#: waited for, and takes what is left
CHILD_NICE = 10


def free_core() -> bool:
    """A forked process can run beside this one: Linux with fork, this process's only Python
    thread (a thread holding a lock at the fork would leave it held in the child: a Dask
    worker's), and a second core idle: the 1-minute load below the cores minus one half, or,
    above it, no more threads runnable now than this one on all but one of the cores this
    process may use (on a busy machine the two would only take turns).

    The load average alone counts this process's own children of the last minute: fits run one
    after another (a campaign, a benchmark) stopped forking after the first few (load 1.5-1.9
    on 2 cores from them alone; benchmarks/fit.py's fit then took 1.6 s instead of 1.15 s).
    The count of runnable threads alone refuses on any passing process."""
    if not sys.platform.startswith("linux") or not hasattr(os, "fork") or threading.active_count() != 1:
        return False
    cpus = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)
    if cpus < 2:
        return False
    if os.getloadavg()[0] < cpus - 0.5:
        return True
    others = _others_running()
    return others is not None and others <= cpus - 2


def _others_running() -> int | None:
    """Threads runnable now on this machine besides the caller (``/proc/loadavg``'s fourth
    field counts them, the caller included), or None when it cannot be read."""
    try:
        with open("/proc/loadavg", encoding="ascii") as f:
            return int(f.read().split()[3].split("/")[0]) - 1
    except (OSError, ValueError, IndexError):
        return None


def plain_json(obj: Any) -> Any:
    """``json.dumps``'s ``default``: numpy arrays as lists, numpy scalars as Python numbers, a
    fit's warning as its sentence."""
    tolist = getattr(obj, "tolist", None)
    if tolist is not None:
        return tolist()
    if isinstance(obj, FitWarning):
        return str(obj)
    raise TypeError(f"{type(obj).__name__} is not JSON serialisable")


class BesideJob:
    """``fn()`` started in a forked child (or to be run here), collected by :meth:`result`.

    Attributes
    ----------
    forked : bool
        Whether the child's answer was used (known once :meth:`result` has returned).
    """

    def __init__(self, fn: Callable[[], Any], fork: bool) -> None:
        self.fn = fn
        self.forked = False
        self._child = _fork(fn) if fork and free_core() else None
        self._done = False
        self._value: Any = None

    @property
    def pid(self) -> int | None:
        """The child's process id while it runs uncollected (None: no child, or collected)."""
        return None if self._child is None else self._child[0]

    def result(self) -> Any:
        """``fn()``'s value: the child's after a JSON round trip (waited for: its work is the
        caller's, no time limit), or ``fn()`` run here when no child was started or it failed
        (its exceptions are the caller's). The second call returns the first's value."""
        if self._done:
            return self._value
        text = None
        if self._child is not None:
            pid, fd = self._child
            self._child = None
            try:
                text = _read_all(fd)
                _, status = os.waitpid(pid, 0)
            except BaseException:
                _kill(pid)
                raise
            finally:
                os.close(fd)
            if os.waitstatus_to_exitcode(status) != 0:
                text = None
        value = None
        if text is not None:
            try:
                value, self.forked = json.loads(text), True
            except ValueError:
                text = None
        if text is None:
            value = self.fn()
        self._value, self._done = value, True
        return value

    def cancel(self) -> None:
        """Kill the child, if one runs (its answer is not wanted)."""
        if self._child is not None:
            pid, fd = self._child
            self._child = None
            _kill(pid)
            os.close(fd)


@contextlib.contextmanager
def started_beside(fn: Callable[[], Any], *, fork: bool = True) -> Iterator[BesideJob]:
    """Start ``fn()`` in a forked child and yield its :class:`BesideJob`; leaving the ``with``
    kills a child whose answer was not collected (the body raised, or did not need it).

    ``fn`` must be deterministic, must not write files, and its value must survive a JSON round
    trip (numbers, strings, lists, dicts; numpy arrays become lists). The body must not change
    what ``fn`` reads. ``fork=False``, no free core (:func:`free_core`), a failed fork or a child
    that fails: :meth:`BesideJob.result` runs ``fn()`` here.
    """
    job = BesideJob(fn, fork)
    try:
        yield job
    finally:
        job.cancel()


class Beside:
    """The answer of :func:`computed_beside`, set when the ``with`` body has finished.

    Attributes
    ----------
    value : object
        ``fn()``'s value after a JSON round trip (lists for arrays, as ``result.json`` holds
        them), or ``fn()`` itself when it ran here.
    forked : bool
        Whether the child's answer was used.
    """

    def __init__(self) -> None:
        self.value: Any = None
        self.forked = False


@contextlib.contextmanager
def computed_beside(fn: Callable[[], Any], *, fork: bool = True) -> Iterator[Beside]:
    """Compute ``fn()`` in a forked child while the body of the ``with`` runs: the yielded
    :class:`Beside` holds its value once the body has finished (:func:`started_beside` with the
    answer collected at the end of the body; the child is killed when the body raises)."""
    out = Beside()
    with started_beside(fn, fork=fork) as job:
        yield out
        out.value = job.result()
        out.forked = job.forked


def _fork(fn):
    """Fork a child that writes ``json.dumps(fn())`` to a pipe and exits (0: written); returns
    ``(pid, read end)``, or None when the pipe or the fork fails."""
    try:
        r, w = os.pipe()
    except OSError:
        return None
    with warnings.catch_warnings():           # Python >= 3.12 warns about forking with threads alive
        warnings.simplefilter("ignore", DeprecationWarning)
        try:
            pid = os.fork()
        except OSError:
            os.close(r)
            os.close(w)
            return None
    if pid:
        os.close(w)
        return pid, r
    code = 1
    try:                                       # the child: compute, write, leave without cleanup handlers
        os.close(r)
        signal.signal(signal.SIGINT, signal.SIG_DFL)
        with contextlib.suppress(OSError):
            os.nice(CHILD_NICE)
        with warnings.catch_warnings():        # the parent says what the work warns about when it reruns it
            warnings.simplefilter("ignore")
            data = json.dumps(fn(), default=plain_json).encode()
        view = memoryview(data)
        while view:
            view = view[os.write(w, view):]
        code = 0
    finally:
        os._exit(code)


def _read_all(fd):
    """Everything written to pipe ``fd`` until its write end closes, as text."""
    parts = []
    while True:
        b = os.read(fd, 1 << 20)
        if not b:
            return b"".join(parts).decode()
        parts.append(b)


def _kill(pid):
    """Kill child ``pid`` and reap it (it may have exited already)."""
    with contextlib.suppress(OSError):
        os.kill(pid, signal.SIGKILL)
    with contextlib.suppress(OSError):
        os.waitpid(pid, 0)
