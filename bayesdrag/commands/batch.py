"""Running the rounds of a campaign: ``bayesdrag batch CAMPAIGN.toml -o DIR`` on Dask, and the
sequential runner behind ``bayesdrag fit CAMPAIGN.toml -o DIR``.

Decisions written down:

* **One task per round** (:func:`round_task`): it reads the round's files itself, runs the
  jobs (``fit``: the same pipeline and outputs as ``bayesdrag fit`` for one round, through
  :func:`bayesdrag.commands.fit.run_fit`; ``diagnose``: :func:`bayesdrag.commands.diagnose.run_diagnose`) into ``DIR/<name>/`` and returns a small
  dict (status, seconds, message). Nothing big crosses the scheduler: the campaign pooling
  reads each round's ``pooling.json`` (Cd and its covariance on the campaign nodes, a few kB).
* **Done means a marker**: a job is finished when ``DIR/<name>/done.<job>.json`` exists. It is
  one of the job's outputs, committed with them as one set (:class:`~bayesdrag.io.outputs.OutputRun`:
  a kill leaves either the earlier set or the new one), and records a fingerprint of the
  inputs (SHA-256 of the track, the round file and the files it references) and of the
  options that change results. A rerun skips a job whose marker matches; a batch killed
  mid-way therefore resumes where it stopped, and a round whose inputs or options changed is
  redone, not silently kept. The ``fit`` marker also records the SHA-256 of the outputs the
  pooling reads (``result.json``, ``pooling.json``); a marker without them (an earlier
  version) is redone.
* **Pooling trusts no file of a round's folder** (:func:`pool_campaign`): ``pooling.json`` must
  be a bounded pooling input (:func:`bayesdrag.campaign.pooling.check_input`: Cd in (0, 5],
  a covariance, bounded sizes), name its own round, be byte for byte the file the round's fit
  wrote, as ``result.json`` (the hashes in ``done.fit.json``), and agree with ``result.json``'s
  Cd rows (:func:`bayesdrag.campaign.pooling.check_against_result`). A round failing any of
  these is left out of the pooling with one line naming it and the file (a Cd of 1e300 pooled
  to 9.7e151; both files edited by +5 % moved the campaign Cd by +5 %). A forger who rewrites
  the marker's hashes and both files consistently is outside this check (``docs/security.md``).
* **A failing round does not stop the others**: its exception is caught in the task and
  reported (name, error) at the end; the exit status is then 1 (outputs of the other rounds
  and the pooled campaign are still written).
* **Same code path for a local cluster and a real scheduler**: ``--scheduler ADDRESS`` makes a
  :class:`distributed.Client` to that address; otherwise a
  :class:`distributed.LocalCluster` with ``--workers`` processes of one thread each. Workers get
  ``NUMBA_NUM_THREADS=1`` (and one BLAS thread) so two workers do not oversubscribe two cores;
  each worker loads the numba kernel from its on-disk cache (compiled once). On a remote
  cluster the campaign's files and ``DIR`` must be on a file system the workers share.
* **Progress**: a tqdm bar over :func:`distributed.as_completed` on stderr.
"""
from __future__ import annotations

import contextlib
import os
import stat
import sys
import time
from pathlib import Path

from .._runtime.renamed import renamed_getattr
from ..errors import InputError
from ..io.csv import read_toml
from ..io.outputs import OutputRun, read_json, sha256_file, write_json
from ..io.tracks import read_track
from ..options import JOBS, FitOptions

__all__ = ["run_campaign", "round_task", "pool_campaign", "say_done", "fingerprint", "job_done"]
#: environment of every worker process: one thread per numeric library
WORKER_ENV = {"NUMBA_NUM_THREADS": "1", "OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1",
              "MKL_NUM_THREADS": "1"}
POOLING = "pooling.json"
#: the fit's outputs whose SHA-256 its done marker records: what the pooling reads
HASHED_OUTPUTS = ("result.json", POOLING)
#: largest done marker read [bytes]
MAX_MARKER_BYTES = 1 << 20


def marker_path(outdir, job):
    """``DIR/<name>/done.<job>.json``."""
    return Path(outdir) / f"done.{job}.json"


