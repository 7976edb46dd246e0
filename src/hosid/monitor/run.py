r"""``hosid monitor``: a long or growing record, window by window, through the batch
engine; the tracks, the change test and the report.

Every window (:mod:`hosid.monitor.windows`) becomes one task of :func:`hosid.batch.run_batch`
(analysis ``fit`` by default: one calibrated posterior per window, on a local dask
cluster or ``scheduler``), so the folder ``OUT/windows`` keeps each finished window as
the batch command does and a rerun, after a crash or a kill, fits only the windows not
done yet.  The record is read by chunks and at most two windows a worker thread are
held at once.  From the rows the monitor writes, together (staged, then moved in):

* ``tracks.csv`` (and ``tracks.nc``): a row per window and parameter with ``start``,
  ``end``, ``parameter``, ``mean``, ``sd``, ``q05``, ``q50``, ``q95``, the window's
  ``status`` and record-check ``verdict`` (a window that fails its checks keeps its
  rows, without numbers: it is marked, never dropped);
* ``changes.csv``: the named changes (:mod:`hosid.monitor.joint`) with ``parameter``,
  ``time``, ``time_lo``, ``time_hi``, ``size``, ``size_lo``, ``size_hi`` (after minus
  before), the parameter's ``kind`` (``drift``: the structure; ``excitation``: the
  force, e.g. a calmer sea) and the test's ``statistic``, ``p_value`` and ``threshold``;
* ``tracks.png``, ``report.html`` and ``monitor.json`` (settings, counts and the change
  test's ``alpha``, ``level`` and ``correlation``, :data:`hosid.monitor.tracks.CORRELATION`).

Warm starts are not used: a window's fit starts from its own pilot estimate, which
costs a few percent of the sampling it would save.
"""

from __future__ import annotations

import json
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..errors import HosidInputError
from ..output.files import locked_dir, staged, write_atomic
from .changes import ALPHA
from .source import Source
from .tracks import Tracks, read_baseline
from .windows import Layout, choose_layout, count, describe, windows

__all__ = ["MonitorResult", "monitor"]

SETTINGS = "monitor.json"


@dataclass
class MonitorResult:
    """What :func:`monitor` wrote: the folder, the tracks, the changes, the files."""

    out: Path
    layout: Layout
    tracks: Tracks
    changes: list = field(default_factory=list)
    files: list[Path] = field(default_factory=list)
    seconds: float = 0.0
    ran: int = 0  # windows fitted now
    skipped: int = 0  # windows found done before (a resumed monitor)


def _settings(source: Source, layout: Layout, analysis: str, options: Mapping, seed: int):
    return {
        "source": str(source.path.resolve()),
        "layout": layout.as_dict(),
        "analysis": analysis,
        "options": dict(options),
        "seed": int(seed),
    }


def _check_settings(out: Path, settings: Mapping) -> None:
    path = out / SETTINGS
    if not path.is_file():
        return
    try:
        old = json.loads(path.read_text()).get("settings", {})
    except (OSError, ValueError):
        return
    diff = [k for k in settings if old.get(k) != settings[k]]
    if diff:
        raise HosidInputError(
            f"{out} holds a monitor with other {', '.join(diff)}; choose another --out "
            "(or remove it) to monitor with these settings"
        )


def _layout(source: Source, window, step, block_seconds, follow: bool):
    """The windows' layout and, for a record of known length, their number.

    Raises
    ------
    HosidInputError
        If no window fits in the record.
    """
    total = None if follow else source.samples()
    layout = choose_layout(
        source, window=window, step=step, block_seconds=block_seconds, total_samples=total
    )
    n_windows = None if total is None else count(total, layout)
    if n_windows == 0:
        raise HosidInputError(
            f"{source.path}: {total} samples ({total * layout.dt:g} s) hold no window of "
            f"{layout.seconds:g} s"
        )
    return layout, n_windows


def _tasks(source, layout, analysis, options, seed, meta, *, follow, poll, stop):
    from ..batch import Task
    from ..record import Record

    for w in windows(source.pieces(follow=follow, poll=poll, stop=stop), layout, tail=not follow):
        if w is None:  # the growing file had nothing new: collect what finished
            yield None
            continue
        record = Record(w.x, layout.dt, name=f"{source.name}@{w.start:g}s")
        task = Task(f"window-{w.index:05d}", analysis, options, seed, record=record)
        meta.append((w.index, w.start, w.end, task.id))
        yield task


