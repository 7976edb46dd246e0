r"""Sampling pseudo-posteriors with emcee: :func:`fit`.

The pseudo-posterior of a cost (:mod:`hosid.likelihood`) is

.. math:: p(\theta\mid x) \propto \pi(\theta)\,
    \exp\Big(-\frac{1}{2\tau}\sum_c w_c J_c(\theta)\Big),

with priors :math:`\pi` (:mod:`hosid.priors`, the eq-65 constraint
:math:`a_1 + n_1\sqrt{8/\pi}\sigma_{\dot x} > 0` on by default) and the
temperature :math:`\tau` calibrated by parametric bootstrap
(:mod:`hosid.calibrate`).

Steps of :func:`fit`:

1. block spectra, moment batches and :math:`\sigma_{\dot x}` of the record;
2. a global search: the paper's protocol (:func:`hosid.estimators.estimate`),
   a scan along the line of constant equivalent damping, then a bounded local
   search of the summed cost; without the constraint the same is done from the
   mirrored start at negative damping, so that both twin modes are found;
3. the temperature (unless given);
4. emcee with differential-evolution moves (including :math:`\gamma = 1` jumps
   between modes) and snooker moves (unconstrained: also a mirror move
   :math:`(a_1, n_1)\to(-a_1,-n_1)` that carries walkers between the twin modes),
   walkers started around the mode(s),
   run in chunks of 250 steps until, after a burn-in of three autocorrelation
   times :math:`\hat t`, at least ``50 t`` steps are kept and the diagnostics the
   summary reports pass with a margin (rank-normalized R-hat over walkers < 1.007,
   bulk and tail ESS >= 500), or ``max_steps`` is reached;
5. an arviz ``DataTree`` (:mod:`hosid.results`) with the cost map for the plots.

The well-scaled costs are centred U-statistics: far from the data's answer they
can reward very dispersed inferred forces.  The default priors therefore bound
an *admissible region* built from the protocol estimate (equivalent damping and
:math:`S_0` within a factor 2.5, stiffness within 50 %); it is stored with the
result, and a warning is issued if posterior mass piles up at its edge.
"""

from __future__ import annotations

import copy
import math
import time
import warnings
from collections.abc import Mapping

import emcee
import numpy as np
import xarray as xr
from scipy import optimize

from . import costs as C
from . import estimators as E
from .calibrate import calibrate
from .errors import HosidInputError
from .likelihood import PseudoLikelihood, components_for, moment_data
from .priors import LogUniform, PriorSet, Uniform
from .records import Record, check_blocks
from .results import build_tree
from .spectra import block_spectra, derivatives

__all__ = ["admissible_priors", "fit", "prepare_likelihood"]

#: Stop rule margins over the summary's thresholds (R-hat < 1.01, ESS >= 400).
RHAT_STOP = 1.007
ESS_STOP = 500.0
#: At least this many autocorrelation times are kept after burn-in.
MIN_KEPT_TAU = 50


def _diagnostics_pass(chain: np.ndarray) -> bool:
    """R-hat and bulk/tail ESS of every parameter (walkers as chains) within the margins."""
    import arviz as az

    if chain.shape[0] < 20:
        return False
    post = xr.Dataset(
        {f"p{i}": (("chain", "draw"), chain[:, :, i].T) for i in range(chain.shape[2])}
    )
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        rhat = az.rhat(post)
        bulk = az.ess(post, method="bulk")
        tail = az.ess(post, method="tail")
    return all(
        float(rhat[k]) < RHAT_STOP and float(bulk[k]) >= ESS_STOP and float(tail[k]) >= ESS_STOP
        for k in post.data_vars
    )


NAMES = C.PARAM_NAMES


class AdmissibleRegionWarning(UserWarning):
    """Posterior mass at the edge of the admissible region."""


def prepare_likelihood(
    record: Record,
    *,
    cost: str = "J4A",
    form: str = "scaled",
    window: str = "hann",
    block_seconds: float = 20.48,
    omega_max: float = 8.0,
    domain: str = "principal",
) -> tuple[PseudoLikelihood, float]:
    """The record's untempered pseudo-likelihood and its velocity RMS."""
    components_for(cost, form)  # validates
    M = round(block_seconds / record.dt)
    check_blocks(record, M)
    sp = block_spectra(record, window=window, block_seconds=block_seconds, omega_max=omega_max)
    data = C.prepare(sp, domain)
    x = record.x - np.mean(record.x)
    v = derivatives(x, record.dt)[0]
    tail = E.velocity_tail(record)
    md = moment_data(record, batch_samples=sp.M, velocity=v, tail=tail)
    sigma_v = float(np.sqrt(np.mean(v**2) + tail))
    return PseudoLikelihood(data, md, cost=cost, form=form), sigma_v


