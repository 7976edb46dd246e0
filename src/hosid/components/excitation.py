r"""The excitation of a model: its spectral shape and the power it feeds the oscillator.

The force :math:`g` has the two-sided spectrum :math:`S_0L(\omega;\theta)` with

.. math:: L(\omega) = \frac{\omega_c^2}{\omega_c^2+\omega^2}\;
    \frac{1}{1 + \beta\,\omega^2/\omega_b^2}\;\mathbf 1\{|\omega| \le \omega_b\},

each factor present only with its term: the low-pass of ``coloured_excitation``
(:math:`\omega_c`) and the band of ``band_limited_excitation`` (its edge
:math:`\omega_b` and its in-band roll-off :math:`\beta \ge 0`, :math:`L(\omega_b^-) =
1/(1+\beta)`; flat for :math:`\beta = 0`).  White noise is :math:`L = 1`.

The generator identities (:mod:`hosid.components.identities`) need the force's
correlation with the state.  For white noise Itô's formula gives it exactly
(:math:`E[q'(\dot x)g] = \pi S_0E[q''(\dot x)]`, :math:`E[h(x)g] = 0`).  Otherwise, for
jointly Gaussian velocity, displacement and force (Stein's lemma),
:math:`E[q'(\dot x)g] = E[q''(\dot x)]\,E[\dot xg]` and :math:`E[h(x)g] = E[h'(x)]\,E[xg]`,
with :math:`E[\dot xg] = \pi S_0\rho` and :math:`E[xg] = \pi S_0\rho_x` the input-power
integrals (:func:`input_power`) of the equivalent linear system
:math:`H = 1/(k - \omega^2 + ic\omega)` at the pilot.

**As the sampled record sees it.**  The identities use the velocity in the band, restored
for the power above the Nyquist frequency :math:`\omega_N` by the model
(:func:`hosid.state.velocity_deficit`); the record resolves nothing of the force's shape up
there.  Both the input power and the restoration therefore take the force's low-pass
factors at :math:`\min(|\omega|, \omega_N)`: above the band the force is white at the
level :math:`L(\omega_N)`.  A corner far above the band then moves them by
:math:`O(1/\omega_c^2)`, as it moves the sampled record; with the continuous shape the
input power moved by :math:`-E[\partial g/\partial\dot x]/\omega_c` and the restoration
by :math:`-\pi S_0/\omega_c`, which cancel for linear damping only (for :math:`n_1\dot
x|\dot x|` the restored identities moved by :math:`a_1 + 3n_1E|\dot x|` against
:math:`a_1 + 2n_1E|\dot x|`), and the identities pulled a corner at 5 Cramer-Rao sd back
to white.  For a corner within the band the two shapes differ by :math:`L(\omega_N)
\approx \omega_c^2/\omega_N^2`.  A band-limited force's edge is kept as it is.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

import numpy as np

from ..model.excitation import Spectrum
from ..model.model import Model
from ..state import jet_deficit, velocity_deficit

__all__ = ["ROLLOFF_FLOOR", "Excitation", "input_power"]

#: Roll-offs below this are computed as this (a corner 1000 times above the edge).
ROLLOFF_FLOOR = 1e-6


class Excitation:
    """The excitation of ``model`` (module docstring), with its equivalent linear system
    frozen at ``pilot``; the spectrum itself is :class:`hosid.model.excitation.Spectrum`.
    """

    def __init__(self, model: Model, pilot: np.ndarray, sigma_v: float, sigma_x: float):
        self.model = model
        self.spectrum = Spectrum(model)
        self.i_S0 = model.index("S0")
        self.i_wc = model.index("wc") if model.has("wc") else None
        self.i_wb = model.index("wb") if model.has("wb") else None
        self.i_rb = model.index("rolloff") if model.has("rolloff") else None
        c = max(float(model.equivalent_damping(pilot, sigma_v)), 1e-6)
        k = (sigma_v / sigma_x) ** 2
        self.linear = (c, k)  #: the equivalent linear system (damping c, stiffness k)

    @property
    def white(self) -> bool:
        """Whether the force is white noise."""
        return self.spectrum.white

    @property
    def whitening(self) -> bool:
        """Whether the identities whiten the force exactly (a rational shaping filter)."""
        return self.spectrum.whitening

    @property
    def shape_indices(self) -> tuple[int, ...]:
        """The parameters the in-band shape sees."""
        return self.spectrum.shape_indices

    def S0(self, theta: np.ndarray) -> np.ndarray:
        """The level :math:`S_0`."""
        return self.spectrum.S0(theta)

    def _corners(self, theta) -> list[np.ndarray]:
        r"""The low-pass corners of :math:`L`: :math:`\omega_c` and
        :math:`\omega_b/\sqrt\beta`, each ``theta.shape[:-1]`` (Stein path).
        """
        th = np.asarray(theta, dtype=float)
        out = [] if self.i_wc is None else [th[..., self.i_wc]]
        if self.i_rb is not None:
            beta = np.maximum(th[..., self.i_rb], ROLLOFF_FLOOR)
            out.append(th[..., self.i_wb] / np.sqrt(beta))
        return out

    def shape(self, omega: np.ndarray, theta: np.ndarray) -> np.ndarray:
        r""":math:`L(\omega)` for each ``theta``, shape ``theta.shape[:-1] + omega.shape``."""
        return self.spectrum.shape(omega, theta)

    def lowpass(self, omega: np.ndarray, theta: np.ndarray) -> np.ndarray:
        """The in-band factors of :math:`L` (its shape without the band's edge)."""
        return self.spectrum.lowpass(omega, theta)

    def inverse_shape(self, omega: np.ndarray) -> list[tuple[np.ndarray, Callable]]:
        r""":math:`1/L(\omega;\theta) = \sum_kb_k(\omega)\,c_k(\theta)` inside the band:
        ``[(b_k, c_k)]`` with :math:`b_k = \omega^{2k}` (so that a spectral component sums
        its bins once per basis function).
        """
        w2 = np.asarray(omega, dtype=float) ** 2
        n = len(self.spectrum.inverse_poly(np.ones(len(self.model.param_names))))
        return [(w2**k, lambda th, k=k: self.spectrum.inverse_poly(th)[k]) for k in range(n)]

    def shape_derivatives(
        self, omega: np.ndarray, theta: np.ndarray
    ) -> list[tuple[int, np.ndarray]]:
        r""":math:`\partial\log L/\partial\theta_i` in the band for the shape parameters
        the spectrum sees (not a band's edge), at one ``theta``.
        """
        return self.spectrum.log_shape_gradient(omega, theta)

    def powers(self, theta: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
        r"""The input-power ratios :math:`\rho = E[\dot xg]/\pi S_0` (1 for white noise)
        and :math:`\rho_x = E[xg]/\pi S_0` (0 for white noise) for each ``theta``, of the
        force as a record sampled at ``dt`` sees it (module docstring): its shape in the
        band and, up to the edge if any, white at :math:`L(\omega_N)` above it.  A
        whitening filter is exact in the identities (:mod:`hosid.components.identities`):
        1 and 0.
        """
        th = np.asarray(theta, dtype=float)
        if self.white or self.whitening:
            return np.ones(th.shape[:-1]), np.zeros(th.shape[:-1])
        wN = math.pi / dt
        wb = np.inf if self.i_wb is None else th[..., self.i_wb]
        inside = input_power(*self.linear, corners=self._corners(th), wb=np.minimum(wb, wN))
        level = self.lowpass(np.asarray(wN), th)  # the shape's top, held above the band
        full = input_power(*self.linear, wb=None if self.i_wb is None else wb)
        band = input_power(*self.linear, wb=wN)
        above = np.asarray(wb) > wN
        return tuple(
            r_in + np.where(above, level * (r_all - r_band), 0.0)
            for r_in, r_all, r_band in zip(inside, full, band, strict=True)
        )

    def deficit(self, theta: np.ndarray, dt: float) -> float:
        """The velocity restoration :math:`s^2` at one ``theta`` (:mod:`hosid.state`), of
        the force as the sampled record sees it (module docstring; a whitening filter's
        own shape, as the identities of the augmented state need it).
        """
        S0 = float(self.S0(theta))
        if self.white:
            return float(velocity_deficit(S0, dt))
        th = np.asarray(theta, dtype=float)
        if self.whitening:
            return float(velocity_deficit(S0, dt, lambda w: self.lowpass(w, th)))
        wN = math.pi / dt

        edge = np.inf if self.i_wb is None else float(th[self.i_wb])

        def seen(w):
            w = np.asarray(w, dtype=float)
            return self.lowpass(np.clip(w, -wN, wN), th) * (np.abs(w) <= edge)

        return float(velocity_deficit(S0, dt, seen))

    def jet_deficit(self, theta: np.ndarray, dt: float) -> np.ndarray:
        """The covariance of what the sampled jet ``(x, v, a, a')`` lacks at one
        ``theta`` (:func:`hosid.state.jet_deficit`), up to the whitening order + 1.
        """
        th = np.asarray(theta, dtype=float)
        return jet_deficit(
            float(self.S0(th)), dt, lambda w: self.lowpass(w, th), self.spectrum.order + 1
        )


def input_power(c, k, *, corners: Sequence = (), wb=None) -> tuple[np.ndarray, np.ndarray]:
    r"""The input-power integrals of a linear system driven by a force of shape L.

    For :math:`H = 1/(k - \omega^2 + ic\omega)`,

    .. math:: \rho = \frac1\pi\int_{-\omega_b}^{\omega_b}\mathrm{Re}[i\omega H]\,L\,
        d\omega, \qquad \rho_x = \frac1\pi\int_{-\omega_b}^{\omega_b}
        \mathrm{Re}[H]\,L\,d\omega,

    with :math:`L = \prod_m\omega_m^2/(\omega_m^2 + \omega^2)` over the low-pass
    ``corners`` (none: 1) and :math:`\omega_b = \infty` unless ``wb`` is given (white: 1
    and 0; one low-pass: :math:`\omega_c^2/(\omega_c^2 + c\omega_c + k)` and
    :math:`\omega_c/(\omega_c^2 + c\omega_c + k)`; a band :math:`\omega_b \gg \sqrt k`:
    :math:`1 - 2c/\pi\omega_b` and :math:`2/\pi\omega_b`).  Exact, by partial fractions:
    the integrand is :math:`N(\omega)/\prod_j(\omega - q_j)` with simple poles
    :math:`q_j` off the real axis (the roots of :math:`k - \omega^2 + ic\omega` and
    :math:`\pm i\omega_m`), so :math:`\int_0^W = \sum_jr_j[\mathrm{Log}(W - q_j) -
    \mathrm{Log}(-q_j)]`, :math:`r_j = N(q_j)/\prod_{i \ne j}(q_j - q_i)` (the path of
    :math:`\omega - q_j` stays in one half-plane); the real part is even in
    :math:`\omega`.  Arrays broadcast.
    """
    c = np.asarray(c, dtype=float)
    k = np.asarray(k, dtype=float)
    d = np.sqrt((k - 0.25 * c**2).astype(complex))
    # a double pole (critical damping): split it by 1e-5 sqrt(k), an O(1e-10) change
    tiny = 1e-5 * np.sqrt(np.abs(k))
    d = np.where(np.abs(d) < tiny, tiny + 0j, d)
    poles = [0.5j * c + d, 0.5j * c - d]
    scale = -1.0
    for wm in corners:
        wm = np.asarray(wm, dtype=float)
        poles += [1j * wm, -1j * wm]
        scale = scale * wm**2
    W = np.inf if wb is None else np.asarray(wb, dtype=float)
    finite = np.isfinite(W)
    Wf = np.where(finite, W, 1.0)
    rho, rho_x = 0.0, 0.0
    for j, qj in enumerate(poles):
        den = 1.0
        for i, qi in enumerate(poles):
            if i != j:
                den = den * (qj - qi)
        end = np.where(finite, np.log(Wf - qj), 0.0)  # at infinity the logs cancel
        term = scale / den * (end - np.log(-qj))
        rho = rho + 1j * qj * term  # numerator i w (the velocity)
        rho_x = rho_x + term  # numerator 1 (the displacement)
    return 2.0 / math.pi * np.real(rho), 2.0 / math.pi * np.real(rho_x)
