r"""What a worker does with one task: a pure function of the task and its seed.

:func:`run_task` simulates the design point (or takes the record), runs the analysis
with the same engine as the single commands (:func:`hosid.fit`, :func:`hosid.estimate`,
:func:`hosid.check.diagnose.diagnose`) and returns the task's row of the results table
(:mod:`hosid.batch.table`) and, when asked, its posterior as netCDF bytes and the
simulated record.  A record the checks reject gives a row with status ``rejected``, any
other failure a row with status ``error`` and its message: a task never raises.

Per parameter the row holds the posterior mean, sd, 5/25/50/75/95 % quantiles, the
smallest and largest draw, R-hat and the bulk and tail ESS (:func:`summarize`);
``estimate`` gives the mode as ``mean`` and the Gaussian quantiles of its calibrated
sd.  True values become ``true_<name>`` columns; with the simulated velocity, the true
equivalent damping of eq (65), :math:`a_{1eq} = a_1 + n_1\sqrt{8/\pi}\,\sigma_{\dot x}`.
"""

from __future__ import annotations

import json
import math
import tempfile
import time
import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import HosidInputError, RecordRejected
from ..model.model import Model
from ..model.terms import TERMS
from ..record import Record
from ..verdicts import Check, overall
from .tasks import OPTIONS, Task, child_seed

__all__ = ["Outcome", "run_task"]

_GAUSS_Z = (-1.6448536269514722, -0.6744897501960817, 0.0, 0.6744897501960817, 1.6448536269514722)
_QUANTILES = ("q05", "q25", "q50", "q75", "q95")


@dataclass
class Outcome:
    """A task's result: its row, and its posterior and record when asked.  ``final`` is
    false for a task that did not run (its cluster went away): its row is not stored, and
    a rerun runs it.
    """

    row: dict[str, Any]
    posterior: bytes | None = None
    record: Record | None = None
    final: bool = True


def _check(c: Check | Mapping[str, Any]) -> Check:
    return c if isinstance(c, Check) else Check.from_dict(c)


def _verdict(row: dict[str, Any], checks: Sequence[Check | Mapping[str, Any]]) -> None:
    checks = [_check(c) for c in checks]
    row["verdict"] = overall(checks)
    bad = [f"{c.name} {c.status}: {c.message}" for c in checks if c.status != "pass"]
    if bad:
        row["checks"] = "; ".join(bad)


def _draw_stats(tree) -> tuple[dict[str, dict[str, float]], dict[str, Any]]:
    """Per parameter summary of a fitted tree, and the fit's scalars."""
    from ..output.results import attr, summarize

    summary = summarize(tree, warn=False)
    post = tree["posterior"]
    params = {}
    for p, s in summary["parameters"].items():
        draws = post[p].values
        params[p] = {**s, "min": float(draws.min()), "max": float(draws.max())}
    names = list(summary["parameters"])
    draws = np.stack([np.asarray(post[p].values, dtype=float).ravel() for p in names])
    scalars = {
        "converged": int(summary["converged"]),
        "steps": (attr(tree, "sampler") or {}).get("steps"),
        "fit_seconds": summary["fit_seconds"],
        "posterior_corr": _corr_cell(names, np.cov(draws)),
    }
    return params, scalars


def _corr_cell(names: Sequence[str], cov: np.ndarray) -> str:
    """The posterior correlation matrix as one JSON cell: ``{"params": [...], "corr":
    [[...]]}`` (the change test of ``hosid monitor`` weighs a window's parameters by it).
    """
    sd = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    with np.errstate(invalid="ignore", divide="ignore"):
        corr = cov / np.outer(sd, sd)
    corr = np.where(np.isfinite(corr), corr, 0.0)
    np.fill_diagonal(corr, 1.0)
    return json.dumps({"params": list(names), "corr": np.round(corr, 6).tolist()})


def _with_shape(options: Mapping) -> dict:
    """``options`` with ``excitation_shape`` (a CSV path) read into the model."""
    o = dict(options)
    path = o.pop("excitation_shape", None)
    if path is not None:
        from ..model.measured import with_shape

        o["model"] = with_shape(o["model"], path)
    return o


def _declared(record: Record, options: dict) -> Record:
    """``record`` with every channel declared what ``options["measured"]`` says (popped;
    ``None``: as its file says).
    """
    measured = options.pop("measured", None)
    return record if measured is None else record.select(record.channels, measured=measured)


def _fit(record: Record, options: Mapping, rng, truths, keep: bool):
    from ..inference import fit
    from ..output.results import attr

    o = _with_shape(options)
    record = _declared(record, o)
    tree = fit(record, **o, seed=rng, progress=False, truths=truths, with_map=keep)
    params, row = _draw_stats(tree)
    return params, row, tree, attr(tree, "checks") or [], list(attr(tree, "model"))