def admissible_priors(
    start: Mapping[str, float], sigma_v: float, *, constrained: bool
) -> PriorSet:
    """Default priors: uniform boxes around a protocol estimate (module doc).

    ``|a1eq|`` and ``S0`` within a factor 2.5 of the estimate, ``a1`` and
    ``n1`` each able to carry 2.5 times the equivalent damping on its own, and
    ``a2``, ``n2`` within 50 % (plus a small absolute margin).  Damping is
    *sign-consistent*: ``a1`` and ``n1`` share the sign of ``a1eq`` (both
    mechanisms dissipate, or, for the mirrored twin, both feed energy), which
    keeps the negative-damping twin inside when unconstrained and excludes
    the far, strongly cancelling combinations (large ``a1`` with negative
    ``n1``) where the centred costs reward very dispersed inferred forces.
    """
    c = E.SQRT_8_PI * sigma_v
    a1eq = abs(start["a1"] + start["n1"] * c)
    S0 = start["S0"]

    def around(v, rel, pad):
        w = rel * abs(v) + pad
        return Uniform(v - w, v + w)

    priors = {
        "a1": Uniform(-2.5 * a1eq, 2.5 * a1eq),
        "n1": Uniform(-2.5 * a1eq / c, 2.5 * a1eq / c),
        "a2": around(start["a2"], 0.5, 1.0),
        "n2": around(start["n2"], 0.5, 0.5),
        "S0": LogUniform(S0 / 2.5, S0 * 2.5),
    }
    ps = PriorSet(priors, sigma_v=sigma_v, constrained=constrained)
    ps.a1eq_range = (a1eq / 2.5, a1eq * 2.5)
    ps.sign_consistent = True
    return ps


def _log_prior(priors: PriorSet, theta: np.ndarray) -> np.ndarray:
    lp = priors.ln_prob(theta)
    rng_ = getattr(priors, "a1eq_range", None)
    if rng_ is not None:
        q = np.abs(priors.a1eq(theta))
        lp = np.where((q >= rng_[0]) & (q <= rng_[1]), lp, -np.inf)
    if getattr(priors, "sign_consistent", False):
        a1, n1 = theta[..., 0], theta[..., 1]
        same = ((a1 >= 0) & (n1 >= 0)) | ((a1 <= 0) & (n1 <= 0))
        lp = np.where(same, lp, -np.inf)
    return lp


def _scales(priors: PriorSet) -> np.ndarray:
    out = []
    for p in priors.values():
        lo, hi = p.lower, p.upper
        out.append((hi - lo) / 100 if np.isfinite(hi - lo) else 1.0)
    return np.array(out)


def _mode(objective, start: np.ndarray, scale: np.ndarray) -> np.ndarray:
    """Minimize ``objective`` (vectorized, inf outside) from ``start``."""

    def f(u):
        return float(objective((start + u * scale)[None])[0])

    with warnings.catch_warnings(), np.errstate(invalid="ignore", over="ignore"):
        # the objective is +inf outside the admissible region; scipy's line
        # searches warn about inf arithmetic there, harmlessly
        warnings.simplefilter("ignore", RuntimeWarning)
        return _minimize(f, start, scale)


def _minimize(f, start, scale):
    best = optimize.minimize(
        f,
        np.zeros(start.size),
        method="Nelder-Mead",
        options={"xatol": 1e-3, "fatol": 1e-4, "maxfev": 3000, "adaptive": True},
    )
    best = optimize.minimize(f, best.x, method="Powell", options={"xtol": 1e-4, "ftol": 1e-8})
    return start + best.x * scale


