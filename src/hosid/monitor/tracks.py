"""The tracks of a monitor: every parameter's posterior window by window, their tables,
and the change test run on them (:mod:`hosid.monitor.joint`).

A window whose fit did not give a posterior (its record checks rejected it, or it
failed) keeps its place in the tracks with its ``status``, ``verdict`` and ``message``
and no numbers; the change test leaves it out (a gap in the track).  Only the model's
own parameters are tested (a derived quantity such as eq (65)'s ``a1eq`` moves with the
excitation level by definition); each named change says whether its parameter belongs
to the structure (``drift``) or to the force (``excitation``).

**Correlation.** The test weighs each window by its posterior covariance and measures a
step of one parameter with its information *given the others*, which for a strongly
correlated pair rests on the small eigenvalue of their correlation.  That eigenvalue is
noisy from window to window: on one 40 000 s record of the ship-roll-like oscillator
(``analyses/monitor_study.py``'s ``ship_a2`` record 6) the ten windows' correlation of
``a1`` and ``n1`` ranged from -0.91 to -0.98, and the last two windows, which had moved
along that pair's ridge, got an ``n1`` step named in place of the record's ``a2`` step.
The estimator's correlation is a property of the system at its operating point, shared
by the windows; by default (:data:`CORRELATION` ``"pooled"``) the test takes each
window's own sds and the mean of the windows' correlations (a failed window left out).
Measured against each window's own correlation, in brackets, on the same kept tracks
(``analyses/results/monitor/correlation.md``: 10 records a step, 20 stationary, a
system): the ship's -5 % ``a2`` step named 9/10 (8/10), its time interval holding the
truth 9/10 (6/10), its size 8/10 (7/10), a wrong structural parameter 0/10 (1/10), a
stationary record's false alarm 0/20 (1/20); the paper oscillator's 7/10 (7/10), 6/10
(6/10), 7/10 (7/10), wrong 2/10 (3/10), stationary 0/20 (0/20); a 30 % step of S0 alone
named alone in 10/10 on each system, no structural parameter (both).
"""

from __future__ import annotations

import csv
import io
import json
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import HosidInputError
from ..output.files import write_atomic
from .windows import Layout

__all__ = ["CHANGE_COLUMNS", "TRACK_COLUMNS", "Tracks", "read_baseline"]

TRACK_COLUMNS = ("start", "end", "parameter", "mean", "sd", "q05", "q50", "q95")
STATS = ("mean", "sd", "q05", "q50", "q95")
CHANGE_COLUMNS = ("parameter", "time", "time_lo", "time_hi", "size", "size_lo", "size_hi")
CHANGE_EXTRA = ("kind", "before", "statistic", "p_value", "threshold", "role")
#: Which posterior correlation the change test gives each window by default
#: (:meth:`Tracks.changes`; module docstring).
CORRELATION = "pooled"


def _kinds(model: str) -> dict[str, str]:
    """Parameter -> ``drift`` / ``excitation`` / ``observation`` of the model's terms."""
    from ..model.model import Model

    try:
        m = Model.from_spec(model)
    except HosidInputError:  # a measured shape is read by the fit: its level is S0
        m = Model.from_spec("paper")
    return {p: t.kind for t in m.terms for p in t.params}


