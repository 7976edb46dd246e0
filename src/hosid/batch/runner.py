"""Running a batch on dask.distributed, resumably, losing nothing.

:func:`run_batch` holds the lock of the output folder (a second batch on it stops at
once), skips the tasks whose rows are already there (same record and settings: the
task id, :mod:`hosid.batch.tasks`), reads each record as it reaches it, and sends the
others to the workers, at most two per worker thread at a time.  As each task ends its
row (and posterior, and record, when asked) is written atomically under the folder
(:mod:`hosid.batch.table`): a batch stopped at any point loses only the tasks that were
running, and the same command finishes the rest.

The workers are a ``LocalCluster`` (``workers`` processes, one thread each, with OpenMP,
BLAS and numba pinned to one thread) or an existing cluster (``scheduler``, started with
``dask scheduler`` and ``dask worker``; the workers need hosid installed and a design's
simulator files at the same paths: this process reads the records and writes the
folder).  A worker that dies has its
task retried on another one by the scheduler (``distributed.scheduler.allowed-failures``,
3 by default); a task that kills its worker every time gets an error row.
"""

from __future__ import annotations

import json
import logging
import os
import sys
import time
from collections import Counter
from collections.abc import Callable, Iterable, Iterator, Sequence, Sized
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..errors import HosidInputError
from ..output.files import locked_dir, make_dir, write_atomic
from .table import read_rows, stored, write_row, write_table
from .tasks import Task
from .work import Outcome, run_task

__all__ = [
    "THREAD_ENV",
    "BatchResult",
    "dask_client",
    "default_workers",
    "local_cluster",
    "run_batch",
]

#: Environment of the local workers: one thread for every BLAS.  Numba is held to one
#: thread in each task (``numba.set_num_threads``), not here: the nannies run in the
#: calling process and set this environment there while they spawn, and numba refuses to
#: compile once its pool was launched under another NUMBA_NUM_THREADS.
THREAD_ENV = {
    "OMP_NUM_THREADS": "1",
    "OPENBLAS_NUM_THREADS": "1",
    "MKL_NUM_THREADS": "1",
}
#: Seconds between rewrites of the table while the batch runs.
TABLE_EVERY = 60.0


def default_workers() -> int:
    """The cores this process may use."""
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()


@contextmanager
def dask_client(*, workers: int | None = None, scheduler: str | None = None) -> Iterator[Any]:
    """A ``distributed.Client`` of a new ``LocalCluster`` or of the cluster at
    ``scheduler`` (module docstring).

    Raises
    ------
    HosidInputError
        If both are given, ``workers`` is below 1, or the scheduler cannot be reached.
    """
    from distributed import Client

    if scheduler is not None:
        if workers is not None:
            raise HosidInputError("--workers sizes a local cluster; not with --scheduler")
        try:
            client = Client(scheduler, timeout="20s")
        except (OSError, TimeoutError, ValueError) as exc:
            raise HosidInputError(f"cannot reach the dask scheduler {scheduler}: {exc}") from None
        try:
            yield client
        finally:
            client.close()
        return
    cluster = local_cluster(default_workers() if workers is None else workers)
    try:
        with Client(cluster) as client:
            yield client
    finally:
        cluster.close()


def local_cluster(workers: int):
    """A ``distributed.LocalCluster`` of ``workers`` processes with one thread each,
    every numerical library held to one thread (:data:`THREAD_ENV`) and glibc's own
    memory trimming.
    """
    import dask
    from distributed import LocalCluster

    if int(workers) < 1:
        raise HosidInputError(f"--workers must be at least 1, got {workers}")
    env = dict(dask.config.get("distributed.nanny.pre-spawn-environ", {}))
    # dask's MALLOC_TRIM_THRESHOLD_ fixes glibc's mmap threshold: every large temporary
    # array of a fit is then mapped afresh (30 times the page faults, +25 % CPU a fit)
    env.pop("MALLOC_TRIM_THRESHOLD_", None)
    with dask.config.set({"distributed.nanny.pre-spawn-environ": {**env, **THREAD_ENV}}):
        return LocalCluster(
            n_workers=int(workers),
            threads_per_worker=1,
            processes=True,
            dashboard_address=None,  # no dashboard, and its HTTP routes on a free port:
            scheduler_kwargs={"dashboard_address": "127.0.0.1:0"},
            silence_logs=logging.CRITICAL,  # a failed task's story is its row
        )


