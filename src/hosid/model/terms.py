r"""Model terms: one frozen dataclass per physical effect.

The general model is

.. math::

    \ddot x + \sum_{k\,\in\,\mathrm{drift}} \theta_k\,\phi_k(x, \dot x) = g(t),
    \qquad y_n = x(n\Delta t) + \epsilon_n,

where each *drift* term contributes one coefficient :math:`\theta_k` times a force
feature :math:`\phi_k` of the displacement or of the velocity alone (the mean force
:math:`m` is the feature :math:`-1`), :math:`g` is white noise of two-sided level
:math:`S_0` (:math:`R_g(\tau) = 2\pi S_0\,\delta(\tau)`, paper eqs 42-43) or, with
``coloured_excitation``, white noise through the low-pass
:math:`\dot g = \omega_c(w - g)`, with ``narrowband_excitation`` white noise through a
second-order shaping filter (a wave moment), and with ``band_limited_excitation`` a
force whose spectrum stops at :math:`\omega_b` (a multisine, a shaker's band); the
excitation's terms are in :mod:`hosid.model.excitation`; and
:math:`\epsilon_n \sim N(0, \sigma_\epsilon^2)` is measurement noise.  The force inferred
from a record is :math:`f = \ddot x + \sum_k\theta_k\phi_k` (eq 45 for the paper's four
drift terms).

A drift term knows its feature and its derivatives in its variable (generalized
functions are Gaussian-regularized at a width ``eps``: :math:`\delta(v) \to
N(v; 0, \epsilon^2)`), which is all the generator identities and the velocity
restoration of :mod:`hosid.components.identities` need.  Every term knows its default
priors, built from the scales of a record (:class:`Scales`), and how its parameters
enter the simulator.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np
from scipy import special

from .bandpass import BandpassExcitation
from .base import DriftTerm, Scales, Term, gauss
from .excitation import (
    BandLimitedExcitation,
    ColouredExcitation,
    ExcitationLevel,
    ImpulsiveExcitation,
    NarrowbandExcitation,
)
from .priors import Uniform

__all__ = [
    "CANDIDATES",
    "TERMS",
    "DriftTerm",
    "Scales",
    "Term",
]

SQRT_8_PI = math.sqrt(8.0 / math.pi)
SQRT_2_PI = math.sqrt(2.0 / math.pi)


@dataclass(frozen=True, repr=False)
class LinearDamping(DriftTerm):
    r"""Viscous damping :math:`a_1\dot x` (eq 40); :math:`a_1 \sim U(-4\omega_n, 4\omega_n)`."""

    name: ClassVar[str] = "linear_damping"
    params: ClassVar[tuple[str, ...]] = ("a1",)
    latex: ClassVar[str] = r"a_1\,\dot x"
    variable: ClassVar[str] = "v"

    def phi(self, u, order=0, eps=0.0):
        """``v``, 1, 0, 0."""
        u = np.asarray(u, dtype=float)
        return u if order == 0 else (np.ones_like(u) if order == 1 else np.zeros_like(u))

    def antiderivative(self, u):
        """``v^2 / 2``."""
        return 0.5 * np.asarray(u, dtype=float) ** 2

    def damping_factor(self, sigma_v):
        """1."""
        return 1.0

    def default_priors(self, scales):
        """``U(-4 w_n, 4 w_n)``."""
        return {"a1": Uniform(-4.0 * scales.omega_n, 4.0 * scales.omega_n)}


@dataclass(frozen=True, repr=False)
class QuadraticDamping(DriftTerm):
    r"""Quadratic damping :math:`n_1\dot x|\dot x|` (eq 40);
    :math:`|n_1| \le 4\omega_n/\sigma_{\dot x}`.
    """

    name: ClassVar[str] = "quadratic_damping"
    params: ClassVar[tuple[str, ...]] = ("n1",)
    latex: ClassVar[str] = r"n_1\,\dot x|\dot x|"
    variable: ClassVar[str] = "v"

    def phi(self, u, order=0, eps=0.0):
        r""":math:`v|v|`, :math:`2|v|`, :math:`2\,\mathrm{sign}\,v`, :math:`4\delta(v)`."""
        u = np.asarray(u, dtype=float)
        if order == 0:
            return u * np.abs(u)
        if order == 1:
            return 2.0 * np.abs(u)
        if order == 2:
            return 2.0 * np.sign(u)
        return 4.0 * gauss(u, eps)

    def antiderivative(self, u):
        """``|v|^3 / 3``."""
        return np.abs(np.asarray(u, dtype=float)) ** 3 / 3.0

    def smoothed(self, u, s2, eps=0.0):
        r"""Exact: :math:`(v^2 + s^2)(2\Phi(v/s) - 1) + 2vs\,\varphi(v/s)`."""
        u = np.asarray(u, dtype=float)
        if s2 <= 0:
            return u * np.abs(u)
        s = math.sqrt(s2)
        z = u / s
        return (u**2 + s2) * special.erf(z / math.sqrt(2)) + 2 * u * s * np.exp(
            -0.5 * z**2
        ) / math.sqrt(2 * math.pi)

    #: Width of the smooth test function under a coloured force, in velocity sd: at 0.1
    #: the identities of a narrow-band force lost 4 % of n1 (the sampled jet does not
    #: resolve the kink of sign v); at 0.3 and 0.6 they held it to 0.1-0.4 % (8 records).
    SMOOTH_WIDTH: ClassVar[float] = 0.5

    def smooth_test(self, u, order=0, scale=1.0):
        r"""The feature smoothed by a Gaussian of width :math:`w = 0.5\sigma_{\dot x}`
        (:attr:`SMOOTH_WIDTH`), :math:`\psi = E[(v + wZ)|v + wZ|]`, and its derivatives
        :math:`2v\,\mathrm{erf}(z/\sqrt2) + 4w\varphi(z)`,
        :math:`2\,\mathrm{erf}(z/\sqrt2)`, :math:`4\varphi(z)/w` (:math:`z = v/w`).
        """
        w = self.SMOOTH_WIDTH * scale
        u = np.asarray(u, dtype=float)
        z = u / w
        erf = special.erf(z / math.sqrt(2.0))
        pdf = np.exp(-0.5 * z**2) / math.sqrt(2.0 * math.pi)
        if order == 0:
            return self.smoothed(u, w * w)
        return (2.0 * u * erf + 4.0 * w * pdf, 2.0 * erf, 4.0 * pdf / w)[order - 1]

    def damping_factor(self, sigma_v):
        r""":math:`\sqrt{8/\pi}\,\sigma_{\dot x}` (eq 65)."""
        return SQRT_8_PI * sigma_v

    def default_priors(self, scales):
        """``U(-4 w_n / sigma_v, 4 w_n / sigma_v)``."""
        s = 4.0 * scales.omega_n / scales.sigma_v
        return {"n1": Uniform(-s, s)}


@dataclass(frozen=True, repr=False)
class CoulombFriction(DriftTerm):
    r"""Coulomb friction :math:`\mu\,\mathrm{sign}(\dot x)`;
    :math:`\mu \sim U(0, 2\omega_n\sigma_{\dot x})`.
    """

    name: ClassVar[str] = "coulomb_friction"
    params: ClassVar[tuple[str, ...]] = ("mu",)
    latex: ClassVar[str] = r"\mu\,\mathrm{sign}(\dot x)"
    variable: ClassVar[str] = "v"

    def phi(self, u, order=0, eps=0.0):
        r""":math:`\mathrm{sign}\,v`, :math:`2\delta`, :math:`2\delta'`, :math:`2\delta''`."""
        u = np.asarray(u, dtype=float)
        return np.sign(u) if order == 0 else 2.0 * gauss(u, eps, order - 1)

    def antiderivative(self, u):
        """``|v|``."""
        return np.abs(np.asarray(u, dtype=float))

    def smoothed(self, u, s2, eps=0.0):
        r"""Exact: :math:`\mathrm{erf}(v/\sqrt{2}s)`."""
        u = np.asarray(u, dtype=float)
        return np.sign(u) if s2 <= 0 else special.erf(u / math.sqrt(2.0 * s2))

    #: Width of the smooth test function, in velocity standard deviations: 0.3 keeps
    #: 65 % of the score's information about mu beyond what v and v|v| carry (a
    #: Gaussian velocity; 0.5 keeps 49 %, 0.1 86 %).  Measured over 10 records each of
    #: the independent simulator at mu = 5 CRB sd, the test's (D - 1)/k^2 rose from 0.68
    #: to 0.79 (paper, S0 = 100) and 0.80 to 0.93 (ship roll); at 0.12 the restoration of
    #: the sampled velocity fails on the paper oscillator (mu 1.6 times the estimate at
    #: 0.5 on the first three records).
    TEST_WIDTH: ClassVar[float] = 0.3

    def test(self, u, order=0, eps=0.0, scale=1.0):
        r"""A smooth stand-in for the score :math:`\mathrm{sign}\,v`:
        :math:`\psi = \tanh(v/w)`, :math:`w = 0.3\,\sigma_{\dot x}` (:attr:`TEST_WIDTH`).
        The exact score needs the velocity density at zero, which the sampled velocity
        blurs at the friction's kink (it underestimated :math:`\mu` by a quarter); any
        smooth :math:`\psi` keeps the identity exact.
        """
        w = self.TEST_WIDTH * scale
        z = np.tanh(np.asarray(u, dtype=float) / w)
        s2 = 1.0 - z**2
        return (z, s2 / w, -2.0 * s2 * z / w**2, (4.0 * s2 * z**2 - 2.0 * s2**2) / w**3)[order]

    def test_antiderivative(self, u, scale=1.0):
        r""":math:`w\log\cosh(v/w)`."""
        w = self.TEST_WIDTH * scale
        a = np.abs(np.asarray(u, dtype=float)) / w
        return w * (a + np.log1p(np.exp(-2.0 * a)) - np.log(2.0))

    def damping_factor(self, sigma_v):
        r""":math:`\sqrt{2/\pi}/\sigma_{\dot x}`."""
        return SQRT_2_PI / sigma_v

    def default_priors(self, scales):
        """``U(0, 2 w_n sigma_v)``."""
        return {"mu": Uniform(0.0, 2.0 * scales.omega_n * scales.sigma_v)}


@dataclass(frozen=True, repr=False)
class _Polynomial(DriftTerm):
    """A restoring term ``theta x^power``."""

    variable: ClassVar[str] = "x"
    power: ClassVar[int]

    def phi(self, u, order=0, eps=0.0):
        """``x^p`` or its derivatives."""
        u = np.asarray(u, dtype=float)
        p = self.power
        if order > p:
            return np.zeros_like(u)
        out = np.full_like(u, math.factorial(p) // math.factorial(p - order))
        for _ in range(p - order):  # products, not pow(): several times faster
            out *= u
        return out


@dataclass(frozen=True, repr=False)
class LinearStiffness(_Polynomial):
    r"""Linear stiffness :math:`a_2 x` (eq 40); :math:`a_2 \sim U(-2\omega_n^2, 4\omega_n^2)`."""

    name: ClassVar[str] = "linear_stiffness"
    params: ClassVar[tuple[str, ...]] = ("a2",)
    latex: ClassVar[str] = r"a_2\,x"
    power: ClassVar[int] = 1

    def default_priors(self, scales):
        """``U(-2 w_n^2, 4 w_n^2)``."""
        w2 = scales.omega_n**2
        return {"a2": Uniform(-2.0 * w2, 4.0 * w2)}


@dataclass(frozen=True, repr=False)
class CubicStiffness(_Polynomial):
    r"""Cubic stiffness :math:`n_2x^3` (eq 40);
    :math:`n_2 \sim U(-\omega_n^2/\sigma_x^2, 4\omega_n^2/\sigma_x^2)`.
    """

    name: ClassVar[str] = "cubic_stiffness"
    params: ClassVar[tuple[str, ...]] = ("n2",)
    latex: ClassVar[str] = r"n_2\,x^3"
    power: ClassVar[int] = 3

    def default_priors(self, scales):
        """``U(-w_n^2 / sigma_x^2, 4 w_n^2 / sigma_x^2)``."""
        s = scales.omega_n**2 / scales.sigma_x**2
        return {"n2": Uniform(-s, 4.0 * s)}


@dataclass(frozen=True, repr=False)
class QuadraticStiffness(_Polynomial):
    r"""Asymmetric stiffness :math:`b_2x^2` (paper section 6);
    :math:`|b_2| \le 2\omega_n^2/\sigma_x`.
    """

    name: ClassVar[str] = "quadratic_stiffness"
    params: ClassVar[tuple[str, ...]] = ("b2",)
    latex: ClassVar[str] = r"b_2\,x^2"
    power: ClassVar[int] = 2

    def default_priors(self, scales):
        """``U(-2 w_n^2 / sigma_x, 2 w_n^2 / sigma_x)``."""
        s = 2.0 * scales.omega_n**2 / scales.sigma_x
        return {"b2": Uniform(-s, s)}


@dataclass(frozen=True, repr=False)
class ExcitationMean(DriftTerm):
    r"""A constant mean force :math:`m` (:math:`\ddot x + \dots = g + m`: feature
    :math:`-1`); :math:`|m| \le 4\omega_n^2\sigma_x`.
    """

    name: ClassVar[str] = "excitation_mean"
    params: ClassVar[tuple[str, ...]] = ("m",)
    latex: ClassVar[str] = r"-m"
    variable: ClassVar[str] = "1"

    def phi(self, u, order=0, eps=0.0):
        """-1 (derivatives 0)."""
        u = np.asarray(u, dtype=float)
        return -np.ones_like(u) if order == 0 else np.zeros_like(u)

    def default_priors(self, scales):
        """``U(-4 w_n^2 sigma_x, 4 w_n^2 sigma_x)``."""
        s = 4.0 * scales.omega_n**2 * scales.sigma_x
        return {"m": Uniform(-s, s)}


@dataclass(frozen=True, repr=False)
class MeasurementNoise(Term):
    r"""White noise on the sampled displacement, :math:`y_n = x_n + \epsilon_n`;
    :math:`\sigma_\epsilon \sim U(0, \sigma_x/2)`.
    """

    name: ClassVar[str] = "measurement_noise"
    params: ClassVar[tuple[str, ...]] = ("noise_sd",)
    kind: ClassVar[str] = "observation"
    latex: ClassVar[str] = r"\epsilon_n \sim N(0, \sigma_\epsilon^2)"

    def default_priors(self, scales):
        """``U(0, sigma_x / 2)``."""
        return {"noise_sd": Uniform(0.0, 0.5 * scales.sigma_x)}


#: Every term by name, in the canonical order of a model's parameters (drift terms
#: first, as in eq 45: the paper model's parameters are ``a1, n1, a2, n2, S0``).
TERMS: dict[str, Term] = {
    t.name: t
    for t in (
        LinearDamping(),
        QuadraticDamping(),
        LinearStiffness(),
        CubicStiffness(),
        QuadraticStiffness(),
        CoulombFriction(),
        ExcitationMean(),
        ExcitationLevel(),
        ColouredExcitation(),
        BandLimitedExcitation(),
        NarrowbandExcitation(),
        BandpassExcitation(),
        ImpulsiveExcitation(),
        MeasurementNoise(),
    )
}

#: The candidate effects of the discrepancy workflow (NOTES.md), spelled exactly so.
CANDIDATES: tuple[str, ...] = (
    "quadratic_damping",
    "cubic_stiffness",
    "quadratic_stiffness",
    "coulomb_friction",
    "coloured_excitation",
    "narrowband_excitation",
    "impulsive_excitation",
    "excitation_mean",
    "measurement_noise",
)