def fingerprint(track, round_path, job, options):
    """Fingerprint of a job's inputs: file hashes (track, round, reference drag, met profile)
    and the options that change its results. Paths are not part of it (moving a campaign
    folder keeps its results valid)."""
    from ..io.rounds import read_round, round_files

    files = {"track": sha256_file(track), "round": sha256_file(round_path)}
    try:
        rnd = read_round(round_path)
    except InputError:
        rnd = None
    if rnd is not None:
        files.update({k: sha256_file(p) for k, p in round_files(round_path, rnd).items() if k != "round"})
    opts = options.to_dict() if job == "fit" else {}
    return {"job": job, "files": files, "options": opts}


def job_done(outdir, job, fp):
    """True if the job's marker exists and its fingerprint equals ``fp``; for ``fit`` it must
    also record its outputs' hashes (a marker of an earlier version does not: the job is redone
    rather than its outputs pooled unchecked)."""
    m = marker_path(outdir, job)
    if not m.is_file():
        return False
    try:
        doc = read_json(m, "done marker", max_bytes=MAX_MARKER_BYTES)
    except InputError:
        return False
    if not isinstance(doc, dict) or doc.get("fingerprint") != fp:
        return False
    return job != "fit" or isinstance(_recorded_hashes(doc), dict)


def output_hashes(folder, names=HASHED_OUTPUTS):
    """``{name: SHA-256}`` of the outputs ``names`` present in ``folder`` (what a done marker
    records)."""
    return {n: sha256_file(Path(folder) / n) for n in names if (Path(folder) / n).is_file()}


def _recorded_hashes(doc):
    """The marker's ``outputs`` as ``{name: hex digest}``, or None when it holds none of that form."""
    out = doc.get("outputs")
    if not isinstance(out, dict) or "result.json" not in out or \
            not all(isinstance(k, str) and isinstance(v, str) and len(v) == 64 for k, v in out.items()):
        return None
    return out


def run_fit_job(track, round_path, outdir, options, covariance="colored", marker=None, resume=False):
    """The ``fit`` job of one round: :func:`bayesdrag.commands.fit.run_fit` into ``outdir`` plus
    ``pooling.json`` (:func:`bayesdrag.campaign.pooling.pooling_input`, Scheme 1 only) and the
    done marker (``marker(message)`` gives its content), committed with the fit's outputs. A
    round killed while sampling left its chain: with ``resume`` it is continued (the chain is
    checked to belong to the same inputs, problem, walkers, moves and seed, and its stored
    log posterior recomputed at sampled positions), without it the round fails saying so: a
    chain file is only read when the user asks. Returns a message."""
    from ..campaign.pooling import pooling_input
    from .fit import run_fit

    def also(result, folder):
        if result.scheme1 is not None:
            write_json(Path(folder) / POOLING, pooling_input(result.ml, result.scheme1.drag_model,
                                                             result.round.reference_drag, covariance=covariance,
                                                             name=Path(outdir).name))
        if marker is not None:
            # the hashes of the files as staged, committed with them: an edit afterwards shows
            write_json(Path(folder) / "done.fit.json", marker(result.message, output_hashes(folder)))

    partial = Path(outdir) / "chain.partial.h5"
    if partial.exists() and not resume and options.mcmc and options.scheme == 1:
        raise InputError(f"{partial}: an unfinished chain of an earlier run is there; continue it with --resume "
                         f"(after checking no one else could write {Path(outdir).parent}) or delete the file to "
                         f"start afresh")
    result = run_fit(track, round_path, outdir, options, resume=resume and partial.exists(), quiet=True,
                     echo=lambda *a: None, also=also)
    return result.message


def run_diagnose_job(track, round_path, outdir, marker=None):
    """The ``diagnose`` job of one round (as ``bayesdrag diagnose``), its done marker committed
    with its outputs. Returns the verdict text."""
    from .diagnose import run_diagnose

    def also(result, folder):
        if marker is not None:
            write_json(Path(folder) / "done.diagnose.json", marker(f"verdict {result.verdict or 'none'}"))

    d = run_diagnose(track, round_path, outdir, quiet=True, echo=lambda *a: None, also=also)
    return f"verdict {d.verdict or 'none'}"


def _referenced_files(round_path):
    """The files a round file names (``[projectile] reference_drag``, ``[atmosphere] profile`` and
    ``metcm_zones``),
    resolved as :func:`bayesdrag.io.rounds.read_round` resolves them, from its TOML alone: nothing
    they hold is read."""
    doc = read_toml(round_path, "round file", "a round file holds [projectile], [launch], ...")
    out = {}
    for section, key in (("projectile", "reference_drag"), ("atmosphere", "profile"), ("atmosphere", "metcm_zones")):
        table = doc.get(section)
        value = table.get(key) if isinstance(table, dict) else None
        if isinstance(value, str) and value.strip():
            out[f"[{section}] {key}"] = Path(os.path.normpath(Path(round_path).parent / value))
    return out


