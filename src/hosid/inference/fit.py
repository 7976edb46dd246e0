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

import json
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
from ..components.spectral import default_band
from ..errors import HosidInputError
from ..model.model import Model
from ..model.priors import PriorSet
from ..output.results import build_tree
from ..record import Record
from . import sampler as S
from .calibrate import calibrate
from .estimate import components_for, estimate, likelihood_map, log_params

__all__ = ["fit"]


def _rng(seed) -> np.random.Generator:
    if isinstance(seed, np.random.Generator):
        return seed
    return np.random.default_rng(np.random.SeedSequence(seed))


def _backend(path, n_walkers: int, p: int, signature: dict) -> emcee.backends.HDFBackend:
    """An HDF5 chain that remembers the record and settings it was run with."""
    import h5py

    be = emcee.backends.HDFBackend(str(path))
    text = json.dumps(signature, sort_keys=True)
    try:
        existing = be.iteration > 0
    except (OSError, KeyError, AttributeError):
        existing = False
    except Exception as exc:  # h5py raises its own errors on unreadable files
        raise HosidInputError(f"{path}: not a chain backend ({exc})") from None
    if existing:
        with h5py.File(path, "r") as f:
            stored = f[be.name].attrs.get("hosid_signature")
        if stored != text:
            raise HosidInputError(
                f"{path} holds a chain of another record or other settings; "
                "remove it or choose another --backend"
            )
        if be.shape != (n_walkers, p):
            raise HosidInputError(f"{path} holds {be.shape[0]} walkers x {be.shape[1]} params")
        return be
    try:
        be.reset(n_walkers, p)
        with h5py.File(path, "a") as f:
            f[be.name].attrs["hosid_signature"] = text
    except OSError as exc:
        raise HosidInputError(
            f"cannot use {path} as a chain backend (not writable, or not an HDF5 file): {exc}"
        ) from None
    return be


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
    progress: bool = True,
    backend: str | Path | None = None,
    truths: Mapping[str, float] | None = None,
    with_map: bool = True,
    start: str = "auto",
    unit: str = "m",
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
    progress : bool
        One labelled progress bar.
    backend : path, optional
        HDF5 chain to store or resume (same record and settings only).
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
    est = estimate(record, model, comps, block_seconds=block_seconds)
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
    modes = {
        "auto": [cal.theta, twin] if twin_ok else [cal.theta],
        "estimate": [cal.theta],
        "twin": [twin],
    }[start]
    be = None
    if backend is not None:
        signature = {
            "record": record.hash,
            "model": list(model.names),
            "cost": cost,
            "constrained": constrained,
            "block_seconds": est.state.layout.T,
            "omega_max": omega_max,
            "form": form,
            "domain": domain,
        }
        be = _backend(backend, n_walkers, len(names), signature)
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
        progress="sampling" if progress else False,
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
    obs = {"omega": bins * est.state.layout.d_omega, "Sxx": est.state.periodogram("x", bins)}
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
        "components": comp_names,
        "cost": cost or "default",
        "constrained": constrained,
        "sigma_v": est.sigma_v,
        "unit": unit,
        "state": est.state.describe(),
        "record_notes": est.notes,
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
            "moves": ("DE 0.7, DE(gamma=1) 0.1, KDE 0.2" if kde else "DE 0.9, DE(gamma=1) 0.1")
            + ("" if constrained else "; x0.9 and mirror 0.1"),
        },
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
