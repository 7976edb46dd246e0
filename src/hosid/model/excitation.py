r"""The excitation: its terms and the force spectrum they make (paper section 2.1).

The force :math:`g` has the two-sided spectrum

.. math:: S_g(\omega;\theta) = S_0\,L(\omega;\theta), \qquad
    \frac{1}{L(\omega)} = \prod_m \Lambda_m(\omega^2)\;\;\text{in the band},

a level :math:`S_0` (``excitation_level``, in every model: :math:`L = 1` is the white
force of paper section 4) times one factor per shape term, each the inverse of a
polynomial :math:`\Lambda_m` in :math:`\omega^2` (:meth:`ShapeTerm.inverse_poly`):

================================  ==================================================  ===
term                              :math:`1/L` factor                                  path
================================  ==================================================  ===
``coloured_excitation``           :math:`1 + \omega^2/\omega_c^2`                     Stein
``band_limited_excitation``       :math:`1 + \beta\omega^2/\omega_b^2`, zero above     Stein
                                  :math:`\omega_b`
``narrowband_excitation``         :math:`[(\omega_f^2 - \omega^2)^2 +                  whitening
                                  (2\zeta_f\omega_f\omega)^2]/\omega_f^4`
``measured_excitation``           a table :math:`1/\ell(\omega)`                        whitening
                                  (:mod:`hosid.model.measured`)
================================  ==================================================  ===

A *whitening* term is white noise through a rational (all-pole) filter,
:math:`g = H w` with :math:`1/H(s) = P(s) = \sum_m p_ms^m` (:meth:`ShapeTerm.operator`;
the second-order shaping filter of ship-roll practice,
:math:`P = 1 + 2\zeta_fs/\omega_f + s^2/\omega_f^2`, :math:`|P(i\omega)|^2 = 1/L`):
the generator identities of the augmented state (:mod:`hosid.components.identities`)
are then exact.  The other shapes reach the identities through the input power of the
equivalent linear system (Stein's lemma, :class:`hosid.components.excitation.Excitation`).

A non-Gaussian force keeps the white spectrum: ``impulsive_excitation``
(:class:`ImpulsiveExcitation`) is Poisson impulses of rate :math:`r` with Gaussian areas
of variance :math:`2\pi S_0/r`, whose fourth cumulant :math:`3(2\pi S_0)^2/r` (per unit
time) enters the generator identities and the inferred force's kurtosis
(:mod:`hosid.components.jumps`); white noise is :math:`r \to \infty`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from .base import Term
from .priors import LogUniform, Uniform

__all__ = [
    "BandLimitedExcitation",
    "ColouredExcitation",
    "ExcitationLevel",
    "ImpulsiveExcitation",
    "NarrowbandExcitation",
    "ShapeTerm",
    "Spectrum",
    "poly_product",
]


def poly_product(a: list, b: list) -> list:
    """The coefficients of the product of two polynomials (lists of broadcasting arrays)."""
    out = [0.0] * (len(a) + len(b) - 1)
    for i, ai in enumerate(a):
        for j, bj in enumerate(b):
            out[i + j] = out[i + j] + ai * bj
    return out


def squared_modulus(p: list) -> list:
    r"""The coefficients :math:`c_k` of :math:`|P(i\omega)|^2 = \sum_kc_k\omega^{2k}` for
    :math:`P(s) = \sum_mp_ms^m`: :math:`c_k = \sum_{m+n=2k}(-1)^{(m-n)/2}p_mp_n`.
    """
    M = len(p) - 1
    out = []
    for k in range(M + 1):
        acc = 0.0
        for m in range(M + 1):
            n = 2 * k - m
            if 0 <= n <= M:
                acc = acc + (-1.0) ** ((m - n) // 2) * p[m] * p[n]
        out.append(acc)
    return out


@dataclass(frozen=True, repr=False)
class ExcitationLevel(Term):
    r"""White-noise level :math:`S_0` (eqs 42-43), in every model;
    :math:`S_0 \sim \log U(\hat S_0/100, 100\hat S_0)`.
    """

    name: ClassVar[str] = "excitation_level"
    params: ClassVar[tuple[str, ...]] = ("S0",)
    kind: ClassVar[str] = "excitation"
    latex: ClassVar[str] = r"2\pi S_0\,\delta(\tau)"

    def default_priors(self, scales):
        """``logU(S0_hat / 100, 100 S0_hat)``."""
        return {"S0": LogUniform(scales.S0 / 100.0, 100.0 * scales.S0)}


@dataclass(frozen=True, repr=False)
class ShapeTerm(Term):
    """A factor of the force's spectral shape (module docstring)."""

    kind: ClassVar[str] = "excitation"
    #: exact generator identities through :meth:`operator` (else Stein's input power)
    whitening: ClassVar[bool] = False
    #: the parameters the in-band shape sees (not a band's edge)
    shape_params: ClassVar[tuple[str, ...]] = ()

    def inverse_poly(self, *values) -> list:
        r"""The factor's :math:`1/L` in the band as coefficients of :math:`\omega^{2k}`."""
        raise NotImplementedError  # pragma: no cover

    def operator(self, *values) -> list:
        """The whitening operator's coefficients :math:`p_m` of :math:`s^m`."""
        raise NotImplementedError  # pragma: no cover

    @property
    def order(self) -> int:
        """The whitening operator's order (its parameters' number)."""
        return len(self.params)

    def table(self, omega):
        """A tabulated factor of :math:`L` (``None``: the shape is :meth:`inverse_poly`'s)."""
        return None

    def factor(self, omega, *values):
        """A factor of :math:`L` beside :math:`1/`:meth:`inverse_poly` (``values`` the
        term's parameters, broadcasting against ``omega``; ``None``: none): the table.
        """
        return self.table(omega)