def check_confined(round_path, root):
    """Refuse (:class:`~bayesdrag.errors.InputError`) a file the round file names that is outside
    the campaign's folder ``root`` (resolved, links followed), before anything in it is read."""
    for key, p in _referenced_files(round_path).items():
        if not Path(os.path.realpath(p)).is_relative_to(root):
            raise InputError(f"{round_path}: {key} names a file outside the campaign's folder {root}; a campaign "
                             f"reads only files in its own folder: move the file there, or pass "
                             f"--allow-outside-inputs")


def _round_folder(outdir):
    """``outdir`` made when missing; refused when something else is there (a link planted while
    the batch ran: round folders are made by bayesdrag only)."""
    p = Path(outdir)
    if not os.path.lexists(p):
        p.mkdir()
    st = os.lstat(p)
    if not stat.S_ISDIR(st.st_mode) or st.st_uid != os.getuid():
        kind = "a symbolic link" if stat.S_ISLNK(st.st_mode) else "not a folder of this user"
        raise InputError(f"{p}: the round's folder is {kind}; bayesdrag makes round folders itself: remove it")
    return p


def round_task(name, track, round_path, outdir, jobs=("fit",), options=None, covariance="colored", resume=False,
               inputs_root=None):
    """Run the jobs of one round; never raises (a failure is returned).

    Parameters
    ----------
    name : str
    track, round_path : str
        Input files.
    outdir : str
        ``DIR/<name>``; created.
    jobs : sequence of {"fit", "diagnose"}
    options : FitOptions
    covariance : {"colored", "crb"}
        Stage-1 covariance kept for pooling.
    resume : bool
        Continue an unfinished chain in ``outdir`` (else its round fails, saying so).
    inputs_root : path, optional
        The campaign's folder: the files the round file names must be inside it (None: any).

    The track is read once without quoting it in a message before the first job that runs: it is
    a file the campaign points to, so an error never repeats its content (it goes into
    ``campaign.json``).

    Returns
    -------
    dict
        ``name``, ``jobs``: {job: {"status": "done" | "skipped" | "failed", "seconds", "message"}}
        (done jobs also ``cpu_seconds``: CPU time of the worker process, to tell contention apart),
        ``pid`` (the worker process).
    """
    options = options if options is not None else FitOptions()
    report = {"name": name, "jobs": {}, "pid": os.getpid()}
    try:
        out = _round_folder(outdir)
        if inputs_root is not None:
            check_confined(round_path, Path(inputs_root))
    except Exception as exc:  # noqa: BLE001 - reported, the batch goes on
        for job in jobs:
            report["jobs"][job] = {"status": "failed", "seconds": 0.0, "message": f"{type(exc).__name__}: {exc}"}
        return report
    checked = False
    for job in jobs:
        t0, c0 = time.perf_counter(), time.process_time()
        try:
            fp = fingerprint(track, round_path, job, options)
            if job_done(out, job, fp):
                report["jobs"][job] = {"status": "skipped", "seconds": 0.0, "message": "done in an earlier run"}
                continue
            if not checked:          # once, and only for a job that runs: a skipped round reads nothing
                read_track(track, quote=False)
                checked = True
            def marker(msg, outputs=None, fp=fp, t0=t0):
                doc = {"fingerprint": fp, "seconds": round(time.perf_counter() - t0, 3), "message": msg}
                if outputs is not None:
                    doc["outputs"] = dict(outputs)
                return doc

            if job == "fit":
                msg = run_fit_job(track, round_path, out, options, covariance, marker, resume)
            elif job == "diagnose":
                msg = run_diagnose_job(track, round_path, out, marker)
            else:
                raise InputError(f"unknown job {job!r}; allowed: {', '.join(JOBS)}")
            secs = time.perf_counter() - t0
            report["jobs"][job] = {"status": "done", "seconds": secs, "message": msg,
                                   "cpu_seconds": time.process_time() - c0}
        except BaseException as exc:  # noqa: BLE001 - reported, the batch goes on
            if isinstance(exc, (KeyboardInterrupt, SystemExit)):
                raise
            report["jobs"][job] = {"status": "failed", "seconds": time.perf_counter() - t0,
                                   "message": f"{type(exc).__name__}: {' '.join(str(exc).split())}"}
    return report


