r"""The one entry point of an identification: :func:`fit`.

A fit is a description of what moved (a single oscillator's term model,
:class:`hosid.model.Model`, or a system of several degrees of freedom,
:class:`hosid.model.system.System`; the single oscillator is the one-element system), a
list of likelihood components (:func:`hosid.inference.estimate.components_for`) and
priors, sampled by emcee:

.. math:: p(\theta\mid x) \propto \pi(\theta)\,\exp\ell_{cal}(\theta),

where :math:`\ell_{cal}` is the components' quasi-log-likelihood after calibration
(:mod:`hosid.inference.calibrate`) and :math:`\pi` the priors, with the eq-65
constraint :math:`a_{1eq} > 0` on every draw (per damped element of a system) unless
``constrained=False``; under a second-order shaping filter the draws stay on the
estimate's side of the filter's swap with the oscillator (:mod:`hosid.inference.swap`).
The settings and their defaults are :class:`hosid.inference.options.FitOptions`; what
differs between a model and a system is :mod:`hosid.inference.structure`.  The result is
one arviz ``DataTree`` (:mod:`hosid.output.results`).
"""

from __future__ import annotations

import dataclasses
import time
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import emcee
import numpy as np
import xarray as xr

from .. import __version__
from ..errors import HosidInputError
from ..model.model import Model
from ..model.system import System
from ..output.results import build_tree
from ..progress import Stages
from ..record import Record
from ..verdicts import convergence
from . import sampler as S
from . import structure as St
from .calibrate import calibrate
from .chains import ChainFile
from .estimate import components_for, estimate, likelihood_map, log_params
from .options import FitOptions
from .swap import swap_guard

__all__ = ["FitOptions", "fit"]


def _rng(seed) -> np.random.Generator:
    if isinstance(seed, np.random.Generator):
        return seed
    return np.random.default_rng(np.random.SeedSequence(seed))


def fit(
    record: Record,
    system: System | str | Path | None = None,
    options: FitOptions | None = None,
    *,
    model: Model | str | None = None,
    **settings,
) -> xr.DataTree:
    r"""Sample the calibrated quasi-posterior of ``system`` (or ``model``) given ``record``.

    Parameters
    ----------
    record : Record
        One channel a dof of the system (the single oscillator's: one displacement).
    system : System or path, optional
        A system (or its TOML file, :mod:`hosid.model.system_file`); its parameters are
        named with their place, ``a1[ground-x1]``, ``mass[x2]``, ``S0[x1]``.
    options : FitOptions, optional
        The settings (default :class:`~hosid.inference.options.FitOptions`'s).
    model : Model or str, optional
        A single oscillator's model instead of a system: ``"paper"`` (the default),
        ``"linear"`` or term names.
    **settings
        Any field of :class:`~hosid.inference.options.FitOptions`, overriding ``options``
        (``seed``, ``cost``, ``n_walkers``, ``constrained``, ``start``, ...).  ``start``:
        ``"auto"`` starts the walkers around the estimate and, without the constraint,
        also around its mirror image (the twin mode of J2 and J4); ``"estimate"`` or
        ``"twin"`` only there.

    Raises
    ------
    RecordRejected
        If the record fails a check and ``force`` is false.
    HosidInputError
        On bad settings, or a record the equations cannot be solved for.
    TypeError
        For a setting that does not exist.
    """
    t0 = time.perf_counter()
    o = FitOptions.of(options, **settings)
    structure = St.resolve(system, model)
    walkers(o, structure)
    cost = o.cost
    if o.components is not None:
        comps, cost = list(o.components), o.cost or "custom"
    elif isinstance(structure, System):
        from .system_estimate import system_components

        system_components(o.cost)  # a cost other than the default is refused
        comps = None  # the estimate chooses: the record may call for the sensors' noise
    else:
        band = None if o.omega_max is None else (0.0, float(o.omega_max))
        comps = components_for(o.cost, band=band, form=o.form, domain=o.domain)
    est = estimate(
        record, structure, comps, block_seconds=o.block_seconds, force=o.force, unit=o.unit,
        checks=o.checks, progress=o.progress, support=o.priors, settle=o.settle,
    )  # fmt: skip
    if est.model.param_names != structure.param_names:  # terms the record called for
        walkers(o, est.model, added=len(est.model.param_names) - len(structure.param_names))
    structure = est.model
    o = FitOptions.of(o, n_walkers=o.n_walkers or max(32, 2 * len(structure.param_names) + 2))
    timings = {"estimate": time.perf_counter() - t0}
    priors = o.priors
    if priors is None:
        priors = structure.default_priors(est.scales(), constrained=o.constrained)
    elif priors.names != structure.param_names:
        raise HosidInputError(f"priors must be for {', '.join(structure.param_names)} in order")
    est = _floored(est, priors, o)
    cal = calibrate(est)
    chain, rng, kde = _sample(record, est, cal, priors, o, cost)
    timings["sampling"] = time.perf_counter() - t0 - sum(timings.values())
    names = structure.param_names
    th = chain.theta
    post = {n: th[:, :, i] for i, n in enumerate(names)}
    pri = priors.sample(rng, 2000)
    prior_group = {n: pri[None, :, i] for i, n in enumerate(names)}
    post.update(St.derived(structure, th, est.sigma_v))
    prior_group.update({k: v[None] for k, v in St.derived(structure, pri, est.sigma_v).items()})

    def calibrated(theta):
        return sum(cal.by_component(theta).values())

    flat = th.reshape(-1, len(names))
    lmap = likelihood_map(est, flat, calibrated) if o.with_map else None
    attrs = _attrs(record, est, cal, priors, chain, o, cost, kde)
    attrs.update(St.modal(est, th))
    attrs["timings"] = timings
    attrs["fit_seconds"] = time.perf_counter() - t0
    comp_names = list(est.ql.slices)
    return build_tree(
        posterior=post,
        sample_stats={"lp": chain.lp, "log_prior": chain.blobs[..., -1]},
        log_likelihood={c: chain.blobs[..., i] for i, c in enumerate(comp_names)},
        prior=prior_group,
        observed_data=St.observed(est, cal.theta, o.omega_max),
        constant_data={"theta_hat": cal.theta, "laplace_cov": cal.cov},
        param_names=names,
        likelihood_map=lmap,
        attrs=attrs,
    )


