r"""The fits that weigh a candidate effect (:func:`hosid.check.evidence.weigh`): the
extended model ``model + effect`` in the effect's regular coordinate (:class:`Frame`), fitted
with the effect at its null and free (:func:`fits`; the rounds and weights of
:mod:`hosid.check.evidence`'s docstring).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..inference.estimate import estimate, log_params
from ..inference.gmm import Transformed, quasi_likelihood, solve
from ..inference.solutions import typical_scale
from ..model.coordinates import COORDINATES, Coordinate
from ..model.excitation import Spectrum
from ..model.model import Model
from .equations import components_for_test, null_moments, null_theta, record_state

__all__ = ["Frame", "fits"]


@dataclass
class Frame:
    """The extended model ``model + effect`` in the effect's regular coordinate ``u``
    (:data:`COORDINATES`): its parameters, the search's bounds and the maps from ``u``
    (and from the free parameters, the effect at its null) to the parameters.
    """

    effect: str
    ext: Model
    coord: Coordinate
    i: int  # the effect's parameter
    lower: np.ndarray
    upper: np.ndarray
    logs: list[int]  # the log-scaled parameters but the effect's
    support: dict
    state: Any

    @classmethod
    def of(cls, record, model, effect: str, states: dict) -> Frame:
        """The frame of ``model + effect`` on ``record`` (``states``: the record states'
        cache of :func:`hosid.check.equations.record_state`).
        """
        coord = COORDINATES[effect]
        ext = model.extended(effect)
        state = record_state(record, ext, states)
        names, i = ext.param_names, ext.index(coord.param)
        support = ext.default_priors(state.scales, constrained=False)
        lower = np.array([support[n].lower for n in names], dtype=float)
        upper = np.array([support[n].upper for n in names], dtype=float)
        lower[i], upper[i] = coord.bounds(support[coord.param].lower, support[coord.param].upper)
        logs = [k for k in log_params(ext) if k != i]
        return cls(effect, ext, coord, i, lower, upper, logs, support, state)

    @property
    def names(self) -> list[str]:
        """The extended model's parameters."""
        return list(self.ext.param_names)

    @property
    def free(self) -> list[int]:
        """The parameters but the effect's."""
        return [k for k in range(len(self.names)) if k != self.i]

    def to_theta(self, u):
        """The parameters of ``u`` (the effect in its regular coordinate)."""
        u = np.asarray(u, dtype=float)
        th = u.copy()
        th[..., self.i] = self.coord.to_param(u[..., self.i])
        return th

    def fixed(self, v):
        """The parameters of the free ones ``v``, the effect at its null."""
        return self.to_theta(np.insert(np.asarray(v, dtype=float), self.i, 0.0, axis=-1))

    def null_fit(self, q, start, scale):
        """The fit of ``q`` with the effect at its null: ``(J, free parameters)``."""
        free = self.free
        ql0 = Transformed.of(q, self.fixed)
        v = solve(
            ql0, start, log_params=[free.index(k) for k in self.logs],
            scale=0.1 * scale[free], lower=self.lower[free], upper=self.upper[free],
        )  # fmt: skip
        return float(-2.0 * ql0(v)), v


def fits(record, model, frame: Frame, start, rounds, states, covariance):
    """The null and free fits of ``frame`` (:func:`hosid.check.evidence.weigh`'s rounds):
    ``(u, ql, qlu, J0, scale)``, the free estimate in ``u``, its equations (in the
    parameters and in ``u``), the null fit's ``J`` and the search's scale.
    """
    ext, coord, i, free = frame.ext, frame.coord, frame.i, frame.free
    comps = components_for_test(model, frame.effect)
    u = null_theta(ext, coord, start).copy()
    u[i] = 0.0
    rounds = max(int(rounds), coord.rounds)
    ql = null = quasi_likelihood(
        null_moments(record, model, frame.effect, start, states),
        n_params=len(frame.names),
        covariance=covariance,
    )
    scale = typical_scale(ext, frame.state, frame.to_theta(u))
    scale[i] = max(abs(u[i]), 1e-3 * (frame.upper[i] - frame.lower[i]))
    J0, u[free] = frame.null_fit(null, u[free], scale)
    scale[i] = _own_sd(Transformed.of(null, frame.to_theta), u, i, scale[i])
    if coord.kind == "inverse_square":  # start coloured, as the fit does
        u[i] = frame.support[coord.param].upper ** -2.0
    qlu = Transformed.of(ql, frame.to_theta)
    if Spectrum(ext).whitening or ext.has("rate"):  # the fit's estimate (multi-start
        # for a filter's peak; the rate piloted by the force's kurtosis)
        found = estimate(frame.state, ext, comps, settle=False, simulations=0)
        u, ql, rounds = found.theta.copy(), found.ql, 0
        u[i] = coord.to_u(found.theta[i])
        qlu = Transformed.of(ql, frame.to_theta)
        J0, _ = frame.null_fit(ql, u[free], scale)
    for _ in range(rounds):
        if u[i] != 0.0:  # the equations and their weight at the current estimate
            ql = quasi_likelihood(
                [c.prepare(frame.state, ext, frame.to_theta(u)) for c in comps],
                n_params=len(frame.names),
                covariance=covariance,
            )
        qlu = Transformed.of(ql, frame.to_theta)
        u = solve(
            qlu, u, log_params=frame.logs, scale=0.1 * scale, lower=frame.lower,
            upper=frame.upper,
        )  # fmt: skip
    if coord.kind == "identity" and ql is not null:  # one weight: the free fit's
        J0, _ = frame.null_fit(ql, u[free], scale)
    return u, ql, qlu, J0, scale


def _own_sd(q: Transformed, u: np.ndarray, i: int, fallback: float) -> float:
    r"""The coordinate's sd from the null equations alone, :math:`1/\|\partial r/\partial
    u_i\|` (a forward difference from the null): the solver's scale.  A prior's width
    is no scale for a corner, whose information lives within :math:`10^{-6}` of a
    coordinate that ranges over :math:`1/\omega_{c,\min}^2`: scaled by the width, the
    free fit of a corner at 5 sd stayed at the null (``fallback`` when the equations do
    not move).
    """
    h = 1e-6 * fallback
    step = np.zeros_like(u)
    step[i] = h
    with np.errstate(all="ignore"):
        g = float(np.linalg.norm((q.residual(u + step) - q.residual(u)) / h))
    return min(fallback, 1.0 / g) if math.isfinite(g) and g > 0 else fallback