# ----------------------------------------------------------------------------------------------
# executors
class _Sequential:
    """In-process executor with the interface used below (for ``bayesdrag fit CAMPAIGN``)."""

    def run(self, calls, progress):
        for kw in calls:
            yield round_task(**kw)


@contextlib.contextmanager
def _environment(**values):
    """``os.environ`` with ``values`` set inside the block (child processes started there inherit
    them), as it was after."""
    old = {k: os.environ.get(k) for k in values}
    os.environ.update(values)
    try:
        yield
    finally:
        for k, v in old.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v


class _Dask:
    """Dask executor: a LocalCluster (default) or a Client to ``scheduler``."""

    def __init__(self, scheduler=None, workers=2):
        self.scheduler, self.workers = scheduler, workers

    def run(self, calls, progress):
        import logging

        from distributed import Client, LocalCluster, as_completed

        from .._runtime.numba_setup import ensure

        cluster = None
        # distributed logs every closed connection at INFO, also while the cluster shuts down
        # after we return; keep stderr for the progress bar and our one-line reports
        for name in ("distributed", "distributed.core", "distributed.worker", "distributed.nanny"):
            logging.getLogger(name).setLevel(logging.ERROR)
        ensure()       # numba's settings in the environment the local workers inherit
        if self.scheduler:
            try:
                client = Client(self.scheduler, timeout="20s")
            except (OSError, TimeoutError, ValueError, TypeError) as exc:
                raise InputError(f"Dask scheduler {self.scheduler}: cannot connect "
                                 f"({' '.join(str(exc).split()) or type(exc).__name__})") from None
        else:
            # the worker processes configure distributed's logging when they import it, before the
            # cluster's env= applies: their INFO lines ("Connection ... has been closed") are
            # silenced by the environment they are spawned with
            # no dashboard; the scheduler's own HTTP server (health routes) on a free port: on its
            # default port a second batch running at the same time warns on stderr that it is taken
            with _environment(DASK_LOGGING__DISTRIBUTED="error"):
                cluster = LocalCluster(n_workers=self.workers, threads_per_worker=1, processes=True,
                                       dashboard_address=None, scheduler_kwargs={"dashboard_address": ":0"},
                                       env=dict(WORKER_ENV), silence_logs=logging.CRITICAL)
            client = Client(cluster)
        try:
            futures = [client.submit(round_task, **kw, key=f"round-{kw['name']}", pure=False) for kw in calls]
            for fut in as_completed(futures):
                try:
                    yield fut.result()
                except Exception as exc:  # noqa: BLE001 - a worker died: report the round, go on
                    name = fut.key.split("round-", 1)[-1] if isinstance(fut.key, str) else str(fut.key)
                    yield {"name": name, "jobs": {"?": {"status": "failed", "seconds": 0.0,
                                                       "message": f"{type(exc).__name__}: {exc}"}}}
        finally:
            # workers first, then the scheduler: no heartbeat errors from orphaned workers
            if cluster is not None:
                client.retire_workers(close_workers=True)
                cluster.close()
            client.close()