def _sample(record: Record, est, cal, priors, o: FitOptions, cost):
    """The emcee run of the calibrated quasi-posterior: the chain, the generator (its
    prior draws follow) and whether the KDE move was used.
    """
    structure = est.model
    names = structure.param_names
    comp_names = list(est.ql.slices)
    rng = _rng(o.seed)

    guard = swap_guard(est)  # a shaping filter: the estimate's side of the swap
    if guard is not None and not guard(cal.theta[None])[0]:
        guard = None  # the calibrated mode itself outside: no side to keep

    def log_prob(theta):
        lp = priors.ln_prob(theta)
        out = np.full((theta.shape[0], 2 + len(comp_names)), -np.inf)
        ok = np.isfinite(lp)
        if guard is not None and ok.any():
            ok[ok] = guard(theta[ok])
        out[:, -1] = lp
        if ok.any():
            parts = cal.by_component(theta[ok])
            ll = sum(parts.values())
            out[ok, 0] = lp[ok] + ll
            for i, c in enumerate(comp_names):
                out[ok, 1 + i] = parts[c]
        return out

    damping = St.damping_columns(structure)
    twin = cal.theta.copy()
    twin[damping] *= -1.0
    twin_ok = not o.constrained and np.isfinite(log_prob(twin[None])[0, 0])
    if o.start not in ("auto", "estimate", "twin"):
        raise HosidInputError(f"unknown start {o.start!r}: auto, estimate or twin")
    if o.start == "twin" and not twin_ok:
        raise HosidInputError(
            "the twin mode is inadmissible (eq-65 constraint): use constrained=False"
        )
    alternatives = [t for t in est.alternatives if np.isfinite(log_prob(t[None])[0, 0])]
    modes = {
        "auto": [cal.theta, *alternatives, *([twin] if twin_ok else [])],
        "estimate": [cal.theta],
        "twin": [twin],
    }[o.start]
    be = None
    if o.backend is not None:
        signature = {
            "record": record.hash,
            **St.describe(structure),
            "cost": cost,
            "constrained": o.constrained,
            "block_seconds": est.state.layout.T,
            "omega_max": o.omega_max,
            "form": o.form,
            "domain": o.domain,
        }
        be = ChainFile(o.backend, signature, o.n_walkers, len(names))
    kde = cost is not None or not o.constrained  # the paper's valley and twin modes
    progress = o.progress
    try:
        chain = S.run(
            log_prob,
            modes=modes,
            cov=cal.cov,
            log_params=log_params(structure, priors),
            n_blobs=1 + len(comp_names),
            rng=rng,
            n_walkers=o.n_walkers,
            n_steps=o.n_steps,
            max_steps=o.max_steps,
            mirror=damping if not o.constrained else (),
            kde=kde,
            backend=be,
            progress=progress if isinstance(progress, Stages) else bool(progress) and "sampling",
        )
    except HosidInputError as exc:
        if "no admissible starting point" not in str(exc):
            raise
        raise HosidInputError(f"{exc} ({_outside(priors, names, cal.theta)})") from None
    return chain, rng, kde


