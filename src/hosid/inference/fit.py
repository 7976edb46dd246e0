r"""The one entry point of an identification: :func:`fit`.

A fit is a term model (:class:`hosid.model.Model`), a list of likelihood components
(:func:`hosid.inference.estimate.components_for`) and priors, sampled by emcee:

.. math:: p(\theta\mid x) \propto \pi(\theta)\,\exp\ell_{cal}(\theta),

where :math:`\ell_{cal}` is the components' quasi-log-likelihood after calibration
(:mod:`hosid.inference.calibrate`) and :math:`\pi` the priors, with the eq-65
constraint :math:`a_{1eq} > 0` on every draw unless ``constrained=False``.  The result
is one arviz ``DataTree`` (:mod:`hosid.output.results`).
"""

from __future__ import annotations

import time
from collections.abc import Mapping, Sequence
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import emcee
import numpy as np
import xarray as xr

from .. import __version__
from ..components.base import Component
from ..components.spectral import default_band, force_periodogram
from ..errors import HosidInputError
from ..model.measured import shape_attrs
from ..model.model import Model
from ..model.priors import PriorSet
from ..output.results import build_tree
from ..progress import Stages
from ..record import Record
from ..verdicts import Check, convergence
from . import sampler as S
from .calibrate import calibrate
from .chains import ChainFile
from .estimate import components_for, estimate, likelihood_map, log_params

__all__ = ["fit"]


def _rng(seed) -> np.random.Generator:
    if isinstance(seed, np.random.Generator):
        return seed
    return np.random.default_rng(np.random.SeedSequence(seed))