@dataclass
class Tracks:
    """Windows (index, start, end, status, verdict, message) and per parameter the
    arrays of :data:`STATS` (NaN where a window has no posterior).
    """

    layout: Layout
    index: np.ndarray
    start: np.ndarray
    end: np.ndarray
    status: list[str]
    verdict: list[str]
    message: list[str]
    values: dict[str, dict[str, np.ndarray]] = field(default_factory=dict)
    kinds: dict[str, str] = field(default_factory=dict)
    corr: np.ndarray | None = None  # (windows, tested, tested) posterior correlations

    @classmethod
    def empty(cls, layout: Layout) -> Tracks:
        """No window yet."""
        z = np.zeros(0)
        return cls(layout, z.astype(int), z, z, [], [], [])

    @classmethod
    def from_rows(
        cls, meta: Sequence[tuple[int, float, float, str]], rows: Mapping[str, dict], layout, model
    ) -> Tracks:
        """The tracks of the windows ``meta`` (index, start, end, task id) whose rows have
        arrived (``rows`` by task id), in window order.
        """
        done = sorted((m for m in meta if m[3] in rows), key=lambda m: m[0])
        kinds = _kinds(model)
        params: list[str] = []
        for m in done:
            for k in rows[m[3]]:
                if k.endswith("_mean") and k[:-5] not in params and not k.startswith("true_"):
                    params.append(k[:-5])
        params.sort(key=lambda p: (p not in kinds, list(kinds).index(p) if p in kinds else 0))
        values = {p: {s: np.full(len(done), np.nan) for s in STATS} for p in params}
        for i, m in enumerate(done):
            row = rows[m[3]]
            if row.get("status") != "ok":
                continue
            for p in params:
                for s in STATS:
                    v = row.get(f"{p}_{s}")
                    values[p][s][i] = float(v) if isinstance(v, int | float) else math.nan
        tested = [p for p in params if p in kinds]
        corr = np.stack([_corr(rows[m[3]], tested) for m in done]) if done else None
        return cls(
            layout,
            np.array([m[0] for m in done], dtype=int),
            np.array([m[1] for m in done], dtype=float),
            np.array([m[2] for m in done], dtype=float),
            [str(rows[m[3]].get("status", "")) for m in done],
            [str(rows[m[3]].get("verdict", "") or "") for m in done],
            [
                str(rows[m[3]].get("message", "") or rows[m[3]].get("checks", "") or "")
                for m in done
            ],
            values,
            {p: kinds.get(p, "derived") for p in params},
            corr,
        )

    @property
    def tested(self) -> list[str]:
        """The parameters the change test looks at: the model's own."""
        return [p for p, k in self.kinds.items() if k != "derived"]

    @property
    def failed(self) -> list[int]:
        """Positions of the windows without a posterior."""
        return [i for i, s in enumerate(self.status) if s != "ok"]

    def changes(
        self, *, alpha, level, baseline=None, baseline_windows=0, seed=0, correlation=CORRELATION
    ) -> list:
        """The named changes (:func:`hosid.monitor.joint.joint_changes` on the model's
        parameters with each window's posterior covariance: its sds and, with
        ``correlation`` ``"pooled"``, the windows' mean correlation, ``"own"`` its own;
        :data:`CORRELATION`), sorted by time; the Monte-Carlo draws come from
        ``SeedSequence(seed)``.
        """
        from .joint import joint_changes

        names = self.tested
        self.reasons = {}
        if self.start.size == 0 or not names:
            return []
        Y = np.stack([self.values[p]["mean"] for p in names], 1)
        sd = np.stack([self.values[p]["sd"] for p in names], 1)
        corr = self.corr
        if correlation == "pooled":
            ok = np.all(np.isfinite(corr), axis=(1, 2))
            if ok.any():
                corr = np.where(ok[:, None, None], corr[ok].mean(axis=0), corr)
        elif correlation != "own":
            raise ValueError(f"correlation must be 'pooled' or 'own', not {correlation!r}")
        cov = corr * sd[:, :, None] * sd[:, None, :]
        base = None
        if baseline is not None:
            missing = [p for p in names if p not in baseline]
            if missing:
                raise HosidInputError(f"the baseline has no {', '.join(missing)}")
            base = (
                np.array([baseline[p][0] for p in names]),
                np.array([baseline[p][1] for p in names]),
            )
        rng = np.random.default_rng(np.random.SeedSequence(int(seed), spawn_key=(0xC4A9,)))
        found, why = joint_changes(
            self.start, self.end, Y, cov, names, rng=rng, alpha=alpha, level=level,
            baseline=base, baseline_windows=baseline_windows,
        )  # fmt: skip
        if why:
            self.reasons = {"all": why}
        return found

    # ------------------------------------------------------------------ files
    def rows(self) -> list[dict]:
        """``tracks.csv``'s rows: a row per window and parameter."""
        out = []
        for i in range(self.start.size):
            for p, v in self.values.items():
                row = {"start": self.start[i], "end": self.end[i], "parameter": p}
                row.update({s: v[s][i] for s in STATS})
                row.update(window=int(self.index[i]), kind=self.kinds[p])
                row.update(status=self.status[i], verdict=self.verdict[i])
                out.append(row)
        return out

    def to_dataset(self):
        """The tracks as an :class:`xarray.Dataset` (dims ``window``, ``parameter``)."""
        import xarray as xr

        params = list(self.values)
        data = {
            s: (("window", "parameter"), np.stack([self.values[p][s] for p in params], 1))
            if params
            else (("window", "parameter"), np.zeros((self.start.size, 0)))
            for s in STATS
        }
        if self.corr is not None and self.tested:
            data["corr"] = (("window", "tested", "tested_other"), self.corr)
        ds = xr.Dataset(
            data,
            coords={
                "window": self.index,
                "parameter": params,
                "start": ("window", self.start),
                "end": ("window", self.end),
                "status": ("window", np.array(self.status, dtype=str)),
                "verdict": ("window", np.array(self.verdict, dtype=str)),
                "kind": ("parameter", np.array([self.kinds[p] for p in params], dtype=str)),
                **({"tested": self.tested, "tested_other": self.tested} if "corr" in data else {}),
            },
        )
        ds.attrs.update({k: v for k, v in self.layout.as_dict().items()})
        return ds

    @classmethod
    def read(cls, path: str | Path) -> Tracks:
        """The tracks a monitor wrote to ``tracks.nc`` (``path``: the file or its folder),
        with each window's posterior correlation (``corr``), so that the change test can
        be run again without refitting (:meth:`changes`).  The windows' messages are
        not stored there and read as empty.

        Raises
        ------
        HosidInputError
            If the file is missing, is not a monitor's tracks, or has no correlations
            (written before they were kept).
        """
        import xarray as xr

        path = Path(path)
        path = path / "tracks.nc" if path.is_dir() else path
        if not path.is_file():
            raise HosidInputError(f"{path}: no such file")
        with xr.open_dataset(path) as ds:
            ds = ds.load()
        if "corr" not in ds or "mean" not in ds:
            raise HosidInputError(f"{path}: not a monitor's tracks.nc with correlations")
        a = ds.attrs
        layout = Layout(int(a["window_samples"]), int(a["step_samples"]), float(a["dt"]),
                        float(a["block_seconds"]))  # fmt: skip
        params = [str(p) for p in ds["parameter"].values]
        values = {p: {s: ds[s].sel(parameter=p).values.astype(float) for s in STATS}
                  for p in params}  # fmt: skip
        n = ds.sizes["window"]
        return cls(
            layout, ds["window"].values.astype(int), ds["start"].values.astype(float),
            ds["end"].values.astype(float), [str(v) for v in ds["status"].values],
            [str(v) for v in ds["verdict"].values], [""] * n, values,
            dict(zip(params, (str(k) for k in ds["kind"].values), strict=True)),
            ds["corr"].values.astype(float),
        )  # fmt: skip

    def write(self, stage: Path, changes, *, settings, alpha, level) -> list[Path]:
        """Write the monitor's files into ``stage`` (module docstring of
        :mod:`hosid.monitor.run`); returns their paths.
        """
        from .report import write_report

        files = [
            _csv(stage / "tracks.csv", [*TRACK_COLUMNS, "window", "kind", "status", "verdict"],
                 self.rows()),
            _csv(stage / "changes.csv", [*CHANGE_COLUMNS, *CHANGE_EXTRA],
                 [self.change_row(c) for c in changes]),
        ]  # fmt: skip
        nc = stage / "tracks.nc"
        self.to_dataset().to_netcdf(nc)
        files.append(nc)
        summary = {
            "settings": settings,
            "windows": int(self.start.size),
            "failed_windows": [int(self.index[i]) for i in self.failed],
            "alpha": alpha,
            "level": level,
            "correlation": CORRELATION,
            "changes": [self.change_row(c) for c in changes],
            "untested": getattr(self, "reasons", {}),
        }
        files.append(write_atomic(stage / "monitor.json", json.dumps(summary, indent=1) + "\n"))
        files += write_report(stage, self, changes, settings=settings, alpha=alpha, level=level)
        return files

    def change_row(self, c) -> dict:
        """``changes.csv``'s row of the change ``c``."""
        row = {k: getattr(c, k) for k in CHANGE_COLUMNS}
        row.update(kind=self.kinds.get(c.parameter, ""), before=c.before)
        row.update(statistic=c.statistic, p_value=c.p_value, threshold=c.threshold)
        row.update(role=c.role)
        return row


