r"""Temperature of a pseudo-likelihood by parametric bootstrap (Godambe sandwich).

For a cost :math:`J` minimized at :math:`\hat\theta`, write
:math:`c(\theta) = J(\theta)/2`, :math:`H = \nabla^2 c(\hat\theta)` and
:math:`u = \nabla c(\hat\theta)`.  The estimator's sampling covariance is the
sandwich :math:`\Sigma = H^{-1} V H^{-1}` with :math:`V = \operatorname{Cov}(u)`,
whereas the pseudo-posterior :math:`\propto e^{-J/(2\tau)}` has covariance
:math:`\tau H^{-1}` near the mode.  The two agree when :math:`V = \tau H`, which is
what a true likelihood gives with :math:`\tau=1` (the information identity);
spectral ordinates are strongly dependent, so the costs violate it.

:math:`V` is estimated by *parametric bootstrap*: records of the same length
are simulated from the fitted model :math:`\hat\theta`, and the gradient of each
record's cost components at :math:`\hat\theta` is taken by central differences.

With several components :math:`J = \sum_c J_c/\tau_c` each gets its own
temperature (J2 and J4 over-count their information by very different factors).
Writing :math:`H_\tau = \sum_c H_c/\tau_c` and :math:`V_\tau = \operatorname{Cov}
(\sum_c u_c/\tau_c)`, the per-parameter variance ratios

.. math:: r_i(\tau) = \frac{(H_\tau^{-1}V_\tau H_\tau^{-1})_{ii}}{(H_\tau^{-1})_{ii}}

(sandwich over pseudo-posterior) measure the calibration.  Inverting the
combined Hessian is fragile (J2 alone is nearly flat along the a1-n1 valley), so
each component's temperature is its largest *diagonal* design effect
:math:`\tau_c = \max_i V_{c,ii}/H_{c,ii}` over the coordinates it identifies
(J2: not n1).  If the combined sandwich is still wider for some parameter
(:math:`\max_i r_i > 1`), all temperatures are multiplied by :math:`\max_i r_i`,
so that no parameter's pseudo-posterior is narrower than the estimator's sampling
spread (conservative for the others).  The final ratios are returned.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from .records import Record
from .simulate import simulate

__all__ = ["Calibration", "calibrate", "gradient", "hessian"]


@dataclass
class Calibration:
    """Result of :func:`calibrate`."""

    temperatures: dict
    hessian: np.ndarray = field(repr=False)
    sandwich: np.ndarray = field(repr=False)
    ratios: np.ndarray
    n_bootstrap: int
    coordinates: tuple

    def as_dict(self) -> dict:
        """JSON-ready summary."""
        sd = np.sqrt(np.clip(np.diag(self.sandwich), 0, None))
        names = list(self.coordinates)
        return {
            "method": "parametric bootstrap of the score (Godambe sandwich); per spectral "
            "component tau_c = max_i V_ii / H_ii, all scaled up by max ratio if > 1",
            "temperatures": self.temperatures,
            "n_bootstrap": self.n_bootstrap,
            "coordinates": names,
            "sandwich_sd": dict(zip(names, map(float, sd), strict=True)),
            "ratio_sandwich_to_tempered": dict(zip(names, map(float, self.ratios), strict=True)),
        }


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


def _ratios(log_tau, H, U):
    """Per-parameter variance ratios for temperatures exp(log_tau)."""
    tau = np.exp(np.clip(log_tau, -50, 50))
    Ht = sum(Hc / t for Hc, t in zip(H, tau, strict=True))
    Ut = sum(U[:, :, c] / t for c, t in enumerate(tau))
    Vt = np.atleast_2d(np.cov(Ut, rowvar=False))
    Hi = np.linalg.pinv(Ht)
    S = Hi @ Vt @ Hi
    return np.diag(S) / np.diag(Hi), S, Hi


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
) -> Calibration:
    """Temperatures of the spectral components (module doc).

    Parameters
    ----------
    components : callable
        ``t (n, q) -> {name: (n,)}``: the record's spectral cost components in
        the calibration coordinates ``t``.
    make_components : callable
        Record -> such a callable, prepared exactly as for the data.
    theta : ndarray
        The mode in the calibration coordinates.
    params : dict
        Simulator parameters of the fitted model.
    scale : ndarray
        Typical scales of the coordinates; finite-difference steps are
        ``1e-3 * scale``.
    simulator : callable, optional
        ``simulator(params, duration=, dt=, rng=)`` for the bootstrap records
        (default :func:`hosid.simulate.simulate`).
    """
    from tqdm.auto import tqdm

    theta = np.asarray(theta, dtype=float)
    h = 1e-3 * np.asarray(scale, dtype=float)
    names = list(components(theta[None]))
    H = [hessian(lambda t, c=c: 0.5 * components(t)[c], theta, h) for c in names]
    pts = _points_gradient(theta, h)
    q = theta.size
    U = np.empty((n_bootstrap, q, len(names)))
    children = rng.spawn(n_bootstrap)
    for b, child in enumerate(
        tqdm(children, desc="calibrating", disable=not progress, leave=False)
    ):
        rec = (simulator or simulate)(params, duration=duration, dt=dt, rng=child)
        vals = make_components(rec)(pts)
        for k, c in enumerate(names):
            v = 0.5 * vals[c]
            U[b, :, k] = (v[:q] - v[q:]) / (2 * h)
    # one temperature per component: its largest diagonal design effect
    # V_ii / H_ii over the coordinates it identifies (H_ii > 0; J2 does not see n1)
    log_tau = np.empty(len(names))
    for k, c in enumerate(names):
        V = np.atleast_2d(np.cov(U[:, :, k], rowvar=False))
        d = np.diag(H[k])
        use = d > 1e-8 * np.max(np.abs(d))
        if c.startswith("J2") and "n1" in coordinates:
            use &= np.array([n != "n1" for n in coordinates])
        eff = np.diag(V)[use] / d[use]
        log_tau[k] = np.log(max(float(np.max(eff)), 1e-6)) if eff.size else 0.0
    r, S, Hi = _ratios(log_tau, H, U)
    if np.all(np.isfinite(r)) and np.max(r) > 1:
        # the combined sandwich is wider than the tempered posterior: widen all
        log_tau = log_tau + np.log(np.max(r))
        r, S, Hi = _ratios(log_tau, H, U)
    taus = dict(zip(names, map(float, np.exp(log_tau)), strict=True))
    return Calibration(
        temperatures=taus,
        hessian=np.linalg.pinv(Hi),
        sandwich=S,
        ratios=r,
        n_bootstrap=n_bootstrap,
        coordinates=tuple(coordinates) or tuple(f"t{i}" for i in range(q)),
    )
