r"""Building blocks of the discrepancy measures (:mod:`hosid.check.measures`).

The drift of a parameter mapping, the potential of its restoring force, standardized
moments, and frequency-band splits with their third-order cross moments.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable, Mapping, Sequence

import numpy as np

from ..errors import HosidInputError
from ..model.terms import TERMS, DriftTerm

__all__ = [
    "Drift",
    "band_split",
    "bispectral_moments",
    "drift_function",
    "potential",
    "std_moments",
]

Drift = Callable[[np.ndarray, np.ndarray], np.ndarray]

_DRIFT_BY_PARAM: dict[str, DriftTerm] = {
    t.params[0]: t for t in TERMS.values() if isinstance(t, DriftTerm)
}
_ALL_PARAMS = frozenset(p for t in TERMS.values() for p in t.params)


def drift_function(params: Mapping[str, float]) -> Drift:
    r"""The drift :math:`\sum_k\theta_k\phi_k(x, \dot x)` of a parameter mapping.

    The coefficients of drift terms (``a1, n1, a2, n2, b2, mu, m``; the mean force
    enters as :math:`-m`) are used, the other parameters of the model (``S0, wc,
    noise_sd``) ignored.

    Raises
    ------
    HosidInputError
        On a key that is no model parameter.
    """
    unknown = set(params) - _ALL_PARAMS
    if unknown:
        raise HosidInputError(
            f"unknown parameter(s) {', '.join(sorted(unknown))}; valid: "
            f"{', '.join(sorted(_ALL_PARAMS))}"
        )
    parts = [(float(params[p]), t) for p, t in _DRIFT_BY_PARAM.items() if p in params]

    def drift(x: np.ndarray, v: np.ndarray) -> np.ndarray:
        x = np.asarray(x, dtype=float)
        v = np.asarray(v, dtype=float)
        out = np.zeros(np.broadcast_shapes(x.shape, v.shape))
        arg = {"x": x, "v": v, "1": np.ones_like(out)}
        for coef, term in parts:
            if coef != 0.0:
                out = out + coef * term.phi(arg[term.variable])
        return out

    return drift


def std_moments(y: np.ndarray) -> np.ndarray:
    """Skewness and excess kurtosis of ``y``."""
    y = y - y.mean()
    s2 = np.mean(y**2)
    return np.array([np.mean(y**3) / s2**1.5, np.mean(y**4) / s2**2 - 3.0])


def potential(x: np.ndarray, drift: Drift) -> np.ndarray:
    r""":math:`V(x) - \min V` with :math:`V = \int_0^x \mathrm{drift}(s, 0)\,ds`, by the
    trapezoidal rule on 2049 points spanning the record.
    """
    lo, hi = min(float(x.min()), 0.0), max(float(x.max()), 0.0)
    grid = np.linspace(lo, hi, 2049)
    k = np.asarray(drift(grid, np.zeros_like(grid)), dtype=float)
    V = np.concatenate([[0.0], np.cumsum(0.5 * (k[1:] + k[:-1]) * np.diff(grid))])
    V -= np.interp(0.0, grid, V)
    Vx = np.interp(x, grid, V)
    return Vx - min(float(V.min()), float(Vx.min()))


def band_split(y: np.ndarray, dt: float, edges: Sequence[float]) -> list[np.ndarray]:
    """``y`` split into frequency bands ``[edges[i], edges[i+1])`` by FFT masking."""
    F = np.fft.rfft(y)
    w = 2.0 * math.pi * np.fft.rfftfreq(y.size, dt)
    return [
        np.fft.irfft(np.where((w >= lo) & (w < hi), F, 0.0), y.size)
        for lo, hi in itertools.pairwise(edges)
    ]


def bispectral_moments(
    pieces: Sequence[tuple[np.ndarray, slice]], dt: float, edges: Sequence[float]
) -> np.ndarray:
    r"""Normalized third-order cross moments of frequency bands: integrals of the
    bispectrum over regions.

    With :math:`x = x_L + x_R + x_H + \dots` split into the bands ``edges``
    (below the resonance, around it, above it),
    :math:`c_{ABC} = E[x_A x_B x_C]/(\sigma_A\sigma_B\sigma_C)` for :math:`(A, B, C)` =
    ``LRR`` (difference interaction: the slow part of :math:`x` following the
    resonant amplitude, as a quadratic stiffness drives it), ``LLR``, ``HRR`` (sum
    interaction: the second harmonic) and ``HHR``.  All are 0 for a system symmetric
    under :math:`x \to -x`.  ``pieces`` are the record's segments ``(xc, body)``:
    each is split on its own and the moments pool the bodies.
    """
    split = [[b[body] for b in band_split(y, dt, edges)] for y, body in pieces]
    L, R, H = (np.concatenate([s[i] for s in split]) for i in range(3))
    sL, sR, sH = L.std(), R.std(), H.std()
    return np.array(
        [
            np.mean(L * R * R) / (sL * sR * sR),
            np.mean(L * L * R) / (sL * sL * sR),
            np.mean(H * R * R) / (sH * sR * sR),
            np.mean(H * H * R) / (sH * sH * sR),
        ]
    )