def _in_worker(task: Task, seed, posterior: bool, keep_record: bool) -> Outcome:
    """:func:`run_task` with numba held to one thread (hand-started workers too)."""
    import numba

    numba.set_num_threads(1)
    return run_task(task, seed, posterior=posterior, keep_record=keep_record)


@dataclass
class BatchResult:
    """What a batch did: the table's rows (input order), the counts of the statuses,
    how many tasks were skipped as done before, and the files of the table.
    """

    out: Path
    rows: list[dict[str, Any]]
    counts: Counter = field(default_factory=Counter)
    skipped: int = 0
    ran: int = 0
    seconds: float = 0.0
    tables: list[Path] = field(default_factory=list)


def _safe(text: str) -> str:
    return "".join(c if c.isalnum() or c in "-_." else "_" for c in text)[:80] or "record"


def _store(out: Path, outcome: Outcome) -> dict[str, Any]:
    """Write a finished task's files; its row last (the row marks the task done)."""
    from ..record import write_record

    row = outcome.row
    stem = _safe(Path(row["record"]).stem if row.get("design") is None else row["record"])
    if outcome.posterior is not None:
        name = f"{stem}-{row['task']}.nc"
        write_atomic(make_dir(out / "posteriors") / name, outcome.posterior)
        row["posterior"] = f"posteriors/{name}"
    if outcome.record is not None:
        folder = make_dir(out / "records")
        tmp = folder / f".{stem}.{row['task']}.tmp.npz"
        write_record(outcome.record, tmp)
        os.replace(tmp, folder / f"{stem}.npz")
        truths = {k[5:]: v for k, v in row.items() if k.startswith("true_") and k != "true_a1eq"}
        write_atomic(folder / f"{stem}.truths.json", json.dumps(truths, indent=2) + "\n")
    write_row(out, row)
    return stored(row)


def _done(row: dict | None, out: Path, *, posterior: bool, records: bool, retry: bool) -> bool:
    if row is None or (retry and row.get("status") == "error"):
        return False
    if posterior and row.get("status") == "ok" and row.get("analysis") != "estimate":
        if not (row.get("posterior") and (out / row["posterior"]).is_file()):
            return False
    if records and row.get("design") is not None and row.get("n") is not None:
        if not (out / "records" / f"{_safe(row['record'])}.npz").is_file():
            return False
    return True


def _failed(task: Task, message: str, task_id: str = "") -> dict[str, Any]:
    return {
        "record": task.label,
        "status": "error",
        "verdict": "",
        "message": message,
        "analysis": task.analysis,
        "task": task_id,
    }


def run_batch(
    tasks: Iterable[Task | None],
    out: str | Path,
    *,
    workers: int | None = None,
    scheduler: str | None = None,
    progress: bool = True,
    save_posterior: bool = False,
    write_records: bool = False,
    retry_errors: bool = False,
    label: str = "hosid batch",
    on_row: Callable[[dict[str, Any]], None] | None = None,
) -> BatchResult:
    """Run ``tasks`` under the folder ``out`` (module docstring).

    Parameters
    ----------
    tasks : iterable of Task or None
        :func:`hosid.batch.record_tasks` or :func:`hosid.batch.design_tasks`; any
        iterable (a generator over a long record is read as it goes, at most two tasks a
        worker thread held at once).  ``None`` is a tick of a source that waits for
        data: the tasks finished meanwhile are collected (``hosid monitor --follow``).
    out : path
        The batch's folder (created if needed, never removed).
    workers : int, optional
        Size of the local cluster; default the number of cores.
    scheduler : str, optional
        Address of an existing dask scheduler instead.
    progress : bool
        One progress bar over the tasks (only when stderr is a terminal).
    save_posterior, write_records : bool
        Also keep each fit's ``posterior.nc`` and each simulated record.
    retry_errors : bool
        Run again the tasks whose stored row has status ``error``.
    label : str
        The progress bar's label and the lock's holder.
    on_row : callable, optional
        Called with each task's row as it finishes (or is found done before).

    Returns
    -------
    BatchResult
    """
    from tqdm.auto import tqdm

    out = Path(out)
    if out.exists() and not out.is_dir():
        raise HosidInputError(f"{out}: exists and is not a directory")
    make_dir(out)  # made here, so that the lock never removes finished rows
    t0 = time.perf_counter()
    result = BatchResult(out, [])
    done_if = {"posterior": save_posterior, "records": write_records, "retry": retry_errors}
    rows: dict[str, dict] = {}
    order: list[str | dict] = []  # task ids, or the rows of records that could not be read
    seen: set[str] = set()
    with locked_dir(out, command=label), _Session(workers, scheduler) as session:
        rows.update(read_rows(out))
        bar = tqdm(
            total=len(tasks) if isinstance(tasks, Sized) else None,
            desc=label,
            unit="task",
            disable=not progress or not sys.stderr.isatty(),
            file=sys.stderr,
        )

        last = [time.monotonic()]

        def finish(outcome: Outcome) -> None:
            if outcome.final:
                rows[outcome.row["task"]] = _store(out, outcome)
            else:
                rows[outcome.row["task"]] = outcome.row
            result.ran += 1
            bar.update()
            if on_row is not None:
                on_row(rows[outcome.row["task"]])
            if time.monotonic() - last[0] > TABLE_EVERY:
                write_table(out, _rows(order, rows))
                last[0] = time.monotonic()

        try:
            for task in tasks:
                if task is None:
                    for outcome in session.ready():
                        finish(outcome)
                    continue
                try:
                    task = task.prepare()
                except HosidInputError as exc:
                    order.append(_failed(task, " ".join(str(exc).split())))
                    bar.update()
                    continue
                if task.id in seen:
                    bar.update()  # the same record twice: one task, one row
                    continue
                seen.add(task.id)
                order.append(task.id)
                if _done(rows.get(task.id), out, **done_if):
                    result.skipped += 1
                    bar.update()
                    if on_row is not None:
                        on_row(rows[task.id])
                    continue
                for outcome in session.submit(task, save_posterior, write_records):
                    finish(outcome)
            for outcome in session.drain():
                finish(outcome)
        finally:
            bar.close()
            result.rows = _rows(order, rows)
            if result.rows:
                result.tables = write_table(out, result.rows)
    result.counts = Counter(r.get("status", "error") for r in result.rows)
    result.seconds = time.perf_counter() - t0
    return result