def monitor(
    path: str | Path,
    out: str | Path,
    *,
    window: float | None = None,
    step: float | None = None,
    block_seconds: float | None = None,
    analysis: str = "fit",
    options: Mapping[str, Any] | None = None,
    alpha: float = ALPHA,
    level: float = 0.95,
    baseline: str | Path | None = None,
    baseline_windows: int = 0,
    seed: int = 0,
    workers: int | None = None,
    scheduler: str | None = None,
    follow: bool = False,
    poll: float = 2.0,
    stop: Callable[[], bool] | None = None,
    progress: bool = True,
    echo: Callable[[str], None] | None = None,
) -> MonitorResult:
    """Monitor the record ``path`` into the folder ``out`` (module docstring).

    Parameters
    ----------
    path : path
        A ``.csv`` or ``.npz`` record, or a folder of consecutive ones.
    out : path
        The monitor's folder (created; a rerun with the same settings resumes).
    window, step, block_seconds : float, optional
        Window length, step between window starts and block length (s); defaults from
        the record (:mod:`hosid.monitor.windows`).
    analysis : {"fit", "estimate"}
        A calibrated emcee posterior per window, or the faster Laplace estimate.
    options : mapping, optional
        Options of the analysis (``model``, ``cost``, ...: :data:`hosid.batch.tasks.OPTIONS`).
    alpha : float
        Probability of naming any change in a stationary record (the family of
        parameters and times).
    level : float
        Level of the intervals of a change's time and size.
    baseline : path, optional
        A fit's ``summary.json`` whose posterior is the state before any change.
    baseline_windows : int
        Or: the first windows are the reference; changes are sought after them.
    seed : int
        Root seed (each window's stream follows from its content).
    workers, scheduler
        The dask cluster (:func:`hosid.batch.run_batch`).
    follow : bool
        Keep reading the growing file until ``stop()`` (or Ctrl-C); each new window is
        reported through ``echo`` and the tables are rewritten.
    poll : float
        Seconds between looks at a growing file.
    progress : bool
        One progress bar over the windows.
    echo : callable, optional
        Where the lines on new windows go (default ``print``).

    Raises
    ------
    HosidInputError
        On an unreadable record, impossible windows, or a folder holding another
        monitor's results.
    """
    import time

    from ..batch import options_for, run_batch

    t0 = time.perf_counter()
    echo = echo or print
    if analysis not in ("fit", "estimate"):
        raise HosidInputError(f"monitor analysis must be fit or estimate, got {analysis!r}")
    if not 0 < alpha < 1 or not 0 < level < 1:
        raise HosidInputError("alpha and level must lie between 0 and 1")
    source = Source(path)
    layout, n_windows = _layout(source, window, step, block_seconds, follow)
    opts = options_for(analysis, {**(options or {}), "block_seconds": layout.block_seconds})
    base = read_baseline(baseline) if baseline is not None else None
    settings = _settings(source, layout, analysis, opts, seed)
    out = Path(out)
    echo(f"hosid monitor: {describe(layout)}" + (f", {n_windows} windows" if n_windows else ""))
    result = MonitorResult(out, layout, Tracks.empty(layout))
    tables = _Tables(result, opts["model"], settings, echo if follow else None,
                     dict(alpha=alpha, level=level, baseline=base,
                          baseline_windows=baseline_windows, seed=seed))  # fmt: skip
    with locked_dir(out, command="hosid monitor"):
        _check_settings(out, settings)
        write_atomic(out / SETTINGS, json.dumps({"settings": settings}, indent=1) + "\n")
        tasks = _tasks(
            source, layout, analysis, opts, seed, tables.meta, follow=follow, poll=poll, stop=stop
        )
        if n_windows is not None:
            tasks = _Sized(tasks, n_windows)
        try:
            batch = run_batch(
                tasks,
                out / "windows",
                workers=workers,
                scheduler=scheduler,
                progress=progress,
                label="hosid monitor",
                on_row=tables.add,
            )
            result.ran, result.skipped = batch.ran, batch.skipped
        except KeyboardInterrupt:
            if not follow:
                raise
            echo("hosid monitor: stopped; the finished windows are kept")
        tables.publish()
    result.seconds = time.perf_counter() - t0
    return result


class _Tables:
    """The monitor's tables as its windows finish: ``meta`` (window number, start, end,
    task) filled by the task generator, each finished window's row added; ``publish``
    rewrites the tracks and changes into the result's folder (staged, never half
    written), after every window when ``echo`` reports them (``--follow``).
    """

    def __init__(self, result: MonitorResult, model, settings, echo, test: Mapping):
        self.result, self.model, self.settings, self.echo, self.test = (
            result, model, settings, echo, dict(test)
        )  # fmt: skip
        self.meta: list[tuple[int, float, float, str]] = []
        self.rows: dict[str, dict] = {}

    def publish(self) -> None:
        """Tracks, changes and their files from the rows so far."""
        r, t = self.result, self.test
        r.tracks = Tracks.from_rows(self.meta, self.rows, r.layout, self.model)
        r.changes = r.tracks.changes(**t)
        with staged(r.out, command="hosid monitor", keep=()) as stage:
            files = r.tracks.write(
                stage, r.changes, settings=self.settings, alpha=t["alpha"], level=t["level"]
            )
        r.files = [r.out / p.name for p in files]

    def add(self, row: dict) -> None:
        """A finished window's row (reported and published when following)."""
        self.rows[row["task"]] = row
        if self.echo is not None:
            i, start, end, _ = next(m for m in self.meta if m[3] == row["task"])
            self.echo(f"window {i}: {start:g}-{end:g} s {row.get('status')} " + _brief(row))
            self.publish()


def _brief(row: Mapping) -> str:
    shown = [
        f"{k[:-5]} {row[k]:.4g} ± {row.get(k[:-5] + '_sd', float('nan')):.2g}"
        for k in row
        if k.endswith("_mean") and isinstance(row[k], int | float)
    ]
    return ", ".join(shown[:5]) or str(row.get("message", ""))


class _Sized:
    """An iterator with a length (for the progress bar)."""

    def __init__(self, it: Iterator, n: int):
        self._it, self._n = it, n

    def __iter__(self):
        return self._it

    def __len__(self) -> int:
        return self._n