def run_campaign(campaign_path, output, jobs=("fit",), options=None, executor="dask", scheduler=None,
                 workers=2, covariance="colored", quiet=False, echo=print, pool_seed=0, resume=False,
                 allow_outside=False):
    """Run every round of a campaign, then pool the fitted rounds.

    Parameters
    ----------
    campaign_path : path
        Campaign TOML (:func:`bayesdrag.io.campaign.read_campaign`).
    output : path
        ``DIR``: rounds go to ``DIR/<name>/``, the campaign to ``DIR/campaign.json``,
        ``campaign.html`` and figures.
    jobs : sequence of {"fit", "diagnose"}
    options : FitOptions
    executor : {"dask", "sequential"}
    scheduler : str, optional
        Address of a running Dask scheduler (``tcp://host:8786``); default a LocalCluster.
    workers : int
        LocalCluster worker processes.
    covariance : {"colored", "crb"}
    quiet : bool
        No progress bar.
    echo : callable
        Status lines (stdout).
    pool_seed : int
        Seed of the pooling sampler (reproducible campaign outputs).
    resume : bool
        Continue the unfinished chains of rounds killed while sampling (``--resume``); without
        it a round with one fails, saying so.
    allow_outside : bool
        Read tracks, round files and the tables they name outside the campaign file's folder
        (``--allow-outside-inputs``); by default they must be inside it.

    Returns
    -------
    dict
        ``reports`` (per round), ``failed`` (list of {name, job, message}), ``campaign``
        (campaign.json document or None), ``seconds``.
    """
    from ..io.campaign import read_campaign

    bad = [j for j in jobs if j not in JOBS]
    if bad or not jobs:
        raise InputError(f"jobs {','.join(jobs)!r} are not allowed; use a non-empty subset of {', '.join(JOBS)}")
    camp = read_campaign(campaign_path, allow_outside=allow_outside)
    files = {"campaign": campaign_path}
    for r in camp.rounds:
        files.update({f"{r.name}/track": r.track, f"{r.name}/round": r.round})
    root = None if allow_outside else camp.path.parent
    if root is not None:
        for r in camp.rounds:
            check_confined(r.round, root)
    with OutputRun(output, "campaign", inputs=files, options=(options or FitOptions()).to_dict(),
                   echo=lambda m: print(m, file=sys.stderr)) as run:
        for r in camp.rounds:
            run.subfolder(r.name, f"the folder of round {r.name}")
        res = _run_rounds(camp, run, jobs, options, executor, scheduler, workers, covariance, quiet, echo,
                          pool_seed, resume, root)
    return res


def _run_rounds(camp, run, jobs, options, executor, scheduler, workers, covariance, quiet, echo, pool_seed,
                resume=False, root=None):
    """The rounds of a campaign into ``run.folder/<name>/`` and the pooled campaign into the
    run's staging folder."""
    from tqdm import tqdm

    out = run.folder
    options = options if options is not None else FitOptions()
    calls = [dict(name=r.name, track=str(r.track), round_path=str(r.round), outdir=str(out / r.name),
                  jobs=tuple(jobs), options=options, covariance=covariance, resume=resume,
                  inputs_root=None if root is None else str(root)) for r in camp.rounds]
    ex = _Sequential() if executor == "sequential" else _Dask(scheduler, workers)
    t0 = time.perf_counter()
    reports = []
    bar = tqdm(total=len(calls), desc="rounds", unit="round", file=sys.stderr, disable=quiet, leave=True)
    for rep in ex.run(calls, bar):
        reports.append(rep)
        status = ", ".join(f"{j} {v['status']}" for j, v in rep["jobs"].items())
        bar.set_postfix_str(f"{rep['name']}: {status}", refresh=False)
        bar.update(1)
    bar.close()
    failed = [{"name": r["name"], "job": j, "message": v["message"]}
              for r in reports for j, v in r["jobs"].items() if v["status"] == "failed"]
    order = {n: i for i, n in enumerate(camp.names)}
    reports.sort(key=lambda r: order.get(r["name"], len(order)))
    doc = None
    if "fit" in jobs:
        left_out = []
        doc = pool_campaign(camp, out, failed, seed=pool_seed, echo=echo, into=run.staging, left_out=left_out)
        # with the rounds left out of the pooling, also when none was left to pool
        failed = failed + left_out
    return {"reports": reports, "failed": failed, "campaign": doc, "seconds": time.perf_counter() - t0}


