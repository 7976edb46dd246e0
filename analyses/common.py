"""Helpers shared by the figure scripts in ``analyses/`` (not part of hosid).

Seeds, replicated records, quiet fits, posterior quantiles, the spectral-stiffness
fit the paper's Figures 1-3 need, CSV output and figure saving.  Every script
imports this module as ``common`` (``analyses/`` is the script's directory).
"""

from __future__ import annotations

import argparse
import csv
import math
import time
import warnings
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure
from scipy import optimize

from hosid import costs as C
from hosid import results as R
from hosid.estimators import SQRT_8_PI
from hosid.records import Record
from hosid.sampling import fit
from hosid.simulate import PAPER_PARAMS, simulate
from hosid.spectra import block_spectra

PARAMS = ("a1", "n1", "a2", "n2", "S0", "a1eq")
#: The S0 sweep of Figures 1, 2, 4 and 5 (the paper does not list its levels).
LEVELS = (25.0, 50.0, 100.0, 200.0, 400.0, 1000.0, 2500.0)
OUT = Path(__file__).resolve().parent / "out"


@dataclass(frozen=True)
class Settings:
    """Run size of a script: full by default, tiny with ``--quick``."""

    records: int
    duration: float
    seed: int
    n_steps: int | None  # None: fit's adaptive stopping rule
    n_bootstrap: int
    quick: bool
    out: Path

    def fit_kwargs(self) -> dict:
        """Keyword arguments for :func:`hosid.sampling.fit`."""
        return {"n_steps": self.n_steps, "n_bootstrap": self.n_bootstrap}


def add_arguments(ap: argparse.ArgumentParser, *, records: int, seed: int) -> None:
    """The options every script shares."""
    ap.add_argument("--records", type=int, default=records, help="records per setting")
    ap.add_argument("--duration", type=float, default=2000.0, help="record length (s)")
    ap.add_argument("--seed", type=int, default=seed)
    ap.add_argument("--steps", type=int, default=None, help="fixed emcee steps per fit")
    ap.add_argument("--bootstrap", type=int, default=30, help="calibration bootstrap records")
    ap.add_argument(
        "--quick",
        action="store_true",
        help="tiny run for the tests: 2 records of 400 s, 100 steps, 2 bootstrap records",
    )
    ap.add_argument("--out", type=Path, default=OUT)


def add_replot(ap: argparse.ArgumentParser) -> None:
    """``--replot``: redraw the figures from the CSV already in ``--out``."""
    ap.add_argument("--replot", action="store_true", help="redraw from the CSV in --out")


def settings(a: argparse.Namespace) -> Settings:
    """Settings from parsed options (``--quick`` overrides the sizes)."""
    if a.quick:
        return Settings(2, 400.0, a.seed, 100, 2, True, a.out)
    return Settings(a.records, a.duration, a.seed, a.steps, a.bootstrap, False, a.out)


def truth(S0: float) -> dict[str, float]:
    """The paper's oscillator (a1 = n1 = 0.5, a2 = 25, n2 = 5) at level S0."""
    return dict(PAPER_PARAMS, S0=float(S0))


def true_a1eq(params: Mapping[str, float], velocity: np.ndarray) -> float:
    """Eq (65) with the simulated velocity's standard deviation."""
    return params["a1"] + params["n1"] * SQRT_8_PI * float(np.std(velocity))


@dataclass(frozen=True)
class Sim:
    """A simulated record, its true parameters (with a1eq) and its own generator."""

    record: Record
    truth: dict[str, float]
    velocity: np.ndarray
    rng: np.random.Generator


def simulate_records(
    params: Mapping[str, float], n: int, *, duration: float, seed: np.random.SeedSequence
) -> list[Sim]:
    """``n`` independent records, each from its own spawned generator (also used
    afterwards for the record's fit)."""
    out = []
    for i, child in enumerate(seed.spawn(n)):
        rng = np.random.default_rng(child)
        rec, v = simulate(params, duration=duration, rng=rng, return_velocity=True, name=f"r{i}")
        out.append(Sim(rec, dict(params, a1eq=true_a1eq(params, v)), v, rng))
    return out


def quiet_fit(record: Record, **kwargs):
    """:func:`hosid.sampling.fit` with its warnings (edge of the admissible region,
    short chains) silenced; returns the tree, its summary and the fit time."""
    t0 = time.perf_counter()
    kwargs.setdefault("progress", False)
    kwargs.setdefault("cost_map", False)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        tree = fit(record, **kwargs)
        summary = R.summarize(tree, warn=False)
    return tree, summary, time.perf_counter() - t0


def draws(tree, name: str) -> np.ndarray:
    """All posterior draws of a variable, flattened."""
    return np.asarray(tree["posterior"][name].values, dtype=float).ravel()