def fit(
    record: Record,
    *,
    model: Model | str = "paper",
    cost: str | None = None,
    components: Sequence[Component] | None = None,
    constrained: bool = True,
    priors: PriorSet | None = None,
    block_seconds: float | None = None,
    omega_max: float | None = None,
    form: str = "scaled",
    domain: str = "principal",
    n_walkers: int = 32,
    n_steps: int | None = None,
    max_steps: int = 20000,
    seed: int | np.random.Generator | None = None,
    progress: bool | Stages = True,
    backend: str | Path | None = None,
    truths: Mapping[str, float] | None = None,
    with_map: bool = True,
    start: str = "auto",
    unit: str = "m",
    force: bool = False,
    checks: Sequence[Check] | None = None,
) -> xr.DataTree:
    r"""Sample the calibrated quasi-posterior of ``model`` given ``record``.

    Parameters
    ----------
    record : Record
    model : Model or str
        ``"paper"`` (default), ``"linear"`` or term names.
    cost : {None, "J2", "J4A", "J4B"}
        ``None``: the default, most efficient components; otherwise the paper's.
    components : sequence of components, optional
        Any combination instead of ``cost``'s, e.g. ``[Identities(), J2(), J3()]``
        (:mod:`hosid.components`).
    constrained : bool
        Keep the equivalent damping of eq (65) positive on every draw.
    priors : PriorSet, optional
        Default: every term's default prior (:meth:`Model.default_priors`).
    block_seconds, omega_max : float, optional
        Block length and upper edge of the J2 band; default derived from the record.
    form : {"scaled", "printed"}
        Weighting of the spectral components.
    domain : {"principal", "reduced", "full"}
        Trispectral domain of J4.
    n_walkers, n_steps, max_steps : int
        Ensemble size; a fixed number of steps, or the stop rule's limit.
    seed : int or Generator, optional
        The only source of randomness (walkers, moves, prior draws).
    progress : bool or Stages
        One labelled progress bar (a command passes its :class:`hosid.progress.Stages`).
    backend : path, optional
        HDF5 chain to store (after every chunk of steps and on Ctrl-C) or resume (same
        record and settings only; :class:`hosid.inference.chains.ChainFile`).
    truths : mapping, optional
        True values (simulated records), kept for plots.
    with_map : bool
        Evaluate the quasi-likelihood on an ``(a1, n1)`` grid for the contour plot.
    start : {"auto", "estimate", "twin"}
        Where the walkers start: ``"auto"`` around the estimate and, without the
        constraint, also around its mirror image (the twin mode of J2 and J4);
        ``"estimate"`` or ``"twin"`` only there (to verify that the posterior's modes and
        their weights do not depend on where the walkers start).
    unit : str
        The unit of the record's displacement (labels of the report).
    force : bool
        Fit a record that fails a check of :func:`hosid.screen.check_record` anyway (the
        failure stays in the ``checks`` attribute and the report).

    Raises
    ------
    RecordRejected
        If the record fails a check and ``force`` is false.
    HosidInputError
        On bad settings, or a record the model's equations cannot be solved for.
    """
    t0 = time.perf_counter()
    timings: dict[str, float] = {}
    model = Model.from_spec(model)
    if int(n_walkers) != n_walkers or n_walkers < 2 * len(model.param_names) + 2 or n_walkers % 2:
        raise HosidInputError(
            f"n_walkers must be even and at least {2 * len(model.param_names) + 2}, "
            f"got {n_walkers}"
        )
    rng = _rng(seed)
    band = None if omega_max is None else (0.0, float(omega_max))
    if components is None:
        comps = components_for(cost, band=band, form=form, domain=domain)
    else:
        comps = list(components)
        cost = cost or "custom"
    est = estimate(
        record, model, comps, block_seconds=block_seconds, force=force, unit=unit, checks=checks,
        progress=progress,
    )  # fmt: skip
    model = est.model  # with the excitation terms the record calls for (estimate docstring)
    timings["estimate"] = time.perf_counter() - t0
    if priors is None:
        priors = model.default_priors(est.scales(), constrained=constrained)
    elif priors.names != model.param_names:
        raise HosidInputError(f"priors must be for {', '.join(model.param_names)} in order")
    cal = calibrate(est)

    names = model.param_names
    comp_names = list(est.ql.slices)

    def log_prob(theta):
        lp = priors.ln_prob(theta)
        out = np.full((theta.shape[0], 2 + len(comp_names)), -np.inf)
        ok = np.isfinite(lp)
        out[:, -1] = lp
        if ok.any():
            parts = cal.by_component(theta[ok])
            ll = sum(parts.values())
            out[ok, 0] = lp[ok] + ll
            for i, c in enumerate(comp_names):
                out[ok, 1 + i] = parts[c]
        return out

    damping = [i for i, t in enumerate(model.drift_terms) if t.variable == "v"]
    twin = cal.theta.copy()
    twin[damping] *= -1.0
    twin_ok = not constrained and np.isfinite(log_prob(twin[None])[0, 0])
    if start not in ("auto", "estimate", "twin"):
        raise HosidInputError(f"unknown start {start!r}: auto, estimate or twin")
    if start == "twin" and not twin_ok:
        raise HosidInputError(
            "the twin mode is inadmissible (eq-65 constraint): use constrained=False"
        )
    alternatives = [t for t in est.alternatives if np.isfinite(log_prob(t[None])[0, 0])]
    modes = {
        "auto": [cal.theta, *alternatives, *([twin] if twin_ok else [])],
        "estimate": [cal.theta],
        "twin": [twin],
    }[start]
    be = None
    if backend is not None:
        signature = {
            "record": record.hash,
            "model": list(model.names),
            **shape_attrs(model),
            "cost": cost,
            "constrained": constrained,
            "block_seconds": est.state.layout.T,
            "omega_max": omega_max,
            "form": form,
            "domain": domain,
        }
        be = ChainFile(backend, signature, n_walkers, len(names))
    kde = cost is not None or not constrained  # the paper's valley and twin modes
    chain = S.run(
        log_prob,
        modes=modes,
        cov=cal.cov,
        log_params=log_params(model, priors),
        n_blobs=1 + len(comp_names),
        rng=rng,
        n_walkers=n_walkers,
        n_steps=n_steps,
        max_steps=max_steps,
        mirror=damping if not constrained else (),
        kde=kde,
        backend=be,
        progress=progress if isinstance(progress, Stages) else bool(progress) and "sampling",
    )
    timings["sampling"] = time.perf_counter() - t0 - sum(timings.values())

    th = chain.theta
    post = {n: th[:, :, i] for i, n in enumerate(names)}
    pri = priors.sample(rng, 2000)
    prior_group = {n: pri[None, :, i] for i, n in enumerate(names)}
    if len(damping) > 1 or (damping and model.drift_terms[damping[0]].params != ("a1",)):
        post["a1eq"] = model.equivalent_damping(th, est.sigma_v)
        prior_group["a1eq"] = model.equivalent_damping(pri, est.sigma_v)[None]

    def calibrated(theta):
        return sum(cal.by_component(theta).values())

    lmap = likelihood_map(est, th.reshape(-1, len(names)), calibrated) if with_map else None
    bins = est.state.layout.bins(*(band or default_band(est.state)), k_min=1)
    obs = {
        "omega": bins * est.state.layout.d_omega,
        "Sxx": est.state.periodogram("x", bins),
        "force": force_periodogram(est.state, model, cal.theta, bins),
    }
    attrs: dict[str, Any] = {
        "created_at": datetime.now(UTC).isoformat(),
        "inference_library": "emcee",
        "inference_library_version": emcee.__version__,
        "hosid_version": __version__,
        "record": record.name,
        "record_hash": record.hash,
        "duration": record.duration,
        "dt": record.dt,
        "model": list(model.names),
        **shape_attrs(model),
        "components": comp_names,
        "cost": cost or "default",
        "constrained": constrained,
        "sigma_v": est.sigma_v,
        "unit": unit,
        "state": est.state.describe(),
        "record_notes": est.notes,
        "excitation_test": est.excitation_test,
        "estimate": est.values,
        "pilot": model.params(est.pilot),
        "calibration": cal.describe(),
        "priors": priors.describe(),
        "settings": {
            "form": form,
            "domain": domain,
            "omega_max": omega_max,
            "block_seconds": est.state.layout.T,
            "seed": seed if isinstance(seed, int) else None,
        },
        "components_info": {m.component: m.info for m in est.ql.moments},
        "sampler": {
            "walkers": n_walkers,
            "steps": chain.steps,
            "burn_in": chain.burn,
            "autocorr_time": dict(zip(names, chain.autocorr.tolist(), strict=True)),
            "acceptance": chain.acceptance,
            **chain.diagnostics,
            "moves": ("DE 0.7, DE(gamma=1) 0.1, KDE 0.2" if kde else "DE 0.9, DE(gamma=1) 0.1")
            + ("" if constrained else "; x0.9 and mirror 0.1"),
        },
        "checks": [
            c.as_dict() for c in [*est.checks, cal.check(), convergence(chain.diagnostics)]
        ],
        "forced": force and any(c.status == "fail" for c in est.checks),
        "truths": dict(truths) if truths else None,
        "timings": timings,
        "fit_seconds": time.perf_counter() - t0,
    }
    return build_tree(
        posterior=post,
        sample_stats={"lp": chain.lp, "log_prior": chain.blobs[..., -1]},
        log_likelihood={c: chain.blobs[..., i] for i, c in enumerate(comp_names)},
        prior=prior_group,
        observed_data=obs,
        constant_data={"theta_hat": cal.theta, "laplace_cov": cal.cov},
        param_names=names,
        likelihood_map=lmap,
        attrs=attrs,
    )