@dataclass(frozen=True, repr=False)
class ColouredExcitation(ShapeTerm):
    r"""The white force through a first-order low-pass,
    :math:`S_g = S_0\,\omega_c^2/(\omega_c^2+\omega^2)` (prior: :meth:`default_priors`).
    """

    name: ClassVar[str] = "coloured_excitation"
    params: ClassVar[tuple[str, ...]] = ("wc",)
    shape_params: ClassVar[tuple[str, ...]] = ("wc",)
    latex: ClassVar[str] = r"\frac{S_0\,\omega_c^2}{\omega_c^2 + \omega^2}"

    @staticmethod
    def shape(omega, wc) -> np.ndarray:
        r""":math:`L(\omega) = \omega_c^2/(\omega_c^2 + \omega^2)` (broadcasting)."""
        omega = np.asarray(omega, dtype=float)
        wc = np.asarray(wc, dtype=float)
        return wc**2 / (wc**2 + omega**2)

    def inverse_poly(self, wc):
        r""":math:`1 + \omega^2/\omega_c^2`."""
        return [np.ones_like(wc), np.asarray(wc, dtype=float) ** -2.0]

    def default_priors(self, scales):
        r""":math:`\omega_c \sim \log U(\omega_n/10, 100\,\omega_N)`, up to :math:`30\,\omega_b`
        under a band-limited excitation (a flat band is a corner far above its edge).  A
        corner above :math:`\omega_N` still shows in the sampled spectrum's top, by
        :math:`\omega_N^2/\omega_c^2` (:mod:`hosid.components.tail`); at :math:`100\omega_N`
        the force is white on any sampled band.
        """
        top = 100.0 * scales.omega_nyquist
        if scales.band_edge is not None:
            top = max(top, 30.0 * scales.band_edge[1])
        return {"wc": LogUniform(scales.omega_n / 10.0, top)}


