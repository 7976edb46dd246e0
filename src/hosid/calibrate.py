r"""Temperature of a pseudo-likelihood by parametric bootstrap of the estimator.

A pseudo-likelihood :math:`\ell(\theta) = -\sum_c J_c(\theta)/(2\tau)` built from
least-squares costs :math:`J_c` has, near its mode :math:`\hat\theta`, the
covariance :math:`\tau H^{-1}` with :math:`H = \nabla^2 \tfrac12\sum_c J_c(\hat\theta)`.
With :math:`\tau = 1` that is the right answer only if the costs were true
negative log-likelihoods of independent data; spectral ordinates are strongly
dependent (neighbouring bins share the window, trispectral triples share
frequencies), so :math:`\tau = 1` is over-confident.

The temperature is chosen by matching the pseudo-posterior's curvature to the
*sampling spread of the estimator* :math:`\hat\theta = \arg\min\sum_c J_c`:

1. simulate :math:`B` records of the same length from the fitted model
   :math:`\hat\theta` (parametric bootstrap);
2. re-estimate each: :math:`\hat\theta_b = \arg\min_t \sum_c J_c^{(b)}(t)`, starting
   from :math:`\hat\theta` (which is the truth of the bootstrap world);
3. :math:`\Sigma_B = \operatorname{Cov}(\hat\theta_b)` and

.. math:: \tau = \max_i \frac{(\Sigma_B)_{ii}}{(H^{-1})_{ii}},

one temperature shared by all spectral components, so that the posterior mode is
the estimator and no coordinate's pseudo-posterior is narrower than the
estimator's spread (conservative for the others).  The ratios
:math:`r_i = (\Sigma_B)_{ii}/(\tau H^{-1})_{ii} \le 1` are returned, with the
bootstrap bias :math:`\overline{\hat\theta_b} - \hat\theta`.

The estimator-bootstrap replaces an earlier score (Godambe sandwich) bootstrap: the
score of the centred spectral costs is dominated by their variance terms, and the
sandwich came out two to three orders of magnitude too wide.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from scipy import optimize

from .records import Record
from .simulate import simulate

__all__ = ["Calibration", "calibrate", "gradient", "hessian", "minimize_total"]


@dataclass
class Calibration:
    """Result of :func:`calibrate`."""

    temperatures: dict
    hessian: np.ndarray = field(repr=False)
    sandwich: np.ndarray = field(repr=False)
    ratios: np.ndarray
    n_bootstrap: int
    coordinates: tuple
    estimates: np.ndarray = field(default=None, repr=False)
    theta: np.ndarray = field(default=None, repr=False)

    def as_dict(self) -> dict:
        """JSON-ready summary."""
        sd = np.sqrt(np.clip(np.diag(self.sandwich), 0, None))
        names = list(self.coordinates)
        out = {
            "method": "parametric bootstrap of the estimator: tau = max_i Var_B(theta_i) / "
            "(H^-1)_ii, one tau shared by the spectral components",
            "temperatures": self.temperatures,
            "n_bootstrap": self.n_bootstrap,
            "coordinates": names,
            "bootstrap_sd": dict(zip(names, map(float, sd), strict=True)),
            "ratio_bootstrap_to_tempered": dict(zip(names, map(float, self.ratios), strict=True)),
        }
        if self.estimates is not None and self.theta is not None:
            bias = np.mean(self.estimates, axis=0) - self.theta
            out["bootstrap_bias"] = dict(zip(names, map(float, bias), strict=True))
        return out


def _points_gradient(x, h):
    E = np.diag(h)
    return np.concatenate([x + E, x - E])


def gradient(f: Callable, x: np.ndarray, h: np.ndarray) -> np.ndarray:
    """Central-difference gradient of a vectorized scalar function (one batch call)."""
    v = f(_points_gradient(x, h))
    p = x.size
    return (v[:p] - v[p:]) / (2 * h)


def hessian(f: Callable, x: np.ndarray, h: np.ndarray) -> np.ndarray:
    """Central-difference Hessian of a vectorized scalar function (one batch call)."""
    p = x.size
    E = np.diag(h)
    pts = [x]
    for i in range(p):
        for j in range(i, p):
            for si, sj in ((1, 1), (1, -1), (-1, 1), (-1, -1)):
                pts.append(x + si * E[i] + sj * E[j])
    v = f(np.array(pts))
    H = np.empty((p, p))
    k = 1
    for i in range(p):
        for j in range(i, p):
            pp, pm, mp, mm = v[k : k + 4]
            H[i, j] = H[j, i] = (pp - pm - mp + mm) / (4 * h[i] * h[j])
            k += 4
    return H


def _positive_definite(H: np.ndarray) -> np.ndarray:
    """Symmetric ``H`` with non-positive eigenvalues replaced by small positive ones."""
    H = 0.5 * (H + H.T)
    w, U = np.linalg.eigh(H)
    floor = 1e-9 * max(float(np.max(np.abs(w))), 1e-300)
    return (U * np.maximum(np.abs(w), floor)) @ U.T


def minimize_total(
    components: Callable, start: np.ndarray, step: np.ndarray, bounds=None
) -> np.ndarray:
    r"""Minimize :math:`\sum_c J_c(t)` from ``start`` (Nelder-Mead in units of ``step``).

    ``bounds`` is an optional ``(lower, upper)`` pair; outside it the objective is
    infinite.
    """
    start = np.asarray(start, dtype=float)
    step = np.asarray(step, dtype=float)

    def f(u):
        t = start + u * step
        if bounds is not None and (np.any(t < bounds[0]) or np.any(t > bounds[1])):
            return np.inf
        v = float(sum(components(t[None]).values())[0])
        return v if np.isfinite(v) else np.inf

    q = start.size
    simplex = np.vstack([np.zeros(q), 2.0 * np.eye(q)])
    with warnings.catch_warnings(), np.errstate(invalid="ignore", over="ignore"):
        warnings.simplefilter("ignore", RuntimeWarning)
        res = optimize.minimize(
            f,
            np.zeros(q),
            method="Nelder-Mead",
            options={
                "xatol": 2e-2,
                "fatol": 1e-3,
                "maxfev": 400 * q,
                "initial_simplex": simplex,
                "adaptive": True,
            },
        )
    return start + res.x * step


def calibrate(
    components: Callable,
    make_components: Callable[[Record], Callable],
    theta: np.ndarray,
    params: dict,
    *,
    duration: float,
    dt: float,
    scale: np.ndarray,
    n_bootstrap: int = 30,
    rng: np.random.Generator,
    progress: bool = False,
    coordinates: tuple = (),
    simulator: Callable | None = None,
    bounds: tuple | None = None,
) -> Calibration:
    """Temperature of the spectral components (module doc).

    Parameters
    ----------
    components : callable
        ``t (n, q) -> {name: (n,)}``: the record's spectral cost components in
        the calibration coordinates ``t``.
    make_components : callable
        Record -> such a callable, prepared exactly as for the data (the same
        estimator: spectra, stiffness cut, ...).
    theta : ndarray
        The mode in the calibration coordinates.
    params : dict
        Simulator parameters of the fitted model.
    scale : ndarray
        Typical scales of the coordinates: finite-difference steps are
        ``1e-3 * scale`` and the re-estimates start with a simplex of ``2 * scale``.
    n_bootstrap : int
        Bootstrap records (at least 2).
    simulator : callable, optional
        ``simulator(params, duration=, dt=, rng=)`` for the bootstrap records
        (default :func:`hosid.simulate.simulate`).
    bounds : (lower, upper), optional
        Box for the re-estimates (the admissible region).
    """
    from tqdm.auto import tqdm

    if n_bootstrap < 2:
        raise ValueError(f"n_bootstrap must be at least 2, got {n_bootstrap}")
    theta = np.asarray(theta, dtype=float)
    scale = np.asarray(scale, dtype=float)
    h = 1e-3 * scale
    names = list(components(theta[None]))
    H = _positive_definite(hessian(lambda t: 0.5 * sum(components(t).values()), theta, h))
    Hi = np.linalg.inv(H)
    est = np.empty((n_bootstrap, theta.size))
    children = rng.spawn(n_bootstrap)
    for b, child in enumerate(
        tqdm(children, desc="calibrating", disable=not progress, leave=False)
    ):
        rec = (simulator or simulate)(params, duration=duration, dt=dt, rng=child)
        est[b] = minimize_total(make_components(rec), theta, scale, bounds)
    S = np.atleast_2d(np.cov(est, rowvar=False))
    tau = max(float(np.max(np.diag(S) / np.diag(Hi))), 1e-6)
    ratios = np.diag(S) / (tau * np.diag(Hi))
    return Calibration(
        temperatures=dict.fromkeys(names, tau),
        hessian=H / tau,
        sandwich=S,
        ratios=ratios,
        n_bootstrap=n_bootstrap,
        coordinates=tuple(coordinates) or tuple(f"t{i}" for i in range(theta.size)),
        estimates=est,
        theta=theta,
    )
