"""Running a study: executors (serial, a local process pool, Dask distributed), the store, progress.

Workers only compute: each trial returns its row to the coordinating process, which writes it to the
store the moment it arrives. Trials carry their own seeds (:mod:`optcal.studies.trial`), so the executor, the
number of workers and the order of completion change nothing but the wall time.

Trials go to workers in chunks of consecutive trials (the solvers of one Monte-Carlo run share its
data, bounds and verification set, built once per chunk): a trial takes tens of milliseconds, and one
scheduling round trip per trial would cost a noticeable share of that. Each worker starts once, imports
the solvers and loads the compiled kernel (compiled beforehand by the coordinator, so that workers never
compile side by side), and then runs chunk after chunk. The trials of the last runs go one by one, the
longest expected first (:func:`schedule`), so that the workers finish together instead of one waiting
for another's last chunk.
"""

from __future__ import annotations

import json
import os
import sys
import time
from collections.abc import Iterator
from concurrent.futures import ProcessPoolExecutor, as_completed
from concurrent.futures.process import BrokenProcessPool
from contextlib import contextmanager
from dataclasses import asdict, dataclass
from pathlib import Path

from optcal.core.errors import InputError
from optcal.studies.spec import EXECUTORS, Spec
from optcal.studies.store import Store
from optcal.studies.trial import Trial, run_chunk, run_trial, trials