def _rows(order: Sequence[str | dict], rows: dict[str, dict]) -> list[dict[str, Any]]:
    return [
        item if isinstance(item, dict) else rows[item]
        for item in order
        if isinstance(item, dict) or item in rows
    ]


class _Session:
    """The dask side of a batch: started at the first task to run, at most two tasks
    per worker thread in flight.
    """

    def __init__(self, workers: int | None, scheduler: str | None):
        self.workers, self.scheduler = workers, scheduler
        self._ctx = self._client = self._ac = None
        self._tasks: dict[str, Task] = {}
        self._window = 2

    def __enter__(self) -> _Session:
        return self

    def __exit__(self, *exc) -> None:
        if self._ctx is not None:
            self._ctx.__exit__(*exc)

    def _start(self) -> None:
        from distributed import as_completed

        self._ctx = dask_client(workers=self.workers, scheduler=self.scheduler)
        self._client = self._ctx.__enter__()
        threads = sum(self._client.nthreads().values())
        self._window = max(2, 2 * threads)
        self._ac = as_completed()

    def submit(self, task: Task, posterior: bool, keep_record: bool) -> Iterator[Outcome]:
        """Send ``task``; yield the outcomes that finish while the window is full."""
        if self._client is None:
            self._start()
        key = f"hosid-{task.analysis}-{task.id}"
        self._tasks[key] = task
        self._ac.add(
            self._client.submit(
                _in_worker, task, task.seed_sequence(), posterior, keep_record, key=key
            )
        )
        while self._ac.count() >= self._window:
            yield self._outcome(next(self._ac))

    def ready(self) -> Iterator[Outcome]:
        """The outcomes of the tasks that have finished, without waiting."""
        if self._ac is not None and self._ac.has_ready():
            for future in self._ac.next_batch(block=False):
                yield self._outcome(future)

    def drain(self) -> Iterator[Outcome]:
        """The outcomes of every task still in flight, as they finish."""
        if self._ac is not None:
            for future in self._ac:
                yield self._outcome(future)

    def _outcome(self, future) -> Outcome:
        from distributed import KilledWorker

        task = self._tasks.pop(future.key)
        try:
            return future.result()
        except KilledWorker:  # the task killed every worker it ran on
            message = "every worker that ran it died (KilledWorker); --retry-errors reruns it"
            return Outcome(_failed(task, message, task.id))
        except Exception as exc:  # lost scheduler, cancelled: not the task's result
            row = _failed(task, f"not run ({type(exc).__name__}: {exc}); rerun", task.id)
            return Outcome(row, final=False)
