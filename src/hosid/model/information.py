r"""The information limit: Cramer-Rao bound of the drift coefficients.

If the whole state :math:`(x, \dot x)` of :math:`\ddot x + \sum_k\theta_k\phi_k = g`
(:math:`g` white, :math:`2\pi S_0\delta(\tau)`) were observed continuously for
:math:`T` seconds, the Girsanov log-likelihood of the drift,

.. math:: \ell(\theta) = -\frac{1}{2\pi S_0}\int_0^T \Big(\sum_k\theta_k\phi_k\Big)
    \,d\dot x - \frac{1}{4\pi S_0}\int_0^T\Big(\sum_k\theta_k\phi_k\Big)^2 dt,

has the Fisher matrix

.. math:: I = \frac{T}{2\pi S_0}\,E[\phi\phi^{\mathsf T}],

and :math:`I^{-1}` bounds the covariance of any unbiased estimator that sees only the
sampled :math:`x(t)`.  :func:`cramer_rao` estimates :math:`E[\phi\phi^{\mathsf T}]` from
a long simulation that keeps the simulated velocity (NOTES.md, last section).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .model import Model

__all__ = ["CramerRao", "cramer_rao"]


@dataclass(frozen=True)
class CramerRao:
    """The bound: ``names`` (drift coefficients), ``cov`` (``I^{-1}``), ``duration``."""

    names: tuple[str, ...]
    cov: np.ndarray
    duration: float
    sigma_v: float
    a1eq_sd: float

    @property
    def sd(self) -> dict[str, float]:
        """Standard deviations by name (plus ``a1eq``, eq 65)."""
        out = dict(zip(self.names, np.sqrt(np.diag(self.cov)).tolist(), strict=True))
        out["a1eq"] = self.a1eq_sd
        return out

    def corr(self, a: str, b: str) -> float:
        """Correlation of two coefficients."""
        i, j = self.names.index(a), self.names.index(b)
        return float(self.cov[i, j] / np.sqrt(self.cov[i, i] * self.cov[j, j]))


def cramer_rao(
    model: Model | str,
    theta,
    *,
    duration: float,
    rng: np.random.Generator,
    dt: float = 0.02,
    sim_duration: float = 40000.0,
) -> CramerRao:
    """The Cramer-Rao bound of the drift coefficients for a record of ``duration`` s.

    Parameters
    ----------
    model : Model or str
    theta : mapping or vector
        The true parameters (white excitation: ``S0`` is used, ``wc`` must be absent).
    duration : float
        Length of the record the bound refers to (s).
    rng : numpy.random.Generator
        Drives the long simulation.
    dt, sim_duration : float
        Sampling of the long simulation and its length (s).
    """
    model = Model.from_spec(model)
    values = model.params(theta)
    record, v = model.simulate(values, duration=sim_duration, dt=dt, rng=rng, return_velocity=True)
    x = record.x
    phi = np.stack([t.phi(v if t.variable == "v" else x) for t in model.drift_terms])
    if "noise_sd" in values:
        raise ValueError("the bound refers to the noise-free state")
    E = phi @ phi.T / x.size
    cov = np.linalg.inv(duration / (2.0 * np.pi * values["S0"]) * E)
    sigma_v = float(np.std(v))
    g = np.array([t.damping_factor(sigma_v) for t in model.drift_terms])
    return CramerRao(
        names=tuple(t.params[0] for t in model.drift_terms),
        cov=cov,
        duration=float(duration),
        sigma_v=sigma_v,
        a1eq_sd=float(np.sqrt(g @ cov @ g)),
    )
