r"""One model checked against the record: fit it, simulate posterior-predictive
replicates, measure the gap (:func:`check_model`).

The replicates are simulated with :meth:`hosid.model.Model.simulate` at posterior
draws, one per seed of ``replicate_seeds`` (pass the same seeds for every model:
common random numbers).  A draw whose simulation escapes is replaced by the next one
on the same seed; a model with more than ``R/2`` escaping draws cannot produce a
stationary record like the observed one and gets an infinite gap.
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import xarray as xr

from ..errors import HosidInputError
from ..inference.estimate import estimate
from ..inference.fit import fit
from ..model.model import Model
from ..output.results import attr, stored_model
from ..record import Record
from .gaps import gaps, robust_z
from .measures import MeasureSpec, drift_function, measures
from .posterior import screen_sample, tree_sample

__all__ = ["ModelCheck", "check_model"]


@dataclass
class ModelCheck:
    """One model fitted to the record and its posterior-predictive gap.

    Attributes
    ----------
    model : Model
        The model checked.
    method : str
        ``"emcee"`` (:func:`hosid.inference.fit.fit`) or ``"screen"`` (estimate and
        importance-weighted draws, :func:`hosid.check.posterior.screen_sample`).
    theta_hat : dict
        The estimate (the mode of the quasi-likelihood); it sets the drift of the
        force and energy measures.
    hansen : dict
        Hansen's over-identification test at the estimate: ``J``, ``df``, ``p_value``.
    sample : ndarray, shape (S, p)
        Equally weighted posterior draws.
    draws : ndarray, shape (R, p)
        The draws the replicates were simulated at.
    gap : dict
        :func:`hosid.check.gaps.gaps` of the record against the replicates.
    record_measures, replicate_measures
        The measures of the record and of each replicate.
    seconds : float
        Wall time of the check.
    failed_replicates : int
        Draws whose simulation escaped.
    tree : xarray.DataTree or None
        The emcee fit (``method="emcee"`` only).
    replicates : list of Record
        The replicate records themselves (``keep_replicates=True`` only).
    info : dict
        Sampler numbers (``draws``; or ``ess``, ``proposals``, ``admissible``).
    """

    model: Model
    method: str
    theta_hat: dict[str, float]
    hansen: dict[str, float]
    sample: np.ndarray
    draws: np.ndarray
    gap: dict
    record_measures: dict[str, np.ndarray]
    replicate_measures: list[dict[str, np.ndarray]]
    seconds: float
    failed_replicates: int = 0
    tree: xr.DataTree | None = None
    info: dict = field(default_factory=dict)
    replicates: list[Record] = field(default_factory=list, repr=False)

    @property
    def total(self) -> float:
        """The total gap :math:`G` (infinite when the model's simulations diverge)."""
        return float(self.gap["total"])

    @property
    def diverged(self) -> bool:
        """Whether more draws escaped than half the number of replicates."""
        return not math.isfinite(self.total)

    @property
    def p_value(self) -> float:
        """The posterior-predictive rank p-value of :math:`G`."""
        return float(self.gap["p_value"])

    @property
    def z(self) -> float:
        """Robust standardization of :math:`G` by its leave-one-out null gaps."""
        return robust_z(self.total, self.gap["null"])

    def interval(self, prob: float = 0.9) -> dict[str, tuple[float, float]]:
        """Central posterior intervals of every parameter."""
        q = np.quantile(self.sample, [(1 - prob) / 2, (1 + prob) / 2], axis=0)
        return {n: (float(q[0, i]), float(q[1, i])) for i, n in enumerate(self.model.param_names)}

    def summary(self) -> dict[str, Any]:
        """Estimate, interval, Hansen test, gaps per measure and settings (report rows)."""
        return {
            "model": list(self.model.names),
            "method": self.method,
            "gap": self.total,
            "z": self.z,
            "p_value": self.p_value,
            "estimate": self.theta_hat,
            "interval90": self.interval(0.9),
            "hansen": self.hansen,
            "measures": self.gap["measures"],
            "null_gaps": np.asarray(self.gap["null"]).tolist(),
            "failed_replicates": self.failed_replicates,
            "seconds": self.seconds,
            **self.info,
        }


def _replicates(record, model, sample, seeds, spec, drift, rng, keep):
    """Measures of one replicate per seed, each at the next posterior draw that does
    not escape (and the records, with ``keep``); ``None`` when more than half as many
    draws escape as there are seeds.
    """
    order = rng.permutation(sample.shape[0])
    reps, used, failed, k, records = [], [], 0, 0, []
    R = len(seeds)
    for seed in seeds:
        sim = None
        while sim is None and failed <= R // 2 and k < order.size:
            theta = sample[order[k]]
            k += 1
            try:
                sim = model.simulate(
                    theta, duration=record.duration, dt=record.dt, rng=np.random.default_rng(seed)
                )
            except HosidInputError:  # the draw lets the response escape
                sim = None
            if sim is not None and not np.max(np.abs(sim.x)) < 1e6:
                sim = None
            if sim is None:
                failed += 1
        if sim is None:
            return None, np.array(used), failed, []
        if sim.n != record.n or record.n_segments > 1:  # the record's length and segments
            sim = Record(x=sim.x[: record.n], dt=sim.dt, segments=record.segments)
        reps.append(measures(sim, spec=spec, drift=drift))
        used.append(theta)
        if keep:
            records.append(sim)
    return reps, np.array(used), failed, records


def check_model(
    record: Record,
    model: Model | str,
    *,
    rng: np.random.Generator,
    replicate_seeds: Sequence[np.random.SeedSequence],
    spec: MeasureSpec | None = None,
    method: str = "emcee",
    keep_replicates: bool = False,
    settle: bool = True,
) -> ModelCheck:
    """Fit ``model`` and measure the record's gap from its posterior-predictive replicates.

    Parameters
    ----------
    record : Record
        The observed record.
    model : Model or str
        The model (or its spec, :meth:`hosid.model.Model.from_spec`).
    rng : numpy.random.Generator
        For the fit (or the screening draws) and the choice of posterior draws.
    replicate_seeds : sequence of SeedSequence
        One per replicate; pass the same seeds for every model (common random numbers).
    spec : MeasureSpec, optional
        The measures' layout; default from the record.
    method : {"emcee", "screen"}
        ``"emcee"``: :func:`hosid.inference.fit.fit` (its DataTree is kept in
        ``tree``); ``"screen"``: :func:`hosid.inference.estimate.estimate` and
        :func:`hosid.check.posterior.screen_sample` (module docstring).
    keep_replicates : bool
        Keep the replicate records (for the calibration of :mod:`hosid.check.selection`).
    settle : bool
        Settle the excitation against the record (:func:`hosid.inference.estimate.estimate`);
        false fits ``model`` as given.

    Returns
    -------
    ModelCheck

    Raises
    ------
    HosidInputError
        If the model cannot be estimated on the record.
    """
    t0 = time.perf_counter()
    model = Model.from_spec(model)
    spec = MeasureSpec.from_record(record) if spec is None else spec
    tree = None
    if method == "emcee":
        tree = fit(record, model=model, seed=rng, progress=False, settle=settle)
        model = stored_model(tree)  # with the excitation terms added
        theta_hat = dict(attr(tree, "estimate"))
        hansen = dict(attr(tree, "calibration")["hansen"])
        sample = tree_sample(tree, model)
        info: dict = {"draws": int(sample.shape[0])}
    elif method == "screen":
        est = estimate(record, model, simulations=0, settle=settle)
        model = est.model
        theta_hat, hansen = est.values, dict(est.test)
        sample, info = screen_sample(est, rng)
    else:
        raise HosidInputError(f"unknown method {method!r}: emcee or screen")
    drift = drift_function(theta_hat)
    obs = measures(record, spec=spec, drift=drift)
    reps, used, failed, records = _replicates(
        record, model, sample, replicate_seeds, spec, drift, rng, keep_replicates
    )
    if reps is not None:
        gap = gaps(obs, reps)
    else:  # more than half as many draws diverged as there are replicates
        gap = {
            "total": math.inf,
            "measures": dict.fromkeys(obs, math.inf),
            "z": {m: np.full(np.shape(v), np.inf) for m, v in obs.items()},
            "worst": "divergence",
            "null": np.array([np.nan]),
            "p_value": 0.0,
            "n_replicates": len(used),
        }
        reps = []
    return ModelCheck(
        model=model,
        method=method,
        theta_hat=theta_hat,
        hansen=hansen,
        sample=sample,
        draws=used,
        gap=gap,
        record_measures=obs,
        replicate_measures=reps,
        seconds=time.perf_counter() - t0,
        failed_replicates=failed,
        tree=tree,
        info=info,
        replicates=records,
    )
