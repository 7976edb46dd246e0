r"""Parameter draws for posterior-predictive replicates, with or without a chain.

:func:`tree_sample` flattens the posterior of a :func:`hosid.inference.fit.fit`
(emcee) run.  :func:`screen_sample` draws from the *same* target, the calibrated
quasi-posterior :math:`p(\theta\mid x) \propto \pi(\theta)\exp\ell_{cal}(\theta)` of
:func:`~hosid.inference.fit.fit` (default priors, eq-65 constraint), without a chain,
from the :func:`~hosid.inference.estimate.estimate` alone:

1. Proposals from the Gaussian :math:`N(\hat\theta, \hat C)` of the estimate (its
   calibrated covariance), restricted to the priors: a multivariate Student t with 5
   degrees of freedom and that scale (inflated by 1.5), in :math:`\log\theta` for the
   log-uniform parameters (:math:`S_0`, :math:`\omega_c`), each standard deviation
   capped at a quarter of its prior's width (an estimate outside its prior is moved
   to the nearest bound and given that spread);
2. importance weights :math:`\pi(\theta)e^{\ell_{cal}(\theta)}/q(\theta)`, zero outside
   the priors; each further round (four in all) proposes from the weighted mean and
   covariance of the one before, and the round with the largest effective sample
   size is kept;
3. multinomial resampling.

Where the Gaussian is right the weights are nearly flat and the draws are those of
:math:`N(\hat\theta, \hat C)` restricted to the priors.  The weights correct it where
it is not: a parameter at the boundary of its prior (``noise_sd`` on a noise-free
record, whose estimating equation depends on :math:`\sigma_\epsilon^2` and leaves the
curvature singular at 0; ``mu`` near 0) or an estimate outside the prior (``wc``
beyond its prior, or run off to :math:`10^{10}` on a white record).
Evaluating :math:`\ell_{cal}` costs microseconds a draw.
"""

from __future__ import annotations

import math

import numpy as np
import xarray as xr

from ..errors import HosidInputError
from ..inference.calibrate import calibrate
from ..inference.estimate import Estimate
from ..model.model import Model

__all__ = ["screen_sample", "tree_sample"]

#: Degrees of freedom of the t proposal.
DF = 5.0
#: Inflation of the proposal's scale over the estimate's covariance.
INFLATE = 1.5
#: Rounds of adaptation of the proposal.
ROUNDS = 4


def tree_sample(tree: xr.DataTree, model: Model) -> np.ndarray:
    """The posterior draws of a fit, ``(chains * draws, p)`` in parameter order."""
    post = tree["posterior"]
    return np.stack([np.asarray(post[n].values).ravel() for n in model.param_names], axis=-1)


def _pd(C: np.ndarray, floor: np.ndarray) -> np.ndarray:
    """A symmetric positive-definite copy of ``C`` (eigenvalues floored)."""
    C = 0.5 * (C + C.T)
    w, U = np.linalg.eigh(C)
    w = np.maximum(w, 1e-10 * max(float(w.max()), float(np.max(floor**2))))
    return (U * w) @ U.T


def _t_draws(rng, mu, C, n) -> tuple[np.ndarray, np.ndarray]:
    """``n`` multivariate t draws and their log density up to a constant."""
    L = np.linalg.cholesky(C)
    z = rng.standard_normal((n, mu.size))
    w = rng.chisquare(DF, size=n) / DF
    u = mu + (z @ L.T) / np.sqrt(w)[:, None]
    d = np.linalg.solve(L, (u - mu).T)
    logq = -0.5 * (DF + mu.size) * np.log1p(np.sum(d**2, axis=0) / DF)
    return u, logq


def _weights(logw: np.ndarray) -> tuple[np.ndarray, float]:
    ok = np.isfinite(logw)
    w = np.zeros_like(logw)
    if ok.any():
        w[ok] = np.exp(logw[ok] - logw[ok].max())
        w /= w.sum()
    ess = 1.0 / float(np.sum(w**2)) if ok.any() else 0.0
    return w, ess


