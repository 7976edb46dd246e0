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

The excitation's corner and measurement noise are not drift terms, and the state bound
says nothing about them (a continuously observed state reveals a coloured force exactly).
:func:`spectral_bound` gives their bound from the sampled record itself: for a
stationary Gaussian sequence sampled at :math:`\Delta t` for :math:`T` seconds with
spectrum :math:`S(\omega;\vartheta)` the Fisher information is Whittle's

.. math:: I_{ij} = \frac{T}{4\pi}\int_{-\omega_N}^{\omega_N}
    \partial_i\log S\,\partial_j\log S\,d\omega, \qquad
    S(\omega) = \sum_{j=-\infty}^{\infty} S_c(\omega + 2j\omega_N)
    + \frac{\sigma_\epsilon^2\Delta t}{2\pi},

with the continuous response spectrum of the equivalent linear system,
:math:`S_c = S_0L(\omega)/[(k - \omega^2)^2 + c^2\omega^2]`,
:math:`L = 1/(1 + \eta\omega^2)`, :math:`\eta = 1/\omega_c^2` (folded by the sampling;
200 aliases), :math:`k = \sigma_{\dot x}^2/\sigma_x^2` and :math:`c = \pi S_0/\sigma_{\dot x}^2`
(the variances of the long simulation).  The parameters are
:math:`\vartheta = (c, k, S_0, \eta, \sigma_\epsilon^2)` (a selection of them), evaluated
at the null :math:`\eta = \sigma_\epsilon^2 = 0`, where both coordinates are regular.
For the linear oscillator this is the exact asymptotic information of the record; for a
nonlinear one it is that of its Gaussian equivalent, whose high-frequency tail, where
both effects show, is the nonlinear response's (:math:`S_0L/\omega^4`: inertia dominates).
:func:`candidate_bound` picks the bound of a candidate effect of ``hosid diagnose``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .model import Model

__all__ = ["CramerRao", "SpectralBound", "candidate_bound", "cramer_rao", "spectral_bound"]


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


#: The coordinate of each non-drift candidate in :func:`spectral_bound`.
SPECTRAL = {"coloured_excitation": "eta", "measurement_noise": "noise_var"}


@dataclass(frozen=True)
class SpectralBound:
    """Whittle's bound: ``names`` (a selection of ``c, k, S0, eta, noise_var``),
    ``cov`` (``I^{-1}``), ``duration``, ``dt`` and the equivalent linear system.
    """

    names: tuple[str, ...]
    cov: np.ndarray
    duration: float
    dt: float
    c: float
    k: float

    @property
    def sd(self) -> dict[str, float]:
        """Standard deviations by name."""
        return dict(zip(self.names, np.sqrt(np.diag(self.cov)).tolist(), strict=True))


def whittle_information(
    c: float,
    k: float,
    S0: float,
    *,
    duration: float,
    dt: float,
    names=("c", "k", "S0", "eta", "noise_var"),
    eta: float = 0.0,
    noise_var: float = 0.0,
    n_alias: int = 200,
    n_grid: int = 4001,
) -> np.ndarray:
    """Whittle's information matrix of the sampled equivalent linear response (module
    docstring), for the parameters ``names``.
    """
    wN = math.pi / dt
    w = np.linspace(0.0, wN, n_grid)[1:]
    W = w[None, :] + 2.0 * wN * np.arange(-n_alias, n_alias + 1)[:, None]
    L = 1.0 / (1.0 + eta * W**2)
    D = (k - W**2) ** 2 + (c * W) ** 2
    Sc = S0 * L / D
    S = Sc.sum(axis=0) + noise_var * dt / (2.0 * math.pi)
    deriv = {
        "S0": lambda: Sc.sum(axis=0) / S0,
        "k": lambda: (-2.0 * (k - W**2) * Sc / D).sum(axis=0),
        "c": lambda: (-2.0 * c * W**2 * Sc / D).sum(axis=0),
        "eta": lambda: (-(W**2) * L * Sc).sum(axis=0),
        "noise_var": lambda: np.full_like(w, dt / (2.0 * math.pi)),
    }
    G = np.stack([deriv[n]() / S for n in names])
    # the integrand is even in omega: twice the integral over (0, wN)
    return duration / (2.0 * math.pi) * np.trapezoid(G[:, None, :] * G[None, :, :], w, axis=-1)


def spectral_bound(
    model: Model | str,
    theta,
    *,
    duration: float,
    rng: np.random.Generator,
    dt: float = 0.02,
    sim_duration: float = 40000.0,
    effects=("coloured_excitation", "measurement_noise"),
) -> SpectralBound:
    r"""Whittle's bound of :math:`\eta = 1/\omega_c^2` and/or
    :math:`\sigma_\epsilon^2` at their null (module docstring), with :math:`c, k, S_0`
    free, for a record of ``duration`` s sampled at ``dt``.

    Parameters
    ----------
    model : Model or str
        The model without the effects (white force, no noise).
    theta : mapping or vector
        Its true parameters.
    duration, dt : float
        The record the bound refers to.
    rng : numpy.random.Generator
        Drives the long simulation that sets the equivalent linear system.
    sim_duration : float
        Length of that simulation (s).
    effects : sequence of str
        ``coloured_excitation`` and/or ``measurement_noise``.
    """
    model = Model.from_spec(model)
    values = model.params(theta)
    if model.has("wc") or model.has("noise_sd"):
        raise ValueError("the bound refers to the null: a white force and no noise")
    record, v = model.simulate(values, duration=sim_duration, dt=dt, rng=rng, return_velocity=True)
    sx2, sv2 = float(np.var(record.x)), float(np.var(v))
    S0 = values["S0"]
    c, k = math.pi * S0 / sv2, sv2 / sx2
    names = ("c", "k", "S0", *(SPECTRAL[e] for e in effects))
    info = whittle_information(c, k, S0, duration=duration, dt=dt, names=names)
    return SpectralBound(names, np.linalg.inv(info), float(duration), float(dt), c, k)


def candidate_bound(
    base: Model | str,
    theta,
    effect: str,
    *,
    duration: float,
    dt: float,
    rng: np.random.Generator,
    sim_duration: float = 40000.0,
) -> float:
    r"""The information limit of a candidate effect of ``hosid diagnose``: the sd of its
    regular coordinate at the null (a drift coefficient; :math:`1/\omega_c^2`;
    :math:`\sigma_\epsilon^2`), in the model ``base`` plus the effect alone.

    Drift effects: :func:`cramer_rao` of the extended model at coefficient 0 (the offset
    of :math:`x` known, as in a simulated record).  The corner and the noise:
    :func:`spectral_bound` of ``base``.
    """
    base = Model.from_spec(base)
    values = base.params(theta)
    if effect in SPECTRAL:
        bound = spectral_bound(
            base, values, duration=duration, dt=dt, rng=rng, sim_duration=sim_duration,
            effects=(effect,),
        )  # fmt: skip
        return bound.sd[SPECTRAL[effect]]
    ext = base.extended(effect)
    param = ext.terms[[t.name for t in ext.terms].index(effect)].params[0]
    crb = cramer_rao(
        ext, {**values, param: 0.0}, duration=duration, dt=dt, rng=rng, sim_duration=sim_duration
    )
    return crb.sd[param]