# One BLAS thread per worker: the workers already use every core, and oversubscribed BLAS pools
# only make them fight (dask's nanny sets the same variables for its workers).
_SINGLE_THREAD = {k: "1" for k in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")}


@contextmanager
def _env(values: dict):
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


@dataclass(frozen=True)
class Lost:
    """A trial whose worker died under it (crash, out of memory, a lost Dask worker). Not a result: it is
    not stored, so running the study again retries it."""

    trial_id: str
    message: str


# A chunk holds at most this many trials (about a Monte-Carlo run's worth of solvers), and each worker
# gets at least CHUNKS_PER_WORKER chunks, so that the last ones still balance the load.
MAX_CHUNK = 40
CHUNKS_PER_WORKER = 8


def chunks(tasks: list[Trial], workers: int) -> list[list[Trial]]:
    """Consecutive trials in chunks (see the module docstring)."""
    size = max(1, min(MAX_CHUNK, len(tasks) // (workers * CHUNKS_PER_WORKER)))
    return [tasks[i:i + size] for i in range(0, len(tasks), size)]


# Seconds of a solver's own work per evaluation of its budget, by registry name (docs/performance.md, "CMA-ES
# and nevergrad: their own Python"): nevergrad's optimisers 0.7-2 ms a candidate, and they use their whole
# budget; pycma's CMA-ES 0.1-0.3 ms, but it stops by itself after about 4,000 of 20,000 evaluations (staged:cmaes
# after about 15,000); every other solver a few microseconds (the evaluation, 0.4 µs in a batch, and the
# solver's arithmetic). Only the order of the work depends on these, never a result.
PER_EVALUATION_S = {"ng:": 1e-3, "cmaes": 5e-5}
OTHER_PER_EVALUATION_S = 3e-6
DEFAULT_EVALUATIONS = 20_000  # a configuration without max_evals runs its solver's default, of this order
TAIL_RUNS = 2  # the last runs (model × scheme × run) whose trials go one by one, longest first


def expected_seconds(t: Trial) -> float:
    """A trial's expected solver time from its configuration: its evaluation budget times its solver's
    time per evaluation (:data:`PER_EVALUATION_S`; staged:X as X). A turntable fit is a least-squares fit."""
    cfg = t.config
    if cfg.reference:
        return 0.0
    name = cfg.name.removeprefix("staged:")
    per = next((v for k, v in PER_EVALUATION_S.items() if name.startswith(k)), OTHER_PER_EVALUATION_S)
    return float(cfg.budget.get("max_evals") or DEFAULT_EVALUATIONS) * per


def schedule(tasks: list[Trial], workers: int) -> list[list[Trial]]:
    """The chunks the workers get, in this order: the trials before the last :data:`TAIL_RUNS` runs in
    chunks of consecutive trials (:func:`chunks`), then the last runs' trials one per chunk, longest
    expected first (:func:`expected_seconds`; longest processing time first, Graham 1969), so that no
    worker waits at the end for another's chunk of CMA-ES and nevergrad trials. Trials carry their own
    seeds: the order changes no result."""
    if workers < 2 or len(tasks) < 2:
        return chunks(tasks, workers)
    runs: list[tuple] = []
    start = len(tasks)
    while start > 0:
        run = (tasks[start - 1].model, tasks[start - 1].scheme, tasks[start - 1].run)
        if run not in runs:
            if len(runs) == TAIL_RUNS:
                break
            runs.append(run)
        start -= 1
    tail = sorted(range(start, len(tasks)), key=lambda i: (-expected_seconds(tasks[i]), i))
    return chunks(tasks[:start], workers) + [[tasks[i]] for i in tail]


def worker_start() -> None:
    """Run once in each worker process: import the solvers and load the compiled kernel."""
    from optcal import solvers  # noqa: F401 - the registry, loaded once per worker
    from optcal.core.warmup import warm

    warm()


def _serial(tasks: list[Trial], workers: int, scheduler: str, tag: str) -> Iterator[dict | Lost]:
    for t in tasks:
        yield run_trial(t)


def _processes(tasks: list[Trial], workers: int, scheduler: str, tag: str) -> Iterator[dict | Lost]:
    import multiprocessing as mp

    # spawn: workers start clean (no inherited threads or locks from the coordinator). The workers start
    # at the first submit and read the environment then, so the single-thread settings stay in place
    # until every task is submitted.
    with _env(_SINGLE_THREAD):
        pool = ProcessPoolExecutor(max_workers=workers, mp_context=mp.get_context("spawn"),
                                   initializer=worker_start)
        try:
            futures = {pool.submit(run_chunk, c): c for c in schedule(tasks, workers)}
        except BaseException:
            pool.shutdown(wait=False, cancel_futures=True)
            raise
    try:
        for f in as_completed(futures):
            try:
                rows = f.result()
            except BrokenProcessPool as exc:  # run_trial never raises: its process died
                rows = [Lost(t.id, f"its worker process died ({exc})") for t in futures[f]]
            yield from rows
    finally:
        pool.shutdown(wait=True, cancel_futures=True)


def _dask(tasks: list[Trial], workers: int, scheduler: str, tag: str) -> Iterator[dict | Lost]:
    try:
        from dask.distributed import Client, LocalCluster
        from dask.distributed import as_completed as dask_completed
    except ImportError:  # pragma: no cover - a runtime dependency
        raise InputError("executor dask needs dask[distributed]; install it with pip") from None
    cluster = None
    if scheduler:
        try:
            client = Client(scheduler, timeout="30s")
        except OSError as exc:
            raise InputError(f"cannot reach the Dask scheduler at {scheduler} ({exc})") from None
    else:
        cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=None)
        client = Client(cluster)
    try:
        client.run(worker_start)  # the workers there now; one that joins later loads on its first chunk
        # Keys carry the spec's hash: on a shared scheduler two studies' trials never share a key (Dask
        # would hand one the other's result).
        futures = {client.submit(run_chunk, c, key=f"optcal-{tag}-{i}-{c[0].id}", pure=False): c
                   for i, c in enumerate(schedule(tasks, max(workers, len(client.scheduler_info()["workers"]))))}
        for f in dask_completed(list(futures)):
            try:
                rows = f.result()
            except Exception as exc:  # noqa: BLE001 - run_trial never raises: its worker was lost
                rows = [Lost(t.id, f"its Dask worker was lost ({type(exc).__name__}: {exc})") for t in futures[f]]
            yield from rows
            f.release()
    finally:
        client.close()
        if cluster is not None:
            cluster.close()


EXECUTOR_FUNCS = {"serial": _serial, "processes": _processes, "dask": _dask}


@dataclass
class RunSummary:
    folder: str
    spec_hash: str
    total: int
    skipped: int
    ran: int
    failed: int
    wall_s: float
    executor: str
    workers: int
    lost: int = 0  # trials whose worker died: not stored, retried when the study is run again


class LiveReport:
    """``report.md`` while a study runs (:func:`optcal.studies.report.write_progress`): the headline tables of the
    trials finished so far, written once a Monte-Carlo run's worth of trials has finished (as many as the
    spec has solvers × models × schemes: the trials go out run by run) and then every :attr:`EVERY_S`
    seconds, so that a user sees results in the study's first minutes. The coordinator keeps of each row
    only the columns the headline reads."""

    EVERY_S = 60.0

    def __init__(self, folder: Path, spec: dict, stored: list[dict], expected: int, first: int):
        from optcal.studies.report import HEADLINE_COLUMNS

        self.folder, self.spec, self.expected, self.first = folder, spec, expected, first
        self.columns = HEADLINE_COLUMNS
        self.rows = [self._slim(r) for r in stored]
        self.t0 = time.perf_counter()
        self.last: float | None = None
        self.written = 0

    def _slim(self, row: dict) -> dict:
        return {k: row.get(k) for k in self.columns}

    def add(self, row: dict) -> None:
        self.rows.append(self._slim(row))
        now = time.perf_counter()
        if (self.last is None and len(self.rows) >= self.first) or (
                self.last is not None and now - self.last >= self.EVERY_S):
            self.write(now)

    def write(self, now: float) -> None:
        from optcal.studies.report import write_progress

        write_progress(self.folder, self.spec, self.rows, self.expected, now - self.t0)
        self.last, self.written = time.perf_counter(), self.written + 1


class ProgressLines:
    """Progress as plain lines, for output that is not a terminal (a CI log, a file): trials done, the rate
    and the time left, every :attr:`EVERY_S` seconds, every :attr:`EVERY_SHARE` of the trials (but not more
    often than every :attr:`MIN_S` seconds) and at the end, so that a
    log shows the study moving where a progress bar would print nothing (tqdm disables itself there)."""

    EVERY_S = 30.0
    EVERY_SHARE = 0.1
    MIN_S = 2.0  # at most one share line in this many seconds (a quick study would print every share at once)

    def __init__(self, total: int, name: str, file=None):
        self.total, self.name, self.file = total, name, file or sys.stderr
        self.n = self.failed = self.lost = 0
        self.t0 = self.last_t = time.perf_counter()
        self.last_n = 0

    def update(self, k: int = 1) -> None:
        self.n += k
        now = time.perf_counter()
        share = self.n - self.last_n >= max(1, self.EVERY_SHARE * self.total) and now - self.last_t >= self.MIN_S
        if now - self.last_t >= self.EVERY_S or share or self.n == self.total:
            self.line(now)

    def line(self, now: float) -> None:
        dt = now - self.t0
        rate = self.n / dt if dt > 0 else float("nan")
        left = (self.total - self.n) / rate if rate > 0 else float("nan")
        eta = f"{left / 60:.1f} min" if left >= 60 else f"{left:.0f} s"
        extra = (f", {self.failed} failed" if self.failed else "") + (f", {self.lost} lost" if self.lost else "")
        print(f"study {self.name}: {self.n}/{self.total} trials ({100 * self.n / max(self.total, 1):.0f} %), "
              f"{rate:.1f} trials/s, {dt:.0f} s elapsed, about {eta} left{extra}", file=self.file, flush=True)
        self.last_t, self.last_n = now, self.n

    def set_postfix(self, failed: int = 0, lost: int = 0, refresh: bool = False) -> None:
        self.failed, self.lost = failed, lost

    def close(self) -> None:
        pass


def _progress(total: int, enabled: bool | None, name: str = "", stream=None):
    """A tqdm bar on a terminal; progress lines (:class:`ProgressLines`) when ``enabled`` is None and the
    output is not a terminal; nothing when ``enabled`` is False."""
    from tqdm import tqdm

    stream = stream or sys.stderr
    if enabled is None and total and not (hasattr(stream, "isatty") and stream.isatty()):
        return ProgressLines(total, name, stream)
    return tqdm(total=total, unit="trial", file=stream, disable=None if enabled is None else not enabled,
                dynamic_ncols=True, smoothing=0.05)


@contextmanager
def _writer_lock(folder: Path):
    """One writer per study folder: a second `optcal study run` into it is refused, not interleaved."""
    try:
        import fcntl
    except ImportError:  # pragma: no cover - not POSIX: no lock
        yield
        return
    fh = open(folder / ".lock", "w")
    try:
        try:
            fcntl.flock(fh, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            raise InputError(f"another `optcal study run` is writing to {folder}; wait for it, or use another "
                             "`out` folder") from None
        yield
    finally:
        fh.close()


def code_version() -> str:
    """The git commit of the code that runs the trials (with '+dirty' for local changes), if known."""
    import subprocess

    root = Path(__file__).resolve().parents[2]  # the repository holding the optcal package
    try:
        head = subprocess.run(["git", "-C", str(root), "rev-parse", "--short", "HEAD"], capture_output=True,
                              text=True, timeout=10).stdout.strip()
        dirty = subprocess.run(["git", "-C", str(root), "status", "--porcelain", "--", "optcal"],
                               capture_output=True, text=True, timeout=10).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        return ""
    return head + ("+dirty" if head and dirty else "")


def spec_json(spec: Spec) -> str:
    return json.dumps({**spec.canonical(), "description": spec.description}, sort_keys=True)


def run_study(spec: Spec, folder: str | Path, *, executor: str | None = None, workers: int | None = None,
              scheduler: str | None = None, progress: bool | None = None, limit: int | None = None,
              live_report: bool = False) -> RunSummary:
    """Run every trial of ``spec`` not yet in ``folder``'s store; return a summary of this session.

    ``progress=None`` shows the bar on a terminal and progress lines otherwise (a CI log). ``limit`` runs at
    most that many pending trials (for tests and partial runs). ``live_report``: keep ``report.md`` showing
    the headline tables of the trials finished so far while the study runs (:class:`LiveReport`; the caller
    writes the full report at the end).
    """
    ex = executor or spec.executor["kind"]
    if ex not in EXECUTORS:
        raise InputError(f"unknown executor {ex!r}; use one of {', '.join(EXECUTORS)}")
    nw = int(spec.executor["workers"] if workers is None else workers)
    if nw < 1:
        raise InputError(f"`workers` must be at least 1, got {nw}")
    sched = scheduler if scheduler is not None else spec.executor.get("scheduler", "")
    if sched and ex != "dask":
        raise InputError("`scheduler` is for the dask `executor`")
    all_trials = trials(spec)
    code = code_version()  # the code that runs the trials (later commits do not relabel this session)
    t0 = time.perf_counter()
    with Store(folder, spec.hash, spec_json(spec)) as store, _writer_lock(Path(folder)):
        done = store.finished()
        pending = [t for t in all_trials if t.id not in done]
        if limit is not None:
            pending = pending[:limit]
        ran = failed = 0
        busy = 0.0  # the trials' own wall time: the workers' useful share of the session
        lost: list[Lost] = []
        live = None
        if live_report and pending:
            per_run = len(spec.solvers) * len(spec.models) * len(spec.schemes)
            live = LiveReport(Path(folder), store.spec, store.rows() if done else [], len(all_trials),
                              len(done) + min(per_run, len(pending)))
        bar = _progress(len(pending), progress, spec.name)
        try:
            if pending and ex != "serial":
                # Compile (or load) the kernel here once, so that the workers load it from the cache.
                from optcal.core.warmup import warm

                warm()
            if pending:
                for row in EXECUTOR_FUNCS[ex](pending, nw, sched, spec.hash):
                    bar.update(1)
                    if isinstance(row, Lost):
                        lost.append(row)
                        bar.set_postfix(failed=failed, lost=len(lost), refresh=False)
                        continue
                    store.write(row)
                    if live is not None:
                        live.add(row)
                    busy += row.get("wall_s") or 0.0
                    ran += 1
                    failed += row["status"] == "failed"
                    if failed:
                        bar.set_postfix(failed=failed, lost=len(lost), refresh=False)
        finally:
            bar.close()
            wall = time.perf_counter() - t0
            store.add_session({"executor": ex, "workers": nw if ex != "serial" else 1, "trials": ran,
                               "wall_s": wall, "trials_wall_s": busy, "ended": time.strftime("%Y-%m-%d %H:%M:%S"),
                               "code": code, "cpus": os.cpu_count()})
        store.export()
        if lost:
            print(f"study {spec.name}: {len(lost)} trial(s) lost with their worker and not stored (first: "
                  f"{lost[0].trial_id}: {lost[0].message}); run the study again to retry them", file=sys.stderr)
        return RunSummary(str(folder), spec.hash, len(all_trials), len(done), ran, failed, wall, ex,
                          nw if ex != "serial" else 1, len(lost))


def summary_json(s: RunSummary) -> str:
    return json.dumps(asdict(s))