@dataclass(frozen=True, repr=False)
class BandLimitedExcitation(ShapeTerm):
    r"""A force whose spectrum stops at :math:`\omega_b` and may roll off within its band,
    :math:`S_g = S_0\,\mathbf 1\{|\omega| \le \omega_b\}/(1 + \beta\omega^2/\omega_b^2)`
    (a multisine, a shaker's band; :math:`\beta = 0` is flat, the band's top is
    :math:`S_0/(1+\beta)`).  :math:`\omega_b \sim U` over the bracket of the record's
    excitation edge (:mod:`hosid.spectra.response`), or :math:`U(\omega_N/2, 2\omega_N)`
    when the record shows none; :math:`\beta \sim U(0, 9)`.

    Below the Nyquist frequency the edge leaves nothing to restore above it (the
    velocity restoration of :mod:`hosid.state` vanishes), and the force's power reaches
    the generator identities through the input-power integrals of
    :func:`hosid.components.excitation.input_power`.  (The roll-off is the same low-pass as
    ``coloured_excitation``'s, :math:`\omega_c = \omega_b/\sqrt\beta`, in a coordinate
    whose flat end is a finite bound: the posterior of :math:`\beta` is near Gaussian,
    where :math:`\log\omega_c` has a plateau up to its prior's bound.)
    """

    name: ClassVar[str] = "band_limited_excitation"
    params: ClassVar[tuple[str, ...]] = ("wb", "rolloff")
    shape_params: ClassVar[tuple[str, ...]] = ("rolloff",)
    latex: ClassVar[str] = (
        r"\frac{S_0\,\mathbf{1}\{|\omega| \le \omega_b\}}{1 + \beta\omega^2/\omega_b^2}"
    )

    def inverse_poly(self, wb, rolloff):
        r""":math:`1 + \beta\omega^2/\omega_b^2` (the edge is applied apart)."""
        return [np.ones_like(wb), np.asarray(rolloff, dtype=float) / np.asarray(wb) ** 2]

    def default_priors(self, scales):
        """``wb ~ U(edge bracket)`` or ``U(w_N / 2, 2 w_N)``; ``rolloff ~ U(0, 9)``."""
        lo, hi = scales.band_edge or (0.5 * scales.omega_nyquist, 2.0 * scales.omega_nyquist)
        return {"wb": Uniform(lo, hi), "rolloff": Uniform(0.0, 9.0)}


@dataclass(frozen=True, repr=False)
class NarrowbandExcitation(ShapeTerm):
    r"""White noise through the second-order shaping filter of ship-roll practice.

    .. math:: \ddot g + 2\zeta_f\omega_f\dot g + \omega_f^2g = \omega_f^2w, \qquad
        S_g = \frac{S_0\,\omega_f^4}{(\omega_f^2 - \omega^2)^2 +
        (2\zeta_f\omega_f\omega)^2}

    (level :math:`S_0` at :math:`\omega = 0`, a peak :math:`S_0/4\zeta_f^2` near
    :math:`\omega_f` when :math:`\zeta_f` is small; white noise is
    :math:`\omega_f \to \infty`).  Its whitening operator is
    :math:`P(s) = 1 + 2\zeta_fs/\omega_f + s^2/\omega_f^2`.
    :math:`\omega_f \sim \log U(\omega_n/10, 100\,\omega_N)`,
    :math:`\zeta_f \sim \log U(0.01, 4)`.
    """

    name: ClassVar[str] = "narrowband_excitation"
    params: ClassVar[tuple[str, ...]] = ("wf", "zf")
    shape_params: ClassVar[tuple[str, ...]] = ("wf", "zf")
    whitening: ClassVar[bool] = True
    latex: ClassVar[str] = (
        r"\frac{S_0\,\omega_f^4}{(\omega_f^2 - \omega^2)^2 + (2\zeta_f\omega_f\omega)^2}"
    )

    def operator(self, wf, zf):
        r""":math:`(1, 2\zeta_f/\omega_f, 1/\omega_f^2)`."""
        wf = np.asarray(wf, dtype=float)
        return [np.ones_like(wf), 2.0 * np.asarray(zf) / wf, wf**-2.0]

    def inverse_poly(self, wf, zf):
        r""":math:`1 + (4\zeta_f^2 - 2)\omega^2/\omega_f^2 + \omega^4/\omega_f^4`."""
        return squared_modulus(self.operator(wf, zf))

    def default_priors(self, scales):
        """``wf ~ logU(w_n / 10, 100 w_N)``, ``zf ~ logU(0.01, 1)``."""
        return {
            "wf": LogUniform(scales.omega_n / 10.0, 100.0 * scales.omega_nyquist),
            "zf": LogUniform(0.01, 1.0),
        }