def _gaussian(values: Mapping[str, float], sd: Mapping[str, float]) -> dict[str, dict]:
    """Per parameter its mean, sd and the Gaussian quantiles of the table's columns."""
    return {
        p: {"mean": v, "sd": sd[p],
            **{q: v + z * sd[p] for q, z in zip(_QUANTILES, _GAUSS_Z, strict=True)}}
        for p, v in values.items()
    }  # fmt: skip


def _estimate(record: Record, options: Mapping, rng, truths, keep: bool):
    from ..inference import components_for, estimate

    t0 = time.perf_counter()
    o = _with_shape(options)
    record = _declared(record, o)
    band = None if o["omega_max"] is None else (0.0, float(o["omega_max"]))
    comps = components_for(o["cost"], band=band, form=o["form"], domain=o["domain"])
    est = estimate(record, o["model"], comps, block_seconds=o["block_seconds"])
    values, sd = dict(est.values), dict(est.sd)
    names, cov = list(est.model.param_names), np.asarray(est.cov, dtype=float)
    # eq (65) is linear in theta: its gradient is its value at e_i (a system: per element,
    # in its fit's summary)
    if isinstance(est.model, Model) and est.model.has("a1"):
        g = est.model.equivalent_damping(np.eye(len(est.theta)), est.sigma_v)
        values["a1eq"] = float(g @ est.theta)
        sd["a1eq"] = math.sqrt(float(g @ est.cov @ g))
        gc = cov @ g
        cov = np.block([[cov, gc[:, None]], [gc[None, :], np.array([[g @ gc]])]])
        names.append("a1eq")
    params = _gaussian(values, sd)
    row = {
        "hansen_J": est.test.get("J"),
        "hansen_df": est.test.get("df"),
        "hansen_p": est.test.get("p_value"),
        "fit_seconds": time.perf_counter() - t0,
        "posterior_corr": _corr_cell(names, cov),
    }
    return params, row, None, getattr(est, "checks", None) or [], list(est.model.names)


def _sample_stats(check) -> dict[str, dict[str, float]]:
    """Per parameter summary of a screened posterior's draws (no chains: no R-hat, ESS)."""
    q = np.quantile(check.sample, [0.05, 0.25, 0.5, 0.75, 0.95], axis=0)
    return {
        p: {
            "mean": float(np.mean(check.sample[:, i])),
            "sd": float(np.std(check.sample[:, i], ddof=1)),
            **{name: float(v) for name, v in zip(_QUANTILES, q[:, i], strict=True)},
            "min": float(np.min(check.sample[:, i])),
            "max": float(np.max(check.sample[:, i])),
        }
        for i, p in enumerate(check.model.param_names)
    }


def _diagnose(record: Record, options: Mapping, rng, truths, keep: bool):
    """``diagnose``; the row also holds the gap after each step (``gaps``), every first-round
    candidate's evidence (``evidence``: JSON ``{effect: [z, D, p, adjusted p]}``) and the
    named parameters' posterior means (``estimates``, JSON).
    """
    from ..check.diagnose import diagnose
    from ..output.results import jsonable

    t0 = time.perf_counter()
    o = _with_shape(options)
    record = _declared(record, o)
    if str(o["model"]).lower().endswith(".toml"):
        return _locate(record, o, t0)
    settings = {k: o[k] for k in OPTIONS["diagnose"] if k in o and k != "model"}
    d = diagnose(record, o["model"], rng=rng, **settings)
    rep = d.report()
    tree = d.final.tree  # None with posterior="screen"
    if tree is not None:
        params, row = _draw_stats(tree)
    else:
        params, row = _sample_stats(d.final), {}
    row.update(
        named_effect="+".join(rep["named_effects"]),
        decision=rep["decision"],
        gap_before=rep["gap_before"],
        gap_after=rep["gap_after"],
        gaps=";".join(repr(float(g)) for g in d.gaps),
        evidence=json.dumps(jsonable(d.rounds[0].numbers() if d.rounds else {})),
        estimates=json.dumps({s.effect: s.posterior()["mean"] for s in d.steps}),
        rounds_calibrated=sum(r.calibrated for r in d.rounds),
        fit_seconds=time.perf_counter() - t0,
    )
    row["final_model"] = "+".join(rep["final_model"])
    return params, row, tree, rep["checks"], list(rep["final_model"])