def _global_search(pl: PseudoLikelihood, priors: PriorSet, start: np.ndarray, sigma_v: float):
    """Scan the eq-65 line from ``start``, then refine locally; returns the mode."""
    c = E.SQRT_8_PI * sigma_v
    a1eq = start[0] + start[1] * c
    n1 = np.linspace(-0.5, 1.5, 41) * a1eq / c
    line = np.repeat(start[None], n1.size, axis=0)
    line[:, 0] = a1eq - n1 * c
    line[:, 1] = n1

    def objective(th):
        lp = _log_prior(priors, th)
        out = np.full(th.shape[0], np.inf)
        ok = np.isfinite(lp)
        if ok.any():
            out[ok] = pl.total_cost(th[ok])
        return out

    J = objective(line)
    if not np.isfinite(J).any():
        raise HosidInputError("no admissible starting point: check the priors")
    scale = _scales(priors)
    return _mode(objective, line[np.argmin(J)], scale)


def _tau_max(tau: np.ndarray, n_steps: int) -> float:
    """Largest autocorrelation time; a parameter whose estimate is not finite (a
    chain too short or stuck) counts as ``n_steps / 10`` (emcee's reliability bound).
    """
    tau = np.where(np.isfinite(tau), tau, max(n_steps / 10, 1.0))
    return float(np.max(tau))


def _mirror(coords: np.ndarray, random) -> tuple[np.ndarray, np.ndarray]:
    r"""Twin-mode move: each walker proposes :math:`(a_1, n_1) \to (-a_1, -n_1)`
    with probability 1/2.  The map is an involution with unit Jacobian, so the
    Metropolis-Hastings ratio is the posterior ratio alone; between the mirrored
    minima of J2 and J4 it is close to 1, so walkers cross between the modes.
    """
    q = coords.copy()
    flip = random.rand(q.shape[0]) < 0.5
    q[flip, :2] *= -1.0
    return q, np.zeros(q.shape[0])


def _initial_walkers(rng, modes, cov, priors, n_walkers):
    """Walkers drawn around the modes (split evenly), inside the prior support."""
    out = []
    per = np.array_split(np.arange(n_walkers), len(modes))
    for mode, idx in zip(modes, per, strict=True):
        got = np.empty((0, mode.size))
        spread = 0.2
        while got.shape[0] < idx.size:
            draw = rng.multivariate_normal(mode, spread**2 * cov, size=4 * idx.size)
            got = np.concatenate([got, draw[np.isfinite(_log_prior(priors, draw))]])
            spread *= 0.7
        out.append(got[: idx.size])
    return np.concatenate(out)


