"""The MCMC chain file: an HDF5 file written in blocks while emcee runs, read back to resume.

emcee's own ``HDFBackend`` opens and closes its file at every step, which cost ~18 ms per step
on the demo track (more than the step's 16 simulations). :class:`ChainBackend` is emcee's memory
backend whose new steps are appended to the file every ``flush_every`` steps (~1 ms per block of
25 steps); a kill loses at most the unflushed block. The file holds the random state of emcee's
generator after its last stored step, so a resumed run continues the exact chain an uninterrupted
run would have produced.

Nothing read from the file is unpickled or evaluated. Every value is read as a typed
number array or a plain string and checked before it is used (:meth:`ChainFile.load_backend`):
a file that is not a chain of this format, of the expected shape, with finite values and a
well-formed random state, made by the same problem and settings, raises
:class:`~bayesdrag.errors.InputError` with one line naming the file and what is wrong.

A chain file is data from a folder someone else may have written (the resume of a planted file
moved a posterior mean by 5 %, copied a secret file's bytes into the outputs, or took 6.7 GB of
memory for a 1.7 MB file), so before any value is read its datasets must be stored inside the
file as this module writes them: contiguous or chunked, not compressed or filtered, not in
external files, not virtual, every chunk of the rows read allocated (no sparse storage), and
no larger than the run's own settings allow (walkers x dimensions exactly, steps at most the
run's ``max_steps``; the file itself at most what such a chain takes). After reading, the log
posterior and blobs stored for every walker's last position and for
:data:`LOG_PROB_SAMPLE` earlier positions drawn at random (unpredictably, so a forger cannot
leave the checked ones genuine; every earlier position when there are fewer) are recomputed with
the run's own posterior, in vectorised batches of :data:`LOG_PROB_BATCH`, and must agree within
:data:`LOG_PROB_ATOL` + :data:`LOG_PROB_RTOL` x |value|: a chain of other numbers is refused
before the sampler continues it.

The sample size is the threat model's (``docs/security.md``): a chain with a fraction
:data:`LOG_PROB_CORRUPT_FRACTION` (1 %) or more of its stored positions changed, their stored
log posterior left as it was (a disk error, a partial copy, an edit), is refused with
probability at least 1 - :data:`LOG_PROB_MISS` (0.999): n draws without replacement all miss
the changed positions with probability at most (1 - 0.01)^n, and n = 688 is the least n with
(1 - 0.01)^n <= 1e-3 (:func:`check_sample_size`). On the demo track the 704 positions
recomputed (16 walkers' last and 688 earlier) take 0.2-0.3 s, against 1.7-3.3 s for the 375
steps its chain samples and 8-13 s for the whole fit (2 shared cores). A forger who also
recomputes the log posterior of the positions they forge (they know the inputs: the
fingerprint is not secret) passes this check: that is outside what a resume can defend
against, and why a run is never resumed in a folder others can write.

Layout (``format = "bayesdrag-chain/2"``), group ``mcmc``:

======================  ===================  ===================================================
name                    type, shape          content
======================  ===================  ===================================================
``chain``               float64 (S, W, D)    walker positions (S >= ``iteration`` steps)
``log_prob``            float64 (S, W)       log posterior of every stored position
``blobs``               float64 (S, W, C)    emcee blobs (residual sums of squares per channel)
``accepted``            float64 (W,)         accepted proposals per walker, 0 .. ``iteration``
``random_state/key``    uint32 (624,)        MT19937 key of emcee's ``RandomState``
attributes of ``mcmc``  str, int             ``format``, ``iteration``, ``bayesdrag_fingerprint``
attributes of           str, int, int,       ``bit_generator`` ("MT19937"), ``pos`` (0 .. 624),
``random_state``        int, float, int      ``has_gauss`` (0/1), ``cached_gaussian``, ``step``
``pending``             group                ``key``, ``accepted`` and the attributes above, as
                                             a flush fills them before it commits its block
======================  ===================  ===================================================

The five random-state fields are those of ``numpy.random.RandomState.get_state()``; ``step`` is
the chain step they belong to (equal to ``iteration`` in a consistent file).

A flush commits its block so that a kill (``kill -9``, the machine stopping the process) at any
point leaves a chain that resumes exactly: the block's rows, then ``pending`` (key, counts, the
state's fields, and its ``step`` last) are flushed to the file; then ``iteration`` is set (the
commit); then ``random_state`` and ``accepted`` are rewritten the same way and ``pending``'s
``step`` set to -1. Each flush writes what came before it, and each single attribute is one
header write, so the file always holds a complete state for its ``iteration``: in
``random_state`` when its ``step`` equals ``iteration``, else in ``pending`` (a kill between the
commit and the rewrite). Rewriting the one state in place could leave, under a kill, a new key
with an old ``step``, or counts of bytes never written (a resume refused "'accepted' holds
values that are not counts"). The file is not synced to disk: a power cut may still leave a
chain that is refused, never one that is silently wrong (the checks above).

The fingerprint stored is the sampler's (problem, walkers, moves, seed) combined with the digest of
the input files' bytes when the command gives one (``ChainFile(path, inputs=...)``): a chain made
from other track or round files, or copied from another folder made from other inputs, is refused.
The chain path must be a regular file (or absent): a symbolic link or a device planted at
``chain.partial.h5`` is refused before it is opened, so starting a chain never truncates another
file. Before each block is appended the free disk space and the file size limit of the process
(``ulimit -f``) are checked (:func:`bayesdrag.io.space.ensure_space`): running out stops the
run with one line and the blocks already written intact, instead of an HDF5 write failing
half-way (which crashed h5py: a segfault for ``EFBIG``).
"""
from __future__ import annotations