@dataclass(frozen=True, repr=False)
class ImpulsiveExcitation(Term):
    r"""Poisson impulses: a white but non-Gaussian force (paper eqs 34-38, :math:`P_4 \ne 0`).

    .. math:: g(t) = \sum_iA_i\,\delta(t - t_i), \qquad t_i \sim \text{Poisson}(r),
        \quad A_i \sim N(0, 2\pi S_0/r),

    the flat spectrum :math:`S_0` of the white force with the fourth cumulant spectrum
    :math:`P_4 = 3(2\pi S_0)^2/(r(2\pi)^3)`: the excess kurtosis of the force averaged
    over a time :math:`\tau` is :math:`3/(r\tau)`, and white Gaussian noise is the limit
    :math:`r \to \infty`.  :math:`r \sim \log U(\omega_n/100, 300\,\omega_N)` (per
    second; at the top the force's kurtosis over a sample is 0.003).
    """

    name: ClassVar[str] = "impulsive_excitation"
    params: ClassVar[tuple[str, ...]] = ("rate",)
    kind: ClassVar[str] = "excitation"
    latex: ClassVar[str] = r"\sum_iA_i\delta(t - t_i),\ A_i \sim N(0, 2\pi S_0/r)"

    @staticmethod
    def area_variance(S0, rate):
        r"""The impulses' area variance :math:`\sigma_A^2 = 2\pi S_0/r`."""
        return 2.0 * np.pi * np.asarray(S0, dtype=float) / np.asarray(rate, dtype=float)

    def default_priors(self, scales):
        """``rate ~ logU(w_n / 100, 300 w_N)``."""
        return {"rate": LogUniform(scales.omega_n / 100.0, 300.0 * scales.omega_nyquist)}