def _floored(est, priors, o: FitOptions):
    """``est``, or, when it breaks eq (65) and is a linear system's spectral-matrix maximum
    (Whittle's likelihood hardly sees the dampers' sign:
    :func:`~hosid.inference.spectral_pilot.damping_floor`), the maximum searched again with
    every damper's coefficient at least 0, from the same state (the record is not read
    again), so that the constrained fit has an admissible start.
    """
    from ..components.chain_spectral_matrix import ChainSpectralMatrix
    from .system_estimate import estimate_system

    spectral = any(m.component == ChainSpectralMatrix.name for m in est.ql.moments)
    if not (spectral and o.constrained) or np.isfinite(priors.ln_prob(est.theta[None])[0]):
        return est
    got = estimate_system(est.state, est.model, checks=est.checks, support=o.priors, floor=True)
    note = ("Whittle's maximum puts a damper below zero (eq 65): the fit starts from its "
            "maximum with every damper's coefficient at least 0")  # fmt: skip
    return dataclasses.replace(got, notes=[*got.notes, note])


def walkers(o: FitOptions, structure, added: int = 0) -> None:
    """Raise unless ``o.n_walkers`` (if given) is even and at least twice the parameters
    plus 2 (emcee's stretch move needs it); ``added`` parameters came from the record.
    """
    n_min = 2 * len(structure.param_names) + 2
    if o.n_walkers is None:
        return
    if int(o.n_walkers) != o.n_walkers or o.n_walkers < n_min or o.n_walkers % 2:
        why = f" (the record added {added} parameters)" if added else ""
        raise HosidInputError(
            f"n_walkers must be even and at least {n_min}{why}, got {o.n_walkers}"
        )


def _outside(priors, names, theta) -> str:
    """Which parameters of ``theta`` are at or beyond their prior's support and which
    constraints it breaks, in words.
    """
    out = []
    for n, v in zip(names, theta, strict=True):
        p = priors[n]
        lo, hi = float(p.lower), float(p.upper)
        tol = 1e-6 * (hi - lo if np.isfinite(hi - lo) else max(abs(v), 1.0))
        if v <= lo + tol or v >= hi - tol:
            out.append(f"{n} = {v:.4g} at the edge of [{lo:.4g}, {hi:.4g}]")
    for c, f in priors.constraints.items():
        val = float(np.asarray(f(theta[None]))[0])
        if not val > 0:
            out.append(f"{c} = {val:.4g} <= 0")
    return "; ".join(out) or "no bound or constraint is met exactly"


def _attrs(record: Record, est, cal, priors, chain, o: FitOptions, cost, kde) -> dict[str, Any]:
    """The fit's root attributes (:mod:`hosid.output.results`)."""
    structure = est.model
    names = structure.param_names
    return {
        "created_at": datetime.now(UTC).isoformat(),
        "inference_library": "emcee",
        "inference_library_version": emcee.__version__,
        "hosid_version": __version__,
        "record": record.name,
        "record_hash": record.hash,
        "duration": record.duration,
        "dt": record.dt,
        **St.describe(structure),
        "components": list(est.ql.slices),
        "cost": cost or "default",
        "constrained": o.constrained,
        "sigma_v": est.sigma_v,
        "unit": o.unit,
        "state": est.state.describe(),
        "record_notes": est.notes,
        "excitation_test": est.excitation_test,
        "estimate": est.values,
        "pilot": structure.params(est.pilot),
        "calibration": cal.describe(),
        "priors": priors.describe(),
        "settings": {
            "form": o.form,
            "domain": o.domain,
            "omega_max": o.omega_max,
            "block_seconds": est.state.layout.T,
            "seed": o.seed if isinstance(o.seed, int) else None,
        },
        "components_info": {m.component: m.info for m in est.ql.moments},
        "sampler": {
            "walkers": o.n_walkers,
            "steps": chain.steps,
            "burn_in": chain.burn,
            "autocorr_time": dict(zip(names, chain.autocorr.tolist(), strict=True)),
            "acceptance": chain.acceptance,
            **chain.diagnostics,
            "moves": ("DE 0.7, DE(gamma=1) 0.1, KDE 0.2" if kde else "DE 0.9, DE(gamma=1) 0.1")
            + ("" if o.constrained else "; x0.9 and mirror 0.1"),
        },
        "checks": [
            c.as_dict() for c in [*est.checks, cal.check(), convergence(chain.diagnostics)]
        ],
        "forced": o.force and any(c.status == "fail" for c in est.checks),
        "truths": dict(o.truths) if o.truths else None,
    }