import hashlib
import itertools
import math
import os
import re
import stat

import emcee
import h5py
import numpy as np

from ..errors import InputError
from .space import DiskFullError, ensure_file_size, ensure_space, space_problem

#: value of the ``format`` attribute written and accepted
FORMAT = "bayesdrag-chain/2"
#: name of the HDF5 group holding the chain
GROUP = "mcmc"
#: the only bit generator emcee's ``RandomState`` uses, and its key length
BIT_GENERATOR = "MT19937"
MT_KEY_SIZE = 624
_FINGERPRINT_RE = re.compile(r"^[0-9a-f]{1,64}$")
#: the group of the random state of the committed step, and the one a flush fills before it commits
STATE, PENDING = "random_state", "pending"
_AFRESH = "delete it to start the chain afresh"
#: fraction of a chain's stored positions whose corruption the resume check must catch
LOG_PROB_CORRUPT_FRACTION = 0.01
#: largest probability that the resume check misses such a corruption
LOG_PROB_MISS = 1e-3


def check_sample_size(fraction=LOG_PROB_CORRUPT_FRACTION, miss=LOG_PROB_MISS):
    """Positions to recompute so that a chain with ``fraction`` of its positions corrupted is
    caught with probability at least ``1 - miss``.

    Draws without replacement from N positions of which ``k = fraction N`` are corrupt all miss
    them with probability ``C(N - k, n) / C(N, n) <= (1 - fraction)^n``; this is the least ``n``
    with ``(1 - fraction)^n <= miss``.

    Parameters
    ----------
    fraction : float
        Fraction of positions corrupted, in (0, 1).
    miss : float
        Largest acceptable probability of missing the corruption, in (0, 1).

    Returns
    -------
    int
        The sample size (688 for 1 % and 1e-3).
    """
    n = math.ceil(math.log(miss) / math.log1p(-fraction))
    # the ceiling of a rounded quotient: step back when n - 1 draws already suffice
    return n - 1 if n > 1 and (1.0 - fraction) ** (n - 1) <= miss else n


#: stored positions (besides every walker's last one) whose log posterior is recomputed on resume
LOG_PROB_SAMPLE = check_sample_size()
#: positions per call of the log posterior when recomputing (one call simulates the whole track
#: for each: bounds the memory of a call, ~40 kB per position on the demo track)
LOG_PROB_BATCH = 1024
#: agreement required between a stored and a recomputed log posterior (and blob): the same code
#: on the same inputs gives the same number to round-off; a forged chain is off by far more
LOG_PROB_ATOL = 1e-6
LOG_PROB_RTOL = 1e-9
#: HDF5 overhead a chain file may carry beyond its numbers [bytes] (headers, the random state,
#: the space of the 'accepted' datasets rewritten at each flush)
FILE_SLACK = 8 << 20
_LAYOUTS = {h5py.h5d.CONTIGUOUS: "contiguous", h5py.h5d.CHUNKED: "chunked", h5py.h5d.COMPACT: "compact"}