def posterior_row(tree, summary, names: Iterable[str] = PARAMS) -> dict[str, float]:
    """``{p: median, p_q05: ..., p_q95: ...}`` plus the convergence flag and fit time."""
    row: dict[str, float] = {}
    for k in names:
        q05, q50, q95 = np.quantile(draws(tree, k), [0.05, 0.5, 0.95])
        row.update({k: q50, f"{k}_q05": q05, f"{k}_q95": q95})
    row["converged"] = int(summary["converged"])
    return row


def spectral_stiffness(
    record: Record,
    start: Mapping[str, float],
    *,
    omega_max: float = 8.0,
    costs: Sequence[str] = ("J2W", "J4AW"),
) -> dict[str, float]:
    """All five parameters by the spectral costs alone (the paper's Figures 1-3:
    "all the unknown parameters were simultaneously estimated").

    hosid's own estimators take the stiffness from moments; this is a local
    minimum of ``sum(costs)`` over (a1, n1, a2, n2, S0) from ``start`` (a protocol
    estimate), with a1, n1 >= 0 and S0 > 0 only.
    """
    data = C.prepare(block_spectra(record, omega_max=omega_max))
    p0 = np.array([start[k] for k in C.PARAM_NAMES], dtype=float)
    scale = np.array([0.5, 0.05, 1.0, 0.2, 0.05 * p0[4]])

    def f(u):
        th = p0 + u * scale
        if th[0] < 0 or th[1] < 0 or th[4] <= 0:
            return math.inf
        return float(sum(C.COSTS[c](th[None], data)[0] for c in costs))

    with warnings.catch_warnings(), np.errstate(invalid="ignore", over="ignore"):
        warnings.simplefilter("ignore", RuntimeWarning)  # inf outside the box
        r = optimize.minimize(
            f,
            np.zeros(5),
            method="Nelder-Mead",
            options={"maxfev": 2000, "xatol": 1e-3, "fatol": 1e-6, "adaptive": True},
        )
        r = optimize.minimize(f, r.x, method="Powell", options={"xtol": 1e-4, "ftol": 1e-9})
    est = dict(zip(C.PARAM_NAMES, map(float, p0 + r.x * scale), strict=True))
    return est


def write_csv(rows: Sequence[Mapping], path: Path) -> Path:
    """Rows (dicts, possibly with different keys) to CSV; missing cells empty."""
    path.parent.mkdir(parents=True, exist_ok=True)
    keys: list[str] = []
    for r in rows:
        keys += [k for k in r if k not in keys]
    with path.open("w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=keys, restval="")
        w.writeheader()
        for r in rows:
            w.writerow({k: _fmt(v) for k, v in r.items()})
    return path


def _fmt(v):
    if isinstance(v, float | np.floating):
        return f"{float(v):.6g}"
    return v


def figure(nrows: int = 1, ncols: int = 1, *, size=(6.5, 4.5), **kw) -> tuple[Figure, np.ndarray]:
    """A pyplot-free figure and its axes (always a 2-D array)."""
    fig = Figure(figsize=size, layout="constrained")
    axes = fig.subplots(nrows, ncols, squeeze=False, **kw)
    return fig, axes


def save(fig: Figure, path: Path) -> Path:
    """Write a PNG."""
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    return path


def clipped(ax, x, y, lo: float, hi: float, **kw) -> int:
    """Scatter ``y`` against ``x``; points outside ``[lo, hi]`` are drawn at the
    edge as triangles. Returns the number clipped."""
    x, y = np.asarray(x, float), np.asarray(y, float)
    inside = (y >= lo) & (y <= hi)
    ax.scatter(x[inside], y[inside], **kw)
    kw = {k: v for k, v in kw.items() if k not in ("marker", "label")}
    ax.scatter(x[y > hi], np.full((y > hi).sum(), hi), marker="^", **kw)
    ax.scatter(x[y < lo], np.full((y < lo).sum(), lo), marker="v", **kw)
    return int((~inside).sum())


def median_abs_rel(est, true) -> float:
    """Median absolute relative error."""
    est, true = np.asarray(est, float), np.asarray(true, float)
    return float(np.median(np.abs(est / true - 1)))


def read_csv(path: Path) -> list[dict]:
    """Rows written by :func:`write_csv`, numbers as floats, empty cells dropped
    (to redraw a figure with ``--replot`` without recomputing)."""
    with path.open() as fh:
        rows = list(csv.DictReader(fh))
    out = []
    for r in rows:
        d = {}
        for k, v in r.items():
            if v == "":
                continue
            try:
                d[k] = float(v)
            except ValueError:
                d[k] = v
        out.append(d)
    return out
