r"""The base classes of model terms and the scales of a record they are built from.

A drift term knows its feature and its derivatives in its variable (generalized
functions are Gaussian-regularized at a width ``eps``: :math:`\delta(v) \to
N(v; 0, \epsilon^2)`), its test function for the generator identity, and the smoothing
by the velocity power a sampled record lacks.  The concrete effects are in
:mod:`hosid.model.terms`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from .priors import Prior

__all__ = ["DriftTerm", "Scales", "Term", "gauss"]


@dataclass(frozen=True)
class Scales:
    r"""Scales of a record that default priors and settings are built from.

    ``sigma_x``, ``sigma_v``: standard deviations of displacement and velocity;
    ``S0``: a rough excitation level; ``dt``: sampling interval (s); ``band_edge``: the
    bracket (rad/s) of the frequency where the record's excitation stops, if it stops
    below the Nyquist frequency (:mod:`hosid.spectra.response`).
    """

    sigma_x: float
    sigma_v: float
    S0: float
    dt: float
    band_edge: tuple[float, float] | None = None

    @property
    def omega_n(self) -> float:
        r"""Equivalent natural frequency :math:`\sigma_{\dot x}/\sigma_x` (rad/s)."""
        return self.sigma_v / self.sigma_x

    @property
    def omega_nyquist(self) -> float:
        r""":math:`\pi/\Delta t` (rad/s)."""
        return math.pi / self.dt


def gauss(u, eps, order=0):
    """Gaussian-regularized delta function and its first two derivatives."""
    u = np.asarray(u, dtype=float)
    g = np.exp(-0.5 * (u / eps) ** 2) / (eps * math.sqrt(2 * math.pi))
    if order == 0:
        return g
    if order == 1:
        return -u / eps**2 * g
    return (u**2 / eps**4 - 1 / eps**2) * g


# ----------------------------------------------------------------------- terms
@dataclass(frozen=True)
class Term:
    """One named effect (base class): ``name``, ``params``, ``kind``, ``latex``."""

    name: ClassVar[str]
    params: ClassVar[tuple[str, ...]]
    kind: ClassVar[str]  # "drift", "excitation" or "observation"
    latex: ClassVar[str]

    def default_priors(self, scales: Scales) -> dict[str, Prior]:  # pragma: no cover
        """Weakly informative priors from the record's scales."""
        raise NotImplementedError

    def simulated(self, params: dict) -> dict:
        """The simulator's parameters for ``params`` (the term's own, unless the
        simulator needs them in another form).
        """
        return params

    def __repr__(self) -> str:
        return f"<Term {self.name}: {', '.join(self.params)}>"


@dataclass(frozen=True, repr=False)
class DriftTerm(Term):
    r"""A drift term :math:`\theta\,\phi(u)` with ``variable`` :math:`u` = ``"x"``,
    ``"v"`` or ``"1"`` (a constant).
    """

    kind: ClassVar[str] = "drift"
    variable: ClassVar[str]

    def phi(self, u: np.ndarray, order: int = 0, eps: float = 0.0) -> np.ndarray:
        """The feature (``order = 0``) or its ``order``-th derivative in its variable."""
        raise NotImplementedError  # pragma: no cover

    def antiderivative(self, u: np.ndarray) -> np.ndarray:
        r""":math:`\int_0^u\phi` (velocity terms: the generator's test function)."""
        raise NotImplementedError  # pragma: no cover

    def smoothed(self, u: np.ndarray, s2: float, eps: float = 0.0) -> np.ndarray:
        r""":math:`E[\phi(u + sZ)]`, :math:`Z \sim N(0, 1)`, :math:`s^2` = ``s2``: the
        feature of a velocity blurred by the power the sampled record lacks (second order,
        :math:`\phi + \tfrac12s^2\phi''`, unless a term knows it exactly).
        """
        return self.phi(u) + 0.5 * s2 * self.phi(u, 2, eps)

    def test(self, u: np.ndarray, order: int = 0, eps: float = 0.0, scale: float = 1.0):
        r"""The test function :math:`\psi` of the term's generator identity, or its
        ``order``-th derivative: the feature itself (the score) unless a term needs a
        smooth one.  ``scale`` is the velocity's standard deviation.
        """
        return self.phi(u, order, eps)

    def smooth_test(self, u: np.ndarray, order: int = 0, scale: float = 1.0) -> np.ndarray:
        r"""A test function with three bounded derivatives (the identities of a coloured
        force differentiate it in time): :meth:`test` unless a term's has kinks.
        """
        return self.test(u, order, 0.0, scale)

    def test_antiderivative(self, u: np.ndarray, scale: float = 1.0) -> np.ndarray:
        r""":math:`\int_0^u\psi` (the boundary term :math:`G` of a velocity identity)."""
        return self.antiderivative(u)

    def damping_factor(self, sigma_v: float) -> float:
        """Equivalent linear damping per unit coefficient (eq 65), 0 if not damping."""
        return 0.0