class ChainFile:
    """The chain file at ``path``.

    Parameters
    ----------
    path : str or path-like
        The HDF5 file (``DIR/chain.partial.h5`` for ``bayesdrag fit``).
    flush_every : int, keyword-only
        Steps kept in memory before they are appended to the file (default 25).
    inputs : str, keyword-only, optional
        Digest of the input files' bytes (:attr:`bayesdrag.io.outputs.OutputRun.inputs_digest`),
        combined with every fingerprint written and checked.
    max_steps : int, keyword-only, optional
        The run's step limit: a stored chain of more steps is refused before it is read. A
        ``ChainFile`` given as ``path`` passes its own on.
    """

    def __init__(self, path, *, flush_every=25, inputs=None, max_steps=None):
        if max_steps is None:
            max_steps = getattr(path, "max_steps", None)
        self.path = os.fspath(path)
        self.flush_every = int(flush_every)
        self.inputs = None if inputs is None else str(inputs)
        self.max_steps = None if max_steps is None else int(max_steps)

    def __fspath__(self):
        return self.path

    def exists(self):
        """True when something is stored at ``path`` (whether it is a valid chain is checked by
        :meth:`load_backend`)."""
        return os.path.lexists(self.path)

    def fingerprint(self, base):
        """The fingerprint stored for a sampler fingerprint ``base``: ``base`` itself, or its hash
        with the inputs' digest."""
        if self.inputs is None:
            return str(base)
        return hashlib.sha256(f"{base}:{self.inputs}".encode()).hexdigest()[:16]

    def _check_kind(self):
        """Refuse a path that is a symbolic link or not a regular file (opened by name later)."""
        try:
            st = os.lstat(self.path)
        except FileNotFoundError:
            return
        if not stat.S_ISREG(st.st_mode):
            kind = "a symbolic link" if stat.S_ISLNK(st.st_mode) else "not a regular file"
            raise InputError(f"{self.path}: the chain file is {kind}; {_AFRESH}")

    def new_backend(self, nwalkers, ndim, *, fingerprint):
        """A fresh :class:`ChainBackend`; the file is (re)created holding no step.

        Parameters
        ----------
        nwalkers, ndim : int
            Walkers W and sampled dimensions D.
        fingerprint : str
            Hex digest of what defines the chain (data, settings), checked when resuming.
        """
        self._check_kind()
        fingerprint = self.fingerprint(fingerprint)
        with h5py.File(self.path, "w") as f:
            g = f.create_group(GROUP)
            g.attrs["format"] = FORMAT
            g.attrs["iteration"] = 0
            g.attrs["bayesdrag_fingerprint"] = str(fingerprint)
        return ChainBackend(self, nwalkers, ndim, flushed=0)

    def load_backend(self, *, nwalkers, ndim, nblobs, fingerprint, max_steps=None, log_prob=None, rng=None):
        """The stored chain as a :class:`ChainBackend`, after checking every value read.

        Parameters
        ----------
        nwalkers, ndim : int
            Walkers W and sampled dimensions D this run needs.
        nblobs : int
            Blob columns C per walker this run produces (0: none).
        fingerprint : str
            The fingerprint this run computes; the stored one must be equal.
        max_steps : int, optional
            The run's step limit (default: the file's :attr:`max_steps`; None: not bounded).
        log_prob : callable, optional
            The run's log posterior: ``log_prob(X)`` of positions (m, D) gives (m, 1 + C), the
            log posterior and the blobs. When given, stored values are recomputed (module
            docstring) and must agree.
        rng : numpy.random.Generator, optional
            Draws the positions checked (default: fresh entropy).

        Returns
        -------
        ChainBackend or None
            None when the file holds no step yet (a run killed before its first block).

        Raises
        ------
        InputError
            One line naming the file and what is wrong: not an HDF5 file or truncated, not a
            chain of this format (a file with a pickled random state included), another problem
            or settings, datasets of the wrong type or shape, stored outside the file, virtual,
            compressed or sparse, more steps than ``max_steps``, non-finite values, a malformed
            random state, or stored values the posterior does not reproduce.
        """
        self._check_kind()
        W, D, C = int(nwalkers), int(ndim), int(nblobs)
        limit = self.max_steps if max_steps is None else int(max_steps)
        if limit is not None:
            self._check_file_size(W, D, C, limit)
        try:
            with h5py.File(self.path, "r") as f:
                b = self._read(f, W, D, C, self.fingerprint(fingerprint), limit)
        except InputError:
            raise
        except (OSError, KeyError, ValueError, TypeError, RuntimeError, MemoryError) as exc:
            detail = " ".join(str(exc).split()) or type(exc).__name__
            raise InputError(f"{self.path}: not a readable chain file ({detail}); {_AFRESH}") from None
        if b is not None and log_prob is not None:
            self._check_log_prob(b, log_prob, rng if rng is not None else np.random.default_rng())
        return b

    def _check_file_size(self, W, D, C, max_steps):
        """Refuse a file larger than a chain of this run's settings can be, before opening it."""
        size = os.stat(self.path).st_size
        bound = 8 * W * (D + 1 + C) * (max_steps + 64) + 8 * W + FILE_SLACK
        if size > bound:
            self._fail(f"the file is {size} bytes, more than a chain of {W} walkers x {max_steps} steps x {D} "
                       f"dimensions takes ({bound}): not a chain of this run")

    def _check_log_prob(self, b, log_prob, rng):
        """Recompute the stored log posterior (and blobs) at every walker's last position and at
        :data:`LOG_PROB_SAMPLE` random earlier ones (all of them when there are fewer), in
        batches of :data:`LOG_PROB_BATCH` positions."""
        n, W = b.log_prob.shape
        rows, walkers = [n - 1] * W, list(range(W))
        earlier = (n - 1) * W
        if earlier:
            pick = rng.choice(earlier, size=min(LOG_PROB_SAMPLE, earlier), replace=False)
            rows += list(pick // W)
            walkers += list(pick % W)
        rows, walkers = np.asarray(rows), np.asarray(walkers)
        X = b.chain[rows, walkers]
        parts = []
        with np.errstate(all="ignore"):
            for a in range(0, rows.size, LOG_PROB_BATCH):
                part = np.asarray(log_prob(X[a:a + LOG_PROB_BATCH]), dtype=float)
                parts.append(part.reshape(min(LOG_PROB_BATCH, rows.size - a), -1))
        widths = {p.shape[1] for p in parts}
        stored = b.log_prob[rows, walkers][:, None]
        if b.blobs is not None:
            stored = np.concatenate([stored, b.blobs[rows, walkers].reshape(rows.size, -1)], axis=1)
        if widths != {stored.shape[1]}:
            self._fail(f"the run's posterior gives {max(widths)} values per position, the chain stores "
                       f"{stored.shape[1]}")
        out = np.concatenate(parts, axis=0)
        ok = np.abs(out - stored) <= LOG_PROB_ATOL + LOG_PROB_RTOL * np.abs(stored)
        if not ok.all():
            i, j = np.argwhere(~ok)[0]
            what = "log posterior" if j == 0 else f"blob {j}"
            self._fail(f"the stored {what} at step {rows[i] + 1}, walker {walkers[i] + 1} is {stored[i, j]:.10g}, "
                       f"the posterior of these inputs gives {out[i, j]:.10g} at that position: not a chain this "
                       f"run made")

    # ------------------------------------------------------------------------------------
    def _fail(self, what):
        raise InputError(f"{self.path}: {what}; {_AFRESH}")

    def _read(self, f, W, D, C, fingerprint, max_steps=None):
        g = _member(f, GROUP, h5py.Group)
        if g is None:
            self._fail(f"no group '{GROUP}': not a bayesdrag chain file")
        if "format" not in g.attrs:
            if "random_state" in g.attrs:
                self._fail("written by an earlier bayesdrag version that stored its random state with "
                           "pickle, which is never loaded")
            self._fail("no 'format' attribute: not a bayesdrag chain file")
        fmt = _attr_str(g, "format")
        if fmt != FORMAT:
            self._fail(f"format {_shown(fmt, g.attrs['format'])} is not supported (expected {FORMAT!r})")
        n = _attr_int(g, "iteration")
        if n is None or n < 0:
            self._fail("its 'iteration' attribute is missing or not a non-negative integer")
        if n == 0:
            return None
        old = _attr_str(g, "bayesdrag_fingerprint")
        if old is None or not _FINGERPRINT_RE.match(old):
            self._fail("its 'bayesdrag_fingerprint' attribute is missing or not a hex digest")
        if old != fingerprint:
            self._fail(f"the stored chain was made with other inputs or settings (fingerprint {old} != "
                       f"{fingerprint})")
        if max_steps is not None and n > max_steps:
            self._fail(f"it holds {n} steps, more than this run's --max-steps {max_steps} (resume with "
                       f"--max-steps {n} or more)")
        state, accepted = _committed_slot(g, n)
        names = [("chain", (W, D), n), ("log_prob", (W,), n), (accepted, (W,), None)]
        names += [("blobs", (W, C), n)] if C else []
        datasets = {name: self._dataset(g, name, tail, rows, max_steps) for name, tail, rows in names}
        chain = self._array(datasets["chain"], "chain", n)
        lp = self._array(datasets["log_prob"], "log_prob", n)
        blobs = self._array(datasets["blobs"], "blobs", n) if C else None
        acc = self._array(datasets[accepted], accepted, None)
        stored = max(n, int(datasets["chain"].shape[0]))
        if np.any(acc < 0) or np.any(acc > stored) or np.any(acc != np.round(acc)):
            self._fail(f"'{accepted}' holds values that are not counts in 0..{stored}")
        # a file written before the two-slot commit, killed after 'accepted' and before
        # 'iteration' were written, holds counts of uncommitted steps: held to the committed ones
        acc = np.minimum(acc, n)
        b = ChainBackend(self, W, D, flushed=n)
        b.chain, b.log_prob, b.blobs, b.accepted = chain, lp, blobs, acc
        b.iteration, b.random_state = n, self._random_state(g, n, state)
        return b

    def _dataset(self, g, name, tail, n, max_steps):
        """Float dataset ``name`` of shape ``(>= n,) + tail`` (``tail`` only when n is None),
        stored as this module stores it (module docstring), checked before any value is read."""
        ds = _member(g, name, h5py.Dataset)
        if ds is None:
            self._fail(f"dataset '{name}' is missing or not stored in this file")
        if ds.dtype.kind != "f":
            self._fail(f"dataset '{name}' has type {ds.dtype.str!r}, expected floating point")
        shape = tuple(ds.shape)
        ok = shape == tail if n is None else (len(shape) == 1 + len(tail) and shape[1:] == tail and shape[0] >= n)
        if not ok:
            need = tail if n is None else (f">={n}",) + tail
            self._fail(f"dataset '{name}' has shape {shape}, this run needs ({', '.join(map(str, need))})")
        if n is not None and max_steps is not None and shape[0] > max_steps + self.flush_every:
            self._fail(f"dataset '{name}' has {shape[0]} rows, more than this run's --max-steps {max_steps}")
        self._check_storage(ds, name, shape[0] if n is None else n)
        return ds

    def _check_storage(self, ds, name, rows):
        """Refuse data stored outside the file, virtual, compressed or not allocated (sparse)."""
        if ds.is_virtual:
            self._fail(f"dataset '{name}' is a virtual dataset (its values are in other files)")
        if ds.external:
            self._fail(f"dataset '{name}' is stored in external files")
        dcpl = ds.id.get_create_plist()
        layout = dcpl.get_layout()
        if layout not in (h5py.h5d.CONTIGUOUS, h5py.h5d.CHUNKED):
            self._fail(f"dataset '{name}' has {_LAYOUTS.get(layout, 'unknown')} storage, expected contiguous or "
                       f"chunked")
        if dcpl.get_nfilters():
            self._fail(f"dataset '{name}' is compressed or filtered")
        if rows == 0:
            return
        if layout == h5py.h5d.CONTIGUOUS:
            need = rows * int(np.prod(ds.shape[1:], dtype=np.int64)) * ds.dtype.itemsize
            allocated = ds.id.get_storage_size() >= need
        else:
            chunk = ds.chunks
            ranges = [range(0, rows, chunk[0])] + [range(0, s, c) for s, c in zip(ds.shape[1:], chunk[1:])]
            allocated = all(ds.id.get_chunk_info_by_coord(tuple(int(v) for v in corner)).byte_offset is not None
                            for corner in itertools.product(*ranges))
        if not allocated:
            self._fail(f"dataset '{name}' is sparse: part of its first {rows} rows is not stored in the file")

    def _array(self, ds, name, n):
        """The first n rows of a checked dataset (all of it when n is None), all finite."""
        a = np.asarray(ds[()] if n is None else ds[:n], dtype=np.float64)
        if not np.all(np.isfinite(a)):
            self._fail(f"dataset '{name}' holds non-finite values")
        return a

    def _random_state(self, g, n, slot=STATE):
        """The stored ``RandomState`` state tuple of group ``slot``, checked field by field and by numpy."""
        rg = _member(g, slot, h5py.Group)
        key = None if rg is None else _member(rg, "key", h5py.Dataset)
        if key is None:
            self._fail(f"the random state ('{slot}/key') is missing or not stored in this file")
        if key.dtype != np.dtype(np.uint32) or tuple(key.shape) != (MT_KEY_SIZE,):
            self._fail(f"'{slot}/key' is {key.dtype.str} {tuple(key.shape)}, expected uint32 "
                       f"({MT_KEY_SIZE},)")
        self._check_storage(key, f"{slot}/key", MT_KEY_SIZE)
        name = _attr_str(rg, "bit_generator")
        pos, has_gauss, step = (_attr_int(rg, k) for k in ("pos", "has_gauss", "step"))
        cached = _attr_float(rg, "cached_gaussian")
        if name != BIT_GENERATOR:
            self._fail(f"random state 'bit_generator' {_shown(name, _attr(rg, 'bit_generator'))}, "
                       f"expected {BIT_GENERATOR!r}")
        if pos is None or not 0 <= pos <= MT_KEY_SIZE:
            self._fail(f"random state 'pos' must be an integer in 0..{MT_KEY_SIZE}")
        if has_gauss not in (0, 1):
            self._fail("random state 'has_gauss' must be 0 or 1")
        if cached is None or not np.isfinite(cached):
            self._fail("random state 'cached_gaussian' must be a finite number")
        if step is None:
            self._fail("random state 'step' must be an integer")
        if step != n:
            self._fail(f"the random state belongs to step {step}, the chain has {n} steps (the run was "
                       f"killed while writing)")
        state = (BIT_GENERATOR, np.array(key[()], dtype=np.uint32), pos, has_gauss, cached)
        try:
            np.random.RandomState().set_state(state)
        except (ValueError, TypeError) as exc:
            self._fail(f"the random state is not valid ({exc})")
        return state


class ChainBackend(emcee.backends.Backend):
    """emcee's memory backend that appends its new steps to a :class:`ChainFile`.

    Parameters
    ----------
    file : ChainFile
    nwalkers, ndim : int
    flushed : int, keyword-only
        Steps already in the file.
    """

    def __init__(self, file, nwalkers, ndim, *, flushed):
        super().__init__()
        self.reset(nwalkers, ndim)
        self.file = file
        self.flushed = int(flushed)

    def save_step(self, state, accepted):
        super().save_step(state, accepted)
        if self.iteration - self.flushed >= self.file.flush_every:
            self.flush()

    def flush(self):
        """Append the steps not yet in the file, then the random state and ``iteration``."""
        n0, n1 = self.flushed, self.iteration
        if n1 <= n0:
            return
        W, D = self.nwalkers, self.ndim
        C = 0 if self.blobs is None else (self.blobs.shape[2] if self.blobs.ndim == 3 else 1)
        # HDF5 allocates whole chunks of 32 steps; twice the block and a chunk spare
        need = 8 * W * (D + 1 + C) * (2 * (n1 - n0) + 64) + 8 * W + 8192
        path = self.file.path
        folder = os.path.dirname(os.path.abspath(path))
        ensure_space(folder, need, os.path.basename(path))
        ensure_file_size(path, need)
        try:
            self._append(n0, n1)
        except (OSError, RuntimeError) as exc:
            why = space_problem(exc, folder)
            if why is not None:
                raise DiskFullError(f"{path}: {why} while writing the chain", reason=why) from None
            raise
        self.flushed = n1

    def _append(self, n0, n1):
        with h5py.File(self.file.path, "a") as f:
            g = f[GROUP]
            W, D = self.nwalkers, self.ndim
            if "chain" not in g:
                g.create_dataset("chain", (0, W, D), maxshape=(None, W, D), dtype="f8", chunks=(32, W, D))
                g.create_dataset("log_prob", (0, W), maxshape=(None, W), dtype="f8", chunks=(32, W))
                if self.blobs is not None:
                    C = self.blobs.shape[2] if self.blobs.ndim == 3 else 1
                    g.create_dataset("blobs", (0, W, C), maxshape=(None, W, C), dtype="f8", chunks=(32, W, C))
            for name, arr in (("chain", self.chain), ("log_prob", self.log_prob), ("blobs", self.blobs)):
                if arr is None or name not in g:
                    continue
                g[name].resize(n1, axis=0)
                g[name][n0:n1] = np.asarray(arr[n0:n1], float).reshape((n1 - n0,) + g[name].shape[1:])
            # the block's steps are in the file before the state of its last step is, and that
            # state before the step it belongs to is committed: a kill anywhere in a flush leaves
            # a file whose committed step has its rows, counts and random state (module docstring)
            acc = np.asarray(self.accepted, float)
            pending = g.require_group(PENDING)
            _write_state(pending, pending, self.random_state, acc, n1)
            f.flush()
            g.attrs["iteration"] = n1
            f.flush()
            _write_state(g.require_group(STATE), g, self.random_state, acc, n1)
            g[PENDING].attrs["step"] = -1


def _write_state(rg, counts_parent, state, accepted, step):
    """Store a ``RandomState.get_state()`` tuple as typed fields of group ``rg``, with the accepted
    counts as ``counts_parent['accepted']``; ``step`` is written last, after a flush, so the slot
    names its step only once everything else it holds is in the file."""
    name, key, pos, has_gauss, cached = state
    key = np.asarray(key, dtype=np.uint32)
    for parent, ds, value in ((rg, "key", key), (counts_parent, "accepted", accepted)):
        if ds in parent and parent[ds].shape == value.shape and parent[ds].dtype == value.dtype:
            parent[ds][...] = value
        else:
            if ds in parent:
                del parent[ds]
            parent.create_dataset(ds, data=value)
    rg.attrs["bit_generator"] = str(name)
    rg.attrs["pos"] = int(pos)
    rg.attrs["has_gauss"] = int(has_gauss)
    rg.attrs["cached_gaussian"] = float(cached)
    rg.file.flush()
    rg.attrs["step"] = int(step)


def _committed_slot(g, n):
    """The group holding the random state of committed step ``n`` and the path of its accepted
    counts: ``random_state`` and ``accepted``, or ``pending`` (a hard-linked group only) when a
    kill landed after step ``n`` was committed and before ``random_state`` was rewritten; errors
    name the slot read."""
    if _slot_step(g, STATE) != n and _slot_step(g, PENDING) == n:
        return PENDING, f"{PENDING}/accepted"
    return STATE, "accepted"


def _slot_step(g, slot):
    rg = _member(g, slot, h5py.Group)
    return None if rg is None else _attr_int(rg, "step")


def _member(parent, name, kind):
    """``parent[name]`` when it is a hard-linked object of type ``kind`` (no soft or external
    links to elsewhere), else None."""
    link = parent.get(name, getlink=True)
    if not isinstance(link, h5py.HardLink):
        return None
    obj = parent.get(name)
    return obj if isinstance(obj, kind) else None


def _attr(obj, name):
    """Attribute value as stored (numbers, strings or opaque bytes; h5py never unpickles)."""
    return obj.attrs[name] if name in obj.attrs else None


def _attr_str(obj, name):
    v = _attr(obj, name)
    if isinstance(v, (bytes, np.bytes_)):
        try:
            v = bytes(v).decode("ascii")
        except UnicodeDecodeError:
            return None
    return v if isinstance(v, str) else None


def _attr_int(obj, name):
    v = _attr(obj, name)
    if isinstance(v, (bool, np.bool_)) or not isinstance(v, (int, np.integer)):
        return None
    return int(v)


def _attr_float(obj, name):
    v = _attr(obj, name)
    if isinstance(v, (bool, np.bool_)) or not isinstance(v, (int, float, np.integer, np.floating)):
        return None
    return float(v)


def _shown(text, raw):
    """A short printable description of an attribute value for an error message."""
    if text is not None:
        return repr(text[:40])
    return "missing" if raw is None else f"of type {type(raw).__name__}"