def fit(
    record: Record,
    *,
    cost: str = "J4A",
    form: str = "scaled",
    constrained: bool = True,
    priors: PriorSet | None = None,
    n_walkers: int = 16,
    n_steps: int | None = None,
    max_steps: int = 6000,
    seed: int | np.random.Generator | None = None,
    temperature: float | None = None,
    n_bootstrap: int = 30,
    progress: bool = True,
    backend: str | None = None,
    truths: Mapping[str, float] | None = None,
    window: str = "hann",
    block_seconds: float = 20.48,
    omega_max: float = 8.0,
    domain: str = "principal",
    cost_map: bool = True,
) -> xr.DataTree:
    r"""Sample the pseudo-posterior of a cost with emcee (module doc).

    Parameters
    ----------
    record : Record
    cost : {"J2", "J4A", "J4B"}
        Which pseudo-likelihood (see :mod:`hosid.likelihood`).
    form : {"scaled", "literal"}
    constrained : bool
        Apply the eq-65 constraint :math:`a_{1eq} > 0` (default).
    priors : PriorSet, optional
        Default: :func:`admissible_priors` around the protocol estimate.
    n_walkers : int
        Ensemble size (even, at least twice the number of parameters).
    n_steps : int, optional
        Fixed number of steps; by default the run stops when the autocorrelation
        criteria are met (module doc) or at ``max_steps``.
    seed : int or Generator, optional
        Seeds the walkers, the moves and the calibration bootstrap.
    temperature : float, optional
        Fix :math:`\\tau` instead of calibrating it.
    n_bootstrap : int
        Bootstrap records for the calibration.
    progress : bool
        Progress bars (tqdm).
    backend : str, optional
        HDF5 file for the chain (:class:`emcee.backends.HDFBackend`); an existing
        file with samples is resumed.
    truths : mapping, optional
        True values (simulated data), stored for plots.
    window, block_seconds, omega_max, domain
        Spectral settings.
    cost_map : bool
        Evaluate the cost on an (a1, n1) grid for the contour plot.

    Returns
    -------
    xarray.DataTree
        Layout of :mod:`hosid.results`.
    """
    t0 = time.perf_counter()
    p = len(NAMES)
    if isinstance(n_walkers, bool) or int(n_walkers) != n_walkers or n_walkers < 2 * p:
        raise HosidInputError(f"n_walkers must be an integer >= {2 * p}, got {n_walkers!r}")
    if n_walkers % 2:
        raise HosidInputError(f"n_walkers must be even, got {n_walkers}")
    if n_steps is not None and (int(n_steps) != n_steps or n_steps < 1):
        raise HosidInputError(f"n_steps must be a positive integer, got {n_steps!r}")
    rng = seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)
    spec = {
        "window": window,
        "block_seconds": block_seconds,
        "omega_max": omega_max,
        "domain": domain,
    }
    pl, sigma_v = prepare_likelihood(record, cost=cost, form=form, **spec)
    proto = E.estimate(record, method="paper", **spec)["estimates"]
    start = np.array([proto[k] for k in NAMES])
    if priors is None:
        priors = admissible_priors(proto, sigma_v, constrained=constrained)
    elif priors.names != NAMES:
        raise HosidInputError(f"priors must be for {', '.join(NAMES)} in that order")

    timings = {"protocol": time.perf_counter() - t0}
    # --- cut: the spectral components use the moment stiffness (paper protocol)
    c_eq = E.SQRT_8_PI * sigma_v
    a1eq_typ = max(abs(start[0] + start[1] * c_eq), 1e-3)
    damping_scale = (2.5 * a1eq_typ, 2.5 * a1eq_typ / c_eq)
    pl = pl.with_(stiffness=(proto["a2"], proto["n2"]), damping_scale=damping_scale)

    # --- global search and mode(s)
    if not np.isfinite(_log_prior(priors, start[None]))[0]:
        start = priors.sample(rng, 1)[0]
    mode = _global_search(pl, priors, start, sigma_v)
    modes = [mode]
    if not constrained:
        twin = start.copy()
        twin[:2] = -start[:2]
        twin_mode = _global_search(pl, priors, twin, sigma_v)
        if np.sign(priors.a1eq(twin_mode)) != np.sign(priors.a1eq(mode)):
            modes.append(twin_mode)

    timings["search"] = time.perf_counter() - t0 - sum(timings.values())
    # --- temperatures of the spectral components, calibrated in the coordinates
    # (a1eq, n1, S0) (J2 alone: (a1eq, S0), n1 held at the mode)
    scale = _scales(priors)
    calib = None
    coords = ("a1eq", "S0") if cost == "J2" else ("a1eq", "n1", "S0")
    t_hat = np.array([mode[0] + mode[1] * c_eq, *([mode[1]] if cost != "J2" else []), mode[4]])
    t_scale = np.array([scale[0], *([scale[1]] if cost != "J2" else []), scale[4]])

    def embed(t, base=mode):
        t = np.atleast_2d(t)
        th = np.repeat(base[None], t.shape[0], axis=0)
        n1 = t[:, 1] if t.shape[1] == 3 else base[1]
        th[:, 1] = n1
        th[:, 0] = t[:, 0] - n1 * c_eq
        th[:, 4] = t[:, -1]
        return th

    def spectral(q):
        return lambda t: q.raw(embed(t), spectral_only=True)

    if temperature is None:
        params = dict(zip(NAMES, map(float, mode), strict=True))

        # the bootstrap estimator searches the admissible box without the
        # sign-consistency of a1 and n1: that is prior information, and the
        # temperature must measure what the data alone determine
        sign_free = copy.copy(priors)
        sign_free.sign_consistent = False

        def admissible(fn):
            def inner(t):
                out = fn(t)
                bad = ~np.isfinite(_log_prior(sign_free, embed(t)))
                return {k: np.where(bad, np.inf, v) for k, v in out.items()}

            return inner

        def make_components(rec):
            q, _ = prepare_likelihood(rec, cost=cost, form=form, **spec)
            st = E.moments(rec, damping=(mode[0], mode[1]))
            cut = q.with_(stiffness=(st["a2"], st["n2"]), damping_scale=damping_scale)
            return admissible(spectral(cut))

        calib = calibrate(
            spectral(pl),
            make_components,
            t_hat,
            params,
            duration=record.duration,
            dt=record.dt,
            scale=t_scale,
            n_bootstrap=n_bootstrap,
            rng=rng,
            progress=progress,
            coordinates=coords,
        )
        temperature = calib.temperatures
    pl = pl.with_(temperature=temperature)

    timings["calibration"] = time.perf_counter() - t0 - sum(timings.values())

    # --- emcee
    def log_prob(th):
        th = np.atleast_2d(th)
        lp = _log_prior(priors, th)
        ok = np.isfinite(lp)
        comps = {c: np.full(th.shape[0], -np.inf) for c in pl.components}
        if ok.any():
            for c, v in pl.pointwise(th[ok]).items():
                comps[c][ok] = v
        ll = sum(comps.values())
        total = np.where(ok, lp + ll, -np.inf)
        total = np.where(np.isnan(total), -np.inf, total)
        return np.column_stack([total, *comps.values(), lp])

    cov = np.diag(scale**2)
    if calib is not None:
        St = np.linalg.pinv(calib.hessian)  # tempered posterior covariance in t
        idx = [0, 1, 4] if len(coords) == 3 else [0, 4]
        Jac = np.eye(len(coords))
        if len(coords) == 3:
            Jac[0, 1] = -c_eq  # a1 = a1eq - c n1
        cov[np.ix_(idx, idx)] = Jac @ St @ Jac.T
    cov = 0.5 * (cov + cov.T)
    w, U = np.linalg.eigh(cov)
    cov = (U * np.clip(w, 1e-12 * max(w.max(), 1e-300), None)) @ U.T
    moves = [
        (emcee.moves.DEMove(), 0.7),
        (emcee.moves.DEMove(gamma0=1.0), 0.1),
        (emcee.moves.DESnookerMove(), 0.2),
    ]
    if not constrained:
        moves = [(m, 0.9 * w) for m, w in moves] + [(emcee.moves.MHMove(_mirror), 0.1)]
    be = None
    initial = None
    if backend is not None:
        be = emcee.backends.HDFBackend(str(backend))
        try:
            resume = be.iteration > 0
        except (OSError, KeyError, AttributeError):
            resume = False
        if resume:
            if be.shape != (n_walkers, p):
                raise HosidInputError(
                    f"backend {backend} holds {be.shape[0]} walkers x {be.shape[1]} parameters; "
                    f"asked for {n_walkers} x {p}"
                )
        else:
            be.reset(n_walkers, p)
    if be is None or be.iteration == 0:
        initial = _initial_walkers(rng, modes, cov, priors, n_walkers)
    sampler = emcee.EnsembleSampler(
        n_walkers,
        p,
        log_prob,
        moves=moves,
        vectorize=True,
        backend=be,
    )
    sampler._random = np.random.mtrand.RandomState(int(rng.integers(2**32 - 1)))
    chunk = 250
    tau_max = np.nan
    state = initial
    if n_steps is not None:
        sampler.run_mcmc(state, int(n_steps), progress=progress)
    else:
        done = sampler.iteration
        while done < max_steps:
            state = sampler.run_mcmc(
                state if sampler.iteration == 0 else None, chunk, progress=progress
            )
            state = None
            done = sampler.iteration
            tau = sampler.get_autocorr_time(tol=0, discard=done // 5)
            tau_max = _tau_max(tau, done)
            burn = math.ceil(3 * tau_max)
            if done - burn >= MIN_KEPT_TAU * tau_max and _diagnostics_pass(
                sampler.get_chain(discard=burn)
            ):
                break
    n_done = sampler.iteration
    tau = sampler.get_autocorr_time(tol=0, discard=n_done // 5)
    tau_max = _tau_max(tau, n_done)
    burn = min(math.ceil(3 * tau_max), n_done // 2)
    chain = sampler.get_chain(discard=burn)  # (draw, walker, p)
    blobs = sampler.get_blobs(discard=burn)  # (draw, walker, k)
    lp_chain = sampler.get_log_prob(discard=burn)

    post = {k: chain[:, :, i].T for i, k in enumerate(NAMES)}
    post["a1eq"] = post["a1"] + post["n1"] * E.SQRT_8_PI * sigma_v
    blobs = np.asarray(blobs, dtype=float)
    ll = {c: blobs[:, :, i].T for i, c in enumerate(pl.components)}
    stats = {"lp": lp_chain.T, "log_prior": blobs[:, :, -1].T}

    med = np.array([np.median(post[k]) for k in NAMES])
    cmap = _cost_map(pl, priors, post, med) if cost_map else None
    _edge_check(priors, chain.reshape(-1, p))
    obs = _observed(pl, med)
    settings = {
        "window": window,
        "block_seconds": block_seconds,
        "omega_max": omega_max,
        "domain": domain,
        "form": form,
        "n_walkers": n_walkers,
        "n_steps": n_done,
        "burn_in": burn,
        "autocorr_time": [float(t) for t in tau],
        "components": list(pl.components),
        "weights": pl.weights,
        "moves": "DE 0.7, DE(gamma=1) 0.1, DE snooker 0.2"
        + ("" if constrained else ", all x 0.9, mirror (a1, n1) -> (-a1, -n1) 0.1"),
        "priors": {k: repr(v) for k, v in priors.items()},
        "a1eq_range": list(getattr(priors, "a1eq_range", ()) or []),
        "protocol_start": {k: float(proto[k]) for k in NAMES},
        "mode": dict(zip(NAMES, map(float, mode), strict=True)),
    }
    attrs = {
        "cost": cost,
        "constrained": bool(constrained),
        "temperature": float(max(pl.temperatures.values())),
        "temperatures": pl.temperatures,
        "sigma_v": sigma_v,
        "x_max": float(np.max(np.abs(record.x - np.mean(record.x)))),
        "record": record.name or "",
        "duration": float(record.duration),
        "fit_seconds": time.perf_counter() - t0,
        "timings": {**timings, "sampling": time.perf_counter() - t0 - sum(timings.values())},
        "settings": settings,
        "truths": dict(truths) if truths else None,
        "calibration": calib.as_dict()
        if calib is not None
        else {"temperature": temperature, "method": "given"},
    }
    return build_tree(
        post, sample_stats=stats, log_likelihood=ll, observed=obs, cost_map=cmap, attrs=attrs
    )


def _cost_map(pl, priors, post, med, n=41):
    a1 = np.append(post["a1"].ravel(), med[0])
    n1 = post["n1"].ravel()
    qa = np.quantile(a1, [0.001, 0.999])
    qn = np.quantile(n1, [0.001, 0.999])
    wa, wn = qa[1] - qa[0], qn[1] - qn[0]
    ga = np.linspace(qa[0] - 0.5 * wa, qa[1] + 0.5 * wa, n)
    gn = np.linspace(qn[0] - 0.5 * wn, qn[1] + 0.5 * wn, n)
    A, Nn = np.meshgrid(ga, gn, indexing="ij")
    th = np.broadcast_to(med, (*A.shape, med.size)).copy()
    th[..., 0], th[..., 1] = A, Nn
    J = pl.total_cost(th.reshape(-1, med.size)).reshape(A.shape)
    return {"a1": ga, "n1": gn, "cost": J}


def _edge_check(priors: PriorSet, draws: np.ndarray, frac: float = 0.01) -> None:
    near = []
    for i, (k, pr) in enumerate(priors.items()):
        lo, hi = pr.lower, pr.upper
        w = hi - lo
        if not np.isfinite(w):
            continue
        edge = np.mean((draws[:, i] < lo + 0.01 * w) | (draws[:, i] > hi - 0.01 * w))
        if edge > frac:
            near.append(f"{k} ({100 * edge:.0f} % of draws)")
    if near:
        warnings.warn(
            "posterior mass at the edge of the prior/admissible region: " + ", ".join(near),
            AdmissibleRegionWarning,
            stacklevel=3,
        )


def _observed(pl: PseudoLikelihood, med: np.ndarray) -> dict:
    d = pl.data
    sp = d.spectra
    om = sp.omega
    Y3 = d.Ysigned[3][d.band_index]  # x on the band, (K, N)
    Sxx = np.mean(np.abs(Y3) ** 2, axis=-1) / (2 * np.pi * d.T * d.k2)
    Va = d.second_order(med) / d.k2
    return {"omega": np.asarray(om, float), "Sxx": Sxx, "force_spectrum_at_median": Va}