def screen_sample(
    est: Estimate,
    rng: np.random.Generator,
    *,
    n_proposals: int = 8000,
    size: int = 2000,
) -> tuple[np.ndarray, dict]:
    """Draws from the calibrated quasi-posterior of ``est`` (module docstring).

    Parameters
    ----------
    est : Estimate
        :func:`hosid.inference.estimate.estimate` of the model.
    rng : numpy.random.Generator
        The only source of randomness.
    n_proposals, size : int
        Proposals per round; draws returned.

    Returns
    -------
    sample : ndarray, shape (size, p)
        Equally weighted draws in parameter order.
    info : dict
        ``ess`` (effective sample size of the kept round), ``proposals``,
        ``admissible`` (fraction of its proposals inside the priors) and ``round``.

    Raises
    ------
    HosidInputError
        If no proposal falls inside the priors with a finite quasi-likelihood.
    """
    model = est.model
    names = model.param_names
    cal = calibrate(est)
    priors = model.default_priors(est.scales(), constrained=True)
    logs = np.array([priors[n].log_scaled for n in names])
    lo = np.array([priors[n].lower for n in names], dtype=float)
    hi = np.array([priors[n].upper for n in names], dtype=float)
    lo[logs], hi[logs] = np.log(lo[logs]), np.log(hi[logs])
    width = np.where(np.isfinite(hi - lo), hi - lo, np.inf)

    theta = np.asarray(cal.theta, dtype=float)
    jac = np.ones_like(theta)
    jac[logs] = 1.0 / np.maximum(theta[logs], np.exp(lo[logs]))
    u0 = theta.copy()
    u0[logs] = np.log(np.maximum(theta[logs], np.exp(lo[logs])))
    C = np.asarray(cal.cov, dtype=float) * np.outer(jac, jac)
    sd = np.sqrt(np.abs(np.diag(C)))
    cap = np.where(np.isfinite(width), 0.25 * width, np.inf)
    # an estimate outside its prior (wc run off to infinity on a white record) has no
    # useful curvature: propose from its nearest bound with the capped spread
    outside = (u0 < lo) | (u0 > hi)
    u0 = np.clip(u0, lo, hi)
    bad = ~np.isfinite(sd) | (sd <= 0) | outside
    sd_ok = np.where(bad, 1.0, sd)
    f = np.where(bad, 0.0, np.minimum(1.0, cap / sd_ok))
    C = np.nan_to_num(C) * np.outer(f, f) + np.diag(np.where(bad, np.minimum(cap, 1e3), 0.0) ** 2)
    C = _pd(C, np.where(np.isfinite(cap), cap, 0.0) * 1e-3)

    def log_target(u: np.ndarray) -> np.ndarray:
        th = u.copy()
        th[:, logs] = np.exp(u[:, logs])
        lp = priors.ln_prob(th)
        out = np.full(u.shape[0], -np.inf)
        ok = np.isfinite(lp)
        if ok.any():
            with np.errstate(all="ignore"):
                ll = sum(cal.by_component(th[ok]).values())
            out[ok] = np.where(np.isfinite(ll), lp[ok] + ll + u[ok][:, logs].sum(axis=1), -np.inf)
        return out

    best = None
    mu, S = u0, INFLATE**2 * C
    for k in range(ROUNDS):
        u, logq = _t_draws(rng, mu, S, int(n_proposals))
        lt = log_target(u)
        w, ess = _weights(lt - logq)
        if ess > 0 and (best is None or ess > best[2]):
            best = (u, w, ess, float(np.mean(np.isfinite(lt))), k + 1)
        if ess <= 0:
            break
        mu = w @ u
        dev = u - mu
        S = _pd(INFLATE**2 * (dev.T * w) @ dev, np.sqrt(np.diag(C)) * 1e-3)
    if best is None:
        raise HosidInputError(
            f"no draw of {model!r} near its estimate lies inside the priors: "
            "the estimate is far outside them"
        )
    u, w, ess, admissible, rnd = best
    idx = rng.choice(u.shape[0], size=int(size), p=w)
    sample = u[idx]
    sample[:, logs] = np.exp(sample[:, logs])
    info = {
        "ess": ess,
        "proposals": int(n_proposals),
        "admissible": admissible,
        "round": rnd,
        "dispersion": float(cal.dispersion),
    }
    if not math.isfinite(ess):  # pragma: no cover - guarded by _weights
        raise HosidInputError("importance weights are not finite")
    return sample, info