class Spectrum:
    r"""The force spectrum :math:`S_0L(\omega;\theta)` of a model (module docstring), for
    parameter vectors ``theta`` of shape ``(..., p)`` in the model's layout; of a
    :class:`hosid.model.system.System`, the shape :math:`L` its driven dofs' forces share
    (its levels :math:`S_{0,d}` are :meth:`~hosid.model.system.System.levels`).
    """

    def __init__(self, model):
        names = model.param_names
        self.i_S0 = names.index("S0") if "S0" in names else None
        terms = getattr(model, "terms", None)
        terms = (model.excitation or ()) if terms is None else terms
        self.terms = [
            (t, tuple(names.index(p) for p in t.params)) for t in terms if isinstance(t, ShapeTerm)
        ]
        self.i_wb = names.index("wb") if "wb" in names else None
        self.shape_indices = tuple(names.index(p) for t, _ in self.terms for p in t.shape_params)
        if self.terms and "rate" in names:
            raise ValueError(
                "impulsive_excitation (a white spectrum) cannot be combined with "
                + ", ".join(t.name for t, _ in self.terms)
            )
        whitening = [t for t, _ in self.terms if t.whitening]
        if whitening and len(self.terms) > 1:
            raise ValueError(
                f"{whitening[0].name} cannot be combined with "
                + ", ".join(t.name for t, _ in self.terms if t is not whitening[0])
            )

    @property
    def white(self) -> bool:
        """Whether the force is white noise."""
        return not self.terms

    @property
    def whitening(self) -> bool:
        """Whether the shape is a whitening (rational all-pole) filter."""
        return any(t.whitening for t, _ in self.terms)

    @property
    def order(self) -> int:
        """The order :math:`M` of the whitening operator (0 unless :attr:`whitening`)."""
        return sum(t.order for t, _ in self.terms if t.whitening)

    def _values(self, theta, idx):
        th = np.asarray(theta, dtype=float)
        return [th[..., i] for i in idx]

    def S0(self, theta) -> np.ndarray:
        """The level :math:`S_0`."""
        return np.asarray(theta, dtype=float)[..., self.i_S0]

    def inverse_poly(self, theta, exclude: tuple[str, ...] = ()) -> list:
        r"""The coefficients :math:`c_k` of :math:`1/L = \sum_kc_k\omega^{2k}` in the band,
        each of shape ``theta.shape[:-1]`` (the factors of the terms ``exclude`` left out).
        """
        out = [np.ones(np.shape(theta)[:-1])]
        for t, idx in self.terms:
            if t.name in exclude:
                continue
            out = poly_product(out, t.inverse_poly(*self._values(theta, idx)))
        return [np.broadcast_to(c, np.shape(theta)[:-1]).astype(float) for c in out]

    def operator(self, theta) -> list:
        """The whitening operator's coefficients :math:`p_m` (``[1]`` without one)."""
        out = [np.ones(np.shape(theta)[:-1])]
        for t, idx in self.terms:
            if t.whitening:
                out = poly_product(out, t.operator(*self._values(theta, idx)))
        return [np.broadcast_to(p, np.shape(theta)[:-1]).astype(float) for p in out]

    def lowpass(self, omega, theta) -> np.ndarray:
        """:math:`L` without a band's edge, shape ``theta.shape[:-1] + omega.shape``."""
        w2 = np.asarray(omega, dtype=float) ** 2
        new = (...,) + (None,) * w2.ndim
        c = self.inverse_poly(theta)
        den = sum(ck[new] * w2**k for k, ck in enumerate(c))
        out = 1.0 / den
        for t, idx in self.terms:  # a measured shape's table, a band-pass's numerator
            tab = t.factor(omega, *(v[new] for v in self._values(theta, idx)))
            if tab is not None:
                out = out * tab
        return out

    def shape(self, omega, theta) -> np.ndarray:
        r""":math:`L(\omega)` for each ``theta``: :meth:`lowpass` cut at the band's edge."""
        omega = np.asarray(omega, dtype=float)
        out = self.lowpass(omega, theta)
        if self.i_wb is not None:
            th = np.asarray(theta, dtype=float)
            out = out * (np.abs(omega) <= th[(..., self.i_wb) + (None,) * omega.ndim])
        return out

    def log_shape_gradient(self, omega, theta) -> list[tuple[int, np.ndarray]]:
        r""":math:`\partial\log L/\partial\theta_i = -\sum_k\partial_ic_k\,\omega^{2k}/
        \sum_kc_k\omega^{2k}` in the band at one ``theta``, for the parameters the in-band
        shape sees (:math:`\partial_ic_k` by central differences of the polynomial, which is
        defined on either side of any value).
        """
        th = np.asarray(theta, dtype=float)
        w2 = np.asarray(omega, dtype=float) ** 2
        c = self.inverse_poly(th)
        den = sum(ck * w2**k for k, ck in enumerate(c))
        out = []
        for i in self.shape_indices:
            h = 1e-6 * max(abs(th[i]), 1e-3)
            up, dn = th.copy(), th.copy()
            up[i] += h
            dn[i] -= h
            cu, cd = self.inverse_poly(up), self.inverse_poly(dn)
            num = sum(
                (u - d) / (2 * h) * w2**k for k, (u, d) in enumerate(zip(cu, cd, strict=True))
            )
            out.append((i, -num / den))
        return out
