r"""The likelihood-component protocol and what the components share.

A component turns the record's state into *estimating equations*: a vector of
:math:`k` block means :math:`\bar m(\theta) = \frac1B\sum_b m_b(\theta)` whose
expectation vanishes at the true parameters.  :meth:`Component.prepare` computes, once
per record, the sufficient statistics that make :math:`\bar m(\theta)` a cheap
polynomial-like function of :math:`\theta` (evaluating it never touches the samples
again) and the per-block *influence* :math:`u_b` at a pilot value :math:`\tilde\theta`,
from which :mod:`hosid.inference.gmm` builds the covariance of :math:`\bar m` and the
calibrated quasi-likelihood

.. math:: \ell(\theta) = -\frac{B}{2}\,\bar m(\theta)^{\mathsf T}\,\hat\Sigma^{-1}\,
    \bar m(\theta), \qquad \hat\Sigma = \widehat{\mathrm{Cov}}(u_b).

Shared here (with the excitation of :mod:`hosid.components.excitation`): the velocity
restoration :math:`s^2` of :mod:`hosid.state`, and the block transforms of the
inferred force's features (eq 45), :math:`Y_0 = \ddot x`, :math:`Y_k = \phi_k` with
velocity features restored as :math:`\phi + \tfrac12 s^2\phi''`.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from functools import partial
from typing import Protocol

import numpy as np

from ..model.model import Model
from ..state import RecordState
from .excitation import Excitation

__all__ = [
    "Component",
    "Excitation",
    "Moments",
    "feature_ffts",
    "restoration",
    "u_pseudovalues",
]


@dataclass(frozen=True)
class Moments:
    """A component prepared on one record.

    Attributes
    ----------
    component : str
        The component's name.
    labels : tuple of str
        One label per estimating equation.
    mean : callable
        ``theta (..., p) -> (..., k)``: the block-mean estimating equations.
    influence : ndarray, shape (B, k)
        Per-block influence at the pilot, centred: the block values of a block mean, the
        jackknife pseudo-values of a U-statistic (:func:`u_pseudovalues`).
    info : dict
        What the component used (band, domain, ...), for the report.
    covariance : ndarray, shape (k, k), optional
        One block's covariance of the equations from the component's own model, when it
        knows it better than its influence's spread does (the quasi-likelihood then uses
        it, :func:`hosid.inference.gmm.quasi_likelihood`).
    """

    component: str
    labels: tuple[str, ...]
    mean: Callable[[np.ndarray], np.ndarray]
    influence: np.ndarray
    info: dict = field(default_factory=dict)
    covariance: np.ndarray | None = None

    @property
    def k(self) -> int:
        """Number of estimating equations."""
        return len(self.labels)

    @classmethod
    def empty(cls, component: str, n_blocks: int, why: str) -> Moments:
        """No equation: the component does not hold here (``why``, in ``info``)."""
        return cls(
            component,
            (),
            lambda theta: np.zeros((*np.shape(theta)[:-1], 0)),
            np.zeros((n_blocks, 0)),
            {"skipped": why},
        )


class Component(Protocol):
    """A likelihood component: ``name`` and :meth:`prepare`."""

    name: str

    def prepare(self, state: RecordState, model: Model, pilot: np.ndarray) -> Moments:
        """Sufficient statistics of ``state`` for ``model``, weights frozen at ``pilot``."""
        ...  # pragma: no cover


def u_pseudovalues(d: np.ndarray, e: np.ndarray) -> np.ndarray:
    r"""Delete-one-block jackknife pseudo-values of the U-statistic of a spectral component.

    With per-block weights :math:`d_{rtj}` and residuals :math:`e_{rt}` (``(B, n, J)``
    and ``(B, n)``, real or complex), the component's equations are the U-statistic

    .. math:: U_j = \frac{1}{B(B-1)}\sum_{r\ne r'}\mathrm{Re}\sum_t
        d^*_{r'tj}\,e_{rt},

    and its pseudo-values :math:`\psi_b = BU - (B-1)U_{(-b)}` (``(B, J)``) average to
    :math:`U`; their covariance over blocks, divided by :math:`B`, is the jackknife
    variance of :math:`U`.  Unlike the Hoeffding projection
    :math:`\mathrm{Re}\sum_t\bar d^{*(-r)}_{tj}e_{rt}` it keeps the degenerate part of
    the statistic (weights and residuals of different blocks both random, and correlated
    within a block), which is not small when each block's weights are noisy, as for the
    trispectrum off the planes :math:`\omega_i + \omega_j = 0` (Efron & Stein 1981: the
    jackknife variance of a U-statistic errs, if at all, on the large side).
    """
    B = d.shape[0]
    dc = np.conj(d)
    D, E = dc.sum(axis=0), e.sum(axis=0)  # (n, J), (n,)
    cross = np.einsum("btj,bt->bj", dc, e)  # a block's own pairs
    full = np.einsum("tj,t->j", D, E) - cross.sum(axis=0)  # all pairs r != r'
    loo = (
        full[None] - np.einsum("tj,bt->bj", D, e) - np.einsum("btj,t->bj", dc, E) + 2.0 * cross
    )  # the pairs without block b
    U = full.real / (B * (B - 1))
    U_loo = loo.real / ((B - 1) * (B - 2))
    return B * U[None] - (B - 1) * U_loo


def restoration(state: RecordState, model: Model, pilot: np.ndarray) -> tuple[float, float]:
    """``(s2, eps)``: the velocity restoration at the pilot and the width at which
    generalized functions are regularized (at least 5 % of the velocity's sd).
    """
    s2 = Excitation(model, pilot, state.scales.sigma_v, state.scales.sigma_x).deficit(
        pilot, state.dt
    )
    if state.noise is not None:  # what the Wiener filter removed below the Nyquist frequency
        s2 += state.noise["extra_deficit"]
    return s2, max(math.sqrt(max(s2, 0.0)), 0.05 * state.scales.sigma_v)


def _feature(term, s2: float, eps: float, blocks: dict) -> np.ndarray:
    """A drift feature on the blocks, velocity features restored by ``s2``."""
    if term.variable == "v":
        return term.smoothed(blocks["v"], s2, eps)
    return term.phi(blocks["x"])


def feature_ffts(
    state: RecordState, model: Model, s2: float, bins: np.ndarray, window=None
) -> np.ndarray:
    r"""Block transforms of :math:`\ddot x` and of every drift feature,
    ``(1 + n_drift, B, K)`` on ``bins`` (velocity features restored by :math:`s^2`), with
    the state's window or ``window``.
    """
    eps = max(math.sqrt(s2), 0.05 * state.scales.sigma_v)
    rows = [state.block_fft("a", lambda b: b["a"], bins, window)]
    for t in model.drift_terms:
        if t.variable == "v":
            key = (t.name, round(s2, 12), state.centred)
        else:
            key = (t.name, state.centred)
        rows.append(state.block_fft(key, partial(_feature, t, s2, eps), bins, window))
    return np.stack(rows)