def _locate(record: Record, o: Mapping, t0: float):
    """``diagnose`` with a system file (``hosid diagnose REC --model SYSTEM.toml``): the
    missing (effect, element) pairs (:func:`hosid.check.locate.locate`); the row holds
    ``named_effect``, ``decision`` and every round's z by pair (``evidence``), the final
    system's estimate with its Gaussian quantiles.
    """
    from ..check.locate import locate
    from ..model.system import System

    loc = locate(record, System.from_toml(o["model"]), candidates=o["candidates"],
                 alpha=o["alpha"], max_effects=o["max_effects"])  # fmt: skip
    params = _gaussian(loc.estimate, loc.sd)
    row = {
        "named_effect": "+".join(loc.named_effects),
        "decision": loc.decision,
        "evidence": json.dumps([{w.label: round(w.z, 3) for w in r.weighed} for r in loc.rounds]),
        "fit_seconds": time.perf_counter() - t0,
    }
    return params, row, None, loc.record_checks, list(loc.final.param_names)


_RUN = {"fit": _fit, "estimate": _estimate, "diagnose": _diagnose}


def _record(task: Task, seed) -> tuple[Record, np.ndarray | None]:
    if task.point is not None:
        from .design import simulate

        return simulate(task.point, rng=np.random.default_rng(child_seed(seed, 0)))
    if task.record is None:
        raise HosidInputError(f"{task.label}: the record was not read")
    return task.record, None  # unpickled as an aligned copy (Record.__setstate__)


def _netcdf(tree) -> bytes:
    """``posterior.nc`` as bytes (:func:`hosid.output.results.save`).  The tree is in
    memory: xarray's writer needs no lock of the dask cluster it runs in.
    """
    import dask

    from ..output.results import save

    with tempfile.TemporaryDirectory() as tmp, dask.config.set(scheduler="synchronous"):
        return save(tree, Path(tmp) / "posterior.nc").read_bytes()


def _one_line(exc: BaseException) -> str:
    text = " ".join(str(exc).split()) or type(exc).__name__
    if not isinstance(exc, HosidInputError | RecordRejected):
        text = f"{type(exc).__name__}: {text}"
    return text[:500]


def run_task(
    task: Task,
    seed: np.random.SeedSequence,
    *,
    posterior: bool = False,
    keep_record: bool = False,
) -> Outcome:
    """Run one task (module docstring); never raises.

    Parameters
    ----------
    task : Task
        A prepared task (:meth:`Task.prepare`).
    seed : numpy.random.SeedSequence
        Its random stream (:meth:`Task.seed_sequence`): child 0 simulates, child 1
        drives the analysis.
    posterior : bool
        Return the posterior (``posterior.nc`` bytes) and evaluate the likelihood map
        that its report draws.
    keep_record : bool
        Return the simulated record.
    """
    t0 = time.perf_counter()
    row: dict[str, Any] = {"record": task.label, "task": task.id, "analysis": task.analysis}
    if task.point is not None:
        p = task.point
        row.update(design=p.name, seed_index=p.index, simulator=p.simulator)
    o = task.options
    row.update(model=o.get("model"), cost=o.get("cost") or "default", seed=task.seed)
    truths = dict(task.truths or {})
    row.update({f"true_{k}": float(v) for k, v in truths.items()})
    out = Outcome(row)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            record, velocity = _record(task, seed)
            row.update(record_hash=record.hash, n=record.n, dt=record.dt)
            if keep_record and task.point is not None:
                out.record = record
            rng = np.random.default_rng(child_seed(seed, 1))
            params, scalars, tree, checks, model = _RUN[task.analysis](
                record, o, rng, task.truths, posterior
            )
            row.update(status="ok", **scalars)
            _verdict(row, checks)
            for name, stats in params.items():
                row.update({f"{name}_{k}": v for k, v in stats.items()})
            if velocity is not None and "a1eq" in params:
                m = Model.from_spec([n for n in model if n in TERMS])  # the drift's terms
                theta = [truths.get(n, 0.0) for n in m.param_names]
                row["sigma_v"] = float(np.std(velocity))
                row["true_a1eq"] = float(m.equivalent_damping(theta, row["sigma_v"]))
            if posterior and tree is not None:
                out.posterior = _netcdf(tree)
        except RecordRejected as exc:
            row.update(status="rejected", message=_one_line(exc))
            _verdict(row, exc.checks)
        except Exception as exc:  # a failed task is a row of the table, not a crash
            row.update(status="error", verdict="", message=_one_line(exc))
    messages = sorted({f"{w.category.__name__}: {w.message}"[:200] for w in caught})
    if messages:
        row["warnings"] = " | ".join(messages)
    row["task_seconds"] = time.perf_counter() - t0
    return out
