r"""The information limit of a system's element coefficients (the full state observed).

If the whole state :math:`(q, \dot q)` of :math:`M\ddot q + \Phi(q, \dot q)\theta = F`
(:mod:`hosid.model.system`) were observed continuously for :math:`T` seconds, the
Girsanov likelihood of the drift acceleration :math:`b(\theta) = -M^{-1}\Phi\theta`,
with the forces' covariance per unit time mapped to accelerations :math:`\Sigma =
M^{-1}\mathrm{diag}(2\pi S_{0,d})M^{-1}`, has the Fisher matrix of the coefficients

.. math:: I = T\,E[J^{\mathsf T}\Sigma^{-1}J], \quad J = \partial b/\partial\theta
    = -M^{-1}\Phi, \qquad\text{so}\qquad
    I = T\sum_{d\,\in\,\mathrm{driven}}\frac{E[\Phi_d\Phi_d^{\mathsf T}]}{2\pi S_{0,d}},

the masses cancelling (they act only through the stationary law of the state), and
:math:`I^{-1}` bounds the covariance of any unbiased estimator of the coefficients that
sees only a sampled record, the masses and force levels taken as known.  For one element
to the ground it is the single oscillator's :math:`T/(2\pi S_0)E[\phi\phi^{\mathsf T}]`
(:mod:`hosid.model.information`).  With :math:`\Phi_d = s_d\odot\varphi`
(:math:`\varphi` the element features, :math:`s_{d,c} = B_{e_c d}`),
:math:`I = T\,(W\odot E[\varphi\varphi^{\mathsf T}])`,
:math:`W = \sum_d s_ds_d^{\mathsf T}/(2\pi S_{0,d})`.

**Undriven degrees of freedom.**  :math:`\Sigma` is singular there: an undriven dof's
equation holds without noise, so a continuous full-state path would fix the
coefficients in it exactly (a degenerate, zero bound that floors nothing).  The bound
here is restricted to the driven dofs' equations (the sum above); a coefficient that
appears in no driven equation gets no information from it, and its row of the
covariance is NaN (the others' bound then treats it as known).

:func:`chain_bound` estimates :math:`E[\varphi\varphi^{\mathsf T}]` from one long
simulation (:func:`hosid.model.chain.simulate_chain`, the state at the sample times),
with a jackknife over consecutive batches for the Monte Carlo error of each sd;
:func:`linear_information` gives it exactly for a linear system from the Lyapunov
covariance (:func:`hosid.model.linear_chain.stationary_covariance`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import HosidInputError
from .chain import simulate_chain
from .linear_chain import stationary_covariance
from .system import System

__all__ = ["ChainBound", "chain_bound", "feature_moments", "linear_information", "weights"]


def weights(system: System, theta=None) -> np.ndarray:
    r""":math:`W = \sum_{d\,\in\,\mathrm{driven}} s_ds_d^{\mathsf T}/(2\pi S_{0,d})`,
    ``(n_drift, n_drift)`` (module docstring).
    """
    levels = system.levels(system.vector(theta))
    B = system.incidence
    S = np.stack([B[e] for e, _ in system.columns], axis=-1)  # (n, n_drift)
    W = np.zeros((system.n_drift, system.n_drift))
    for d in system.driven:
        k = system.dofs.index(d)
        W += np.outer(S[k], S[k]) / (2.0 * math.pi * levels[k])
    return W


def feature_moments(system: System, q: np.ndarray, v: np.ndarray, batches: int = 1):
    r""":math:`E[\varphi\varphi^{\mathsf T}]` of the element features over samples of the
    state, one ``(n_drift, n_drift)`` matrix per consecutive batch
    (``(batches, n_drift, n_drift)``; batches of equal length, the remainder dropped).
    """
    n = q.shape[0] // batches
    out = np.empty((batches, system.n_drift, system.n_drift))
    for b in range(batches):
        f = system.element_features(q[b * n : (b + 1) * n], v[b * n : (b + 1) * n])
        out[b] = f.T @ f / n
    return out


@dataclass(frozen=True)
class ChainBound:
    """The bound: ``names`` (element coefficients), ``info`` (:math:`I` for ``duration``
    s), ``cov`` (:math:`I^{-1}`, NaN for coefficients no driven equation holds),
    ``sd_se`` (Monte Carlo standard errors of the sds, jackknife), the response's sds
    ``sigma_q``, ``sigma_v`` per dof, and the number of state samples averaged.
    """

    names: tuple[str, ...]
    info: np.ndarray
    cov: np.ndarray
    duration: float
    n_samples: int
    sd_se: np.ndarray
    sigma_q: np.ndarray
    sigma_v: np.ndarray

    @property
    def sd(self) -> dict[str, float]:
        """Standard deviations by name."""
        return dict(zip(self.names, np.sqrt(np.diag(self.cov)).tolist(), strict=True))

    def corr(self, a: str, b: str) -> float:
        """Correlation of two coefficients."""
        i, j = self.names.index(a), self.names.index(b)
        return float(self.cov[i, j] / np.sqrt(self.cov[i, i] * self.cov[j, j]))


def _inverse(info: np.ndarray, reached: np.ndarray) -> np.ndarray:
    cov = np.full_like(info, np.nan)
    idx = np.flatnonzero(reached)
    cov[np.ix_(idx, idx)] = np.linalg.inv(info[np.ix_(idx, idx)])
    return cov


def linear_information(system: System, theta=None, *, duration: float) -> np.ndarray:
    r"""The exact :math:`I` of a linear system (``linear_damping`` and
    ``linear_stiffness`` terms only) for ``duration`` s: :math:`\varphi = Gs` with
    :math:`s = (q, \dot q)`, :math:`E[\varphi\varphi^{\mathsf T}] = GPG^{\mathsf T}`,
    :math:`P` the Lyapunov covariance.

    Raises
    ------
    HosidInputError
        If a term is not linear, or the system has no stationary state.
    """
    n, B = system.n, system.incidence
    G = np.zeros((system.n_drift, 2 * n))
    for c, (e, term) in enumerate(system.columns):
        if term.name not in ("linear_damping", "linear_stiffness"):
            raise HosidInputError(f"linear_information: {term.name} is not a linear term")
        if term.name == "linear_damping":
            G[c, n:] = B[e]  # the relative velocity
        else:
            G[c, :n] = B[e]  # the relative displacement
    P = stationary_covariance(system, theta)
    return duration * weights(system, theta) * (G @ P @ G.T)


def chain_bound(
    system: System,
    values=None,
    *,
    duration: float,
    rng: np.random.Generator,
    dt: float = 0.02,
    sim_duration: float = 40000.0,
    batches: int = 20,
    substeps: int = 10,
) -> ChainBound:
    """The full-state bound of the element coefficients for a record of ``duration`` s
    (module docstring), from one simulation of ``sim_duration`` s sampled at ``dt``.

    Parameters
    ----------
    system : System
    values : mapping or vector, optional
        The true parameters (default the system's own values).
    duration : float
        Length of the record the bound refers to (s).
    rng : numpy.random.Generator
        Drives the long simulation.
    dt, sim_duration, substeps : float, float, int
        Its sampling, length and Heun sub-steps.
    batches : int
        Consecutive batches of the simulation for the jackknife (at least 2).

    Raises
    ------
    HosidInputError
        If no coefficient is in a driven equation, or the simulation fails.
    """
    th = system.vector(values)
    _, q, v = simulate_chain(
        system, th, duration=sim_duration, dt=dt, rng=rng, substeps=substeps,
        measured="displacement", return_state=True,
    )  # fmt: skip
    return bound_from_state(system, th, q, v, duration=duration, batches=batches)


def bound_from_state(
    system: System, values, q: np.ndarray, v: np.ndarray, *, duration: float, batches: int = 20
) -> ChainBound:
    """The bound of :func:`chain_bound` from given samples ``q``, ``v`` (each
    ``(n_samples, n)``) of the stationary state.

    Raises
    ------
    HosidInputError
        If no coefficient is in a driven equation, or ``batches < 2``.
    """
    if batches < 2:
        raise HosidInputError("batches must be at least 2 (the jackknife)")
    th = system.vector(values)
    W = weights(system, th)
    reached = np.diag(W) > 0
    if not reached.any():
        raise HosidInputError("no element coefficient is in the equation of a driven dof")
    moments = feature_moments(system, q, v, batches)
    info = duration * W * moments.mean(axis=0)
    cov = _inverse(info, reached)
    loo = (moments.sum(axis=0) - moments) / (batches - 1)  # leave one batch out
    sds = np.array([np.sqrt(np.diag(_inverse(duration * W * m, reached))) for m in loo])
    se = np.sqrt((batches - 1) / batches * ((sds - sds.mean(axis=0)) ** 2).sum(axis=0))
    return ChainBound(
        names=system.param_names[: system.n_drift],
        info=info,
        cov=cov,
        duration=float(duration),
        n_samples=int(q.shape[0]),
        sd_se=se,
        sigma_q=q.std(axis=0),
        sigma_v=v.std(axis=0),
    )