def _corr(row: Mapping, names: Sequence[str]) -> np.ndarray:
    """A window's posterior correlation of ``names`` (its row's ``posterior_corr``; the
    identity when the row has none).
    """
    out = np.eye(len(names))
    cell = row.get("posterior_corr")
    if not cell:
        return out
    try:
        data = json.loads(cell) if isinstance(cell, str) else cell
        idx = [data["params"].index(p) for p in names]
        out = np.asarray(data["corr"], dtype=float)[np.ix_(idx, idx)]
    except (ValueError, KeyError, TypeError, IndexError):
        return np.eye(len(names))
    return out


def _note(row: Mapping) -> str:
    return str(row.get("message", "") or row.get("checks", "") or "")


def _csv(path: Path, columns: Sequence[str], rows: Sequence[Mapping]) -> Path:
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=list(columns), lineterminator="\n", extrasaction="ignore")
    w.writeheader()
    for row in rows:
        w.writerow({k: _cell(v) for k, v in row.items()})
    return write_atomic(path, buf.getvalue())


def _cell(v):
    if isinstance(v, float | np.floating):
        return "" if not math.isfinite(v) else repr(float(v))
    return v


def read_baseline(path: str | Path) -> dict[str, tuple[float, float]]:
    """The reference state of a fit's ``summary.json``: ``{parameter: (mean, sd)}``.

    Raises
    ------
    HosidInputError
        If the file is missing or holds no ``parameters`` with ``mean`` and ``sd``.
    """
    path = Path(path)
    try:
        data = json.loads(path.read_text())
    except FileNotFoundError:
        raise HosidInputError(f"{path}: no such file") from None
    except (OSError, UnicodeDecodeError, ValueError) as exc:
        raise HosidInputError(f"{path}: not a fit's summary.json ({exc})") from None
    params = data.get("parameters") if isinstance(data, dict) else None
    try:
        base = {k: (float(v["mean"]), float(v["sd"])) for k, v in params.items()}
    except (AttributeError, KeyError, TypeError, ValueError):
        raise HosidInputError(
            f"{path}: not a fit's summary.json (needs parameters with mean and sd)"
        ) from None
    if not base:
        raise HosidInputError(f"{path}: its parameters are empty")
    return base