def pool_campaign(camp, out, failed=(), seed=0, echo=print, into=None, left_out=None):
    """Pool the rounds of ``camp`` whose ``pooling.json`` exists in ``out`` and write
    ``campaign.json``, ``campaign.html`` and the figures into ``into`` (default ``out``).
    Returns the document or None when no round was fitted. A round whose ``pooling.json`` is not
    a pooling input of this version, of this round, the file its fit wrote (with
    ``result.json``: the hashes in ``done.fit.json``) and in agreement with its ``result.json``
    is left out and reported in ``failed`` (:func:`_pooling_doc`), and appended to the list
    ``left_out`` when one is given (the document's ``failed`` is lost when no round is left). A
    round whose fit is among ``failed`` (it failed in this run) is not pooled at all."""
    import numpy as np

    from ..campaign.pooling import campaign_json, pool_rounds
    from ..report.campaign import write_campaign_report

    inputs, failed = [], list(failed)
    # a round whose fit failed in this run is not pooled from an earlier fit of other inputs
    failed_now = {f["name"] for f in failed if f.get("job") in ("fit", "?")}
    for r in camp.rounds:
        p = Path(out) / r.name / POOLING
        if r.name in failed_now:
            continue
        if p.is_file() and marker_path(Path(out) / r.name, "fit").is_file():
            try:
                inputs.append(_pooling_doc(p, r.name))
            except InputError as exc:   # reported with the failed rounds (say_done)
                entry = {"name": r.name, "job": "pool", "message": f"left out of the pooling: {exc}"}
                failed.append(entry)
                if left_out is not None:
                    left_out.append(entry)
    if not inputs:
        echo("campaign: no fitted round to pool")
        return None
    pooled = pool_rounds(inputs, rng=np.random.default_rng(seed))
    doc = campaign_json(pooled, inputs, camp.name, failed)
    write_campaign_report(into if into is not None else out, camp, inputs, pooled, doc)
    s = doc["scatter"]
    scatter = (f"round-to-round scatter of Cd {100 * s['median']:.2f} % (90 % interval {100 * s['q05']:.2f}-"
               f"{100 * s['q95']:.2f} %)" if s.get("median") is not None else s.get("note", "no scatter"))
    echo(f"campaign: pooled {len(inputs)} of {len(camp.rounds)} rounds; {scatter}; "
         f"wrote {Path(out) / 'campaign.json'}, campaign.html")
    return doc


def _pooling_doc(path, name=None):
    """A round's ``pooling.json`` (bounded JSON, never evaluated), checked in turn: a pooling
    input of this version (:func:`bayesdrag.campaign.pooling.check_input`), of round ``name``,
    with ``result.json`` the files the round's fit wrote (the SHA-256 its ``done.fit.json``
    records), and agreeing with ``result.json``
    (:func:`bayesdrag.campaign.pooling.check_against_result`).

    Raises
    ------
    InputError
        One line naming the file and what is wrong, and how to redo the round.
    """
    from ..campaign.pooling import check_against_result, check_input

    path = Path(path)
    folder = path.parent
    marker = marker_path(folder, "fit")
    redo = f"delete {marker} to refit the round"
    doc = read_json(path, "pooling input", max_bytes=16 << 20)
    try:
        check_input(doc)
    except ValueError as exc:
        raise InputError(f"{path}: not a pooling input of this version ({exc}); {redo}") from None
    if name is not None and doc["name"] != name:
        raise InputError(f"{path}: the pooling input of round {doc['name'][:64]!r}, not of round {name!r} (copied "
                         f"from another round's folder?); {redo}")
    mark = read_json(marker, "done marker", max_bytes=MAX_MARKER_BYTES)
    recorded = _recorded_hashes(mark) if isinstance(mark, dict) else None
    if recorded is None:
        raise InputError(f"{marker}: records no hashes of the fit's outputs (an earlier version, or edited); {redo}")
    for output in HASHED_OUTPUTS:
        f = folder / output
        if not f.is_file() or f.is_symlink():
            raise InputError(f"{f}: missing or not a regular file, though the round's fit wrote it; {redo}")
        if recorded.get(output) != sha256_file(f):
            raise InputError(f"{f}: not the file the round's fit wrote (its SHA-256 differs from the one {marker.name} "
                             f"records): the round's folder was edited after the fit; {redo}")
    result = read_json(folder / "result.json", "result")
    try:
        check_against_result(doc, result)
    except ValueError as exc:
        raise InputError(f"{path}: disagrees with {folder / 'result.json'} ({exc}); {redo}") from None
    return doc


def say_done(res, echo=print):
    """Say what a campaign did: rounds, jobs run, skipped and failed (``echo``), each failure on stderr."""
    done = sum(1 for r in res["reports"] for v in r["jobs"].values() if v["status"] == "done")
    skipped = sum(1 for r in res["reports"] for v in r["jobs"].values() if v["status"] == "skipped")
    echo(f"batch: {len(res['reports'])} rounds, {done} jobs run, {skipped} skipped (done earlier), "
         f"{len(res['failed'])} failed, {res['seconds']:.1f} s")
    for f in res["failed"]:
        print(f"bayesdrag: round {f['name']} ({f['job']}) failed: {f['message']}", file=sys.stderr)
    return 1 if res["failed"] else 0

#: old names, kept with a warning until release 0.3
__getattr__ = renamed_getattr(__name__, {"summarise": "say_done"}, globals())
