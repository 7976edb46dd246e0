r"""What the response spectrum of a record says before any model is fitted.

The settings of a fit (block length, band of the spectral components) and the
excitation's band follow from the record's own displacement spectrum :math:`S_x`
(Welch, Hann blocks of :math:`M_0` samples inside the segments: the longest power of
two that leaves at least 8 blocks, then a running mean over :math:`\lceil 64/B_0\rceil`
bins so that every ordinate averages about 64 block periodograms), and from its
acceleration spectrum :math:`S_a = \omega^4S_x`, which far above resonance is the force
spectrum of a second-order system:

- the **resonance** :math:`\omega_p` (the peak of :math:`S_x`) and the **equivalent
  bandwidth** :math:`\Delta\omega = \sigma_x^2/(\pi\max S_x)` (for a lightly damped
  linear oscillator :math:`\Delta\omega = c`, the half-power width; a model-free width for
  any peak);
- the **force level** :math:`A`: the median of :math:`S_a` on
  :math:`[1.5\,\omega_n, 2.5\,\omega_n]` (:math:`\omega_n = \sigma_{\dot x}/\sigma_x`,
  kept below the edge and half the Nyquist frequency);
- the **excitation edge**: the first frequency above :math:`1.5\,\omega_n` from which
  :math:`S_a` stays below :math:`A/10` (at least 90 % of the bins above it): the
  excitation stops there (:data:`EDGE_DROP`).  The edge is bracketed by the last bin still
  at half the level and the first bin below a tenth of it, and must be a cliff: a fall by
  :data:`EDGE_CLIFF` within 7 % of its frequency on either side (a force through a
  shaping filter rolls off as :math:`\omega^{-4}`, by 1.5 there);
- the **noise floor** :math:`N`: the white floor of :math:`S_x`, from a non-negative
  least-squares fit :math:`S_a = A' + N\omega^4` on :math:`[1.5\,\omega_n, \omega_{top}]`
  or, above an edge, the median of :math:`S_x` there; the response falls into it at
  :math:`\omega_f = (A/N)^{1/4}`, where the force level equals the floor's acceleration.

A white excitation with no noise has no edge and no floor; the aliases lift
:math:`S_a` by 1 % at half the Nyquist frequency and double it at the Nyquist frequency,
which neither criterion mistakes for an edge or a floor.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ..errors import HosidInputError
from .blocks import BlockLayout, block_fft
from .windows import get_window

__all__ = ["EDGE_CLIFF", "EDGE_DROP", "ResponseSpectrum", "response_spectrum"]

#: The acceleration spectrum falls below the force level divided by this at an edge.
EDGE_DROP = 10.0
#: At an edge the acceleration spectrum falls by at least this factor from just below it
#: (0.9-0.97 of its frequency) to just beyond (1.03-1.1): a cliff.  A force through a
#: shaping filter rolls off as w^-4 there (a factor of 1.5), and its fall is the
#: filter's, not a band's edge (``narrowband_excitation``); band-limited forces fell by
#: more than 20 (simulated edges, flat and rolled off, and the Silverbox).
EDGE_CLIFF = 5.0
#: Periodograms each smoothed ordinate averages (blocks times neighbouring bins).
AVERAGES = 64


@dataclass(frozen=True)
class ResponseSpectrum:
    """The record's spectral landmarks (module docstring); frequencies in rad/s."""

    omega: np.ndarray  # bins 1 .. M0/2 - 1
    Sxx: np.ndarray  # smoothed two-sided displacement spectrum
    omega_n: float  # sigma_v / sigma_x
    peak: float
    bandwidth: float
    level: float  # force level A of S_a
    edge: tuple[float, float] | None  # bracket of the excitation edge
    floor: float  # white floor N of S_x (0: none seen)
    omega_nyquist: float

    @property
    def floor_edge(self) -> float:
        r"""Where the response falls into the floor, :math:`(A/N)^{1/4}` (inf: none)."""
        return (self.level / self.floor) ** 0.25 if self.floor > 0 else math.inf

    @property
    def band_limited(self) -> bool:
        """Whether the excitation stops below the Nyquist frequency."""
        return self.edge is not None

    def describe(self) -> dict:
        """The landmarks as plain numbers (attrs and reports)."""
        fe = self.floor_edge
        return {
            "resonance_rad_s": self.peak,
            "bandwidth_rad_s": self.bandwidth,
            "force_level": self.level,
            "excitation_edge_rad_s": list(self.edge) if self.edge else None,
            "noise_floor": self.floor,
            "floor_edge_rad_s": fe if math.isfinite(fe) else None,
        }

    def summary(self) -> str:
        """One sentence for the report."""
        s = (
            f"response spectrum: resonance {self.peak:.4g} rad/s, equivalent bandwidth "
            f"{self.bandwidth:.3g} rad/s"
        )
        if self.edge:
            s += (
                f"; the acceleration spectrum falls below a tenth of its level "
                f"{self.level:.3g} between {self.edge[0]:.4g} and {self.edge[1]:.4g} rad/s "
                f"(Nyquist {self.omega_nyquist:.4g}): the excitation is band-limited"
            )
        else:
            s += "; no excitation edge below the Nyquist frequency"
        fe = self.floor_edge
        if math.isfinite(fe) and fe < 10 * self.omega_nyquist:
            s += f"; the response meets the noise floor {self.floor:.3g} near {fe:.4g} rad/s"
        return s


def _smooth(P: np.ndarray, width: int) -> np.ndarray:
    """Running mean over ``width`` bins (fewer at the ends)."""
    if width <= 1:
        return P
    kernel = np.ones(width)
    return np.convolve(P, kernel, "same") / np.convolve(np.ones_like(P), kernel, "same")


def _edge(w, Sa, level, start) -> tuple[float, float] | None:
    """Bracket of the first sustained drop of ``Sa`` below ``level / EDGE_DROP``, if it
    is a cliff (:data:`EDGE_CLIFF`) and starts below 0.9 times the highest frequency
    (above it the cliff's far side is past the Nyquist frequency: a spectrum hovering at
    a tenth of the level, as a multi-dof channel's above its higher modes, ended in 3
    bins below it near the Nyquist frequency and was taken for an edge there).
    """
    low = Sa < level / EDGE_DROP
    top = 0.9 * w[-1]  # nearer the Nyquist frequency no cliff can be seen
    for k in np.flatnonzero(low & (w > start) & (w <= top)):
        if low[k:].mean() >= 0.9 and low[k:].size >= 3:
            above = np.flatnonzero((Sa[:k] >= 0.5 * level) & (w[:k] > start))
            lo = w[above[-1]] if above.size else w[max(k - 1, 0)]
            below = (w >= 0.9 * w[k]) & (w <= 0.97 * w[k])
            beyond = (w >= 1.03 * w[k]) & (w <= 1.1 * w[k])
            if below.any() and beyond.any():
                drop = np.median(Sa[below]) / max(np.median(Sa[beyond]), 1e-300)
                if drop < EDGE_CLIFF:  # a filtered force's roll-off, not an edge
                    return None
            return float(lo), float(w[k])
    return None


def response_spectrum(
    x: np.ndarray,
    dt: float,
    *,
    sigma_v: float,
    bounds: Sequence[tuple[int, int]] | None = None,
    noise_floor: bool = True,
) -> ResponseSpectrum:
    r"""The spectral landmarks of a centred displacement record (module docstring).

    Parameters
    ----------
    x : ndarray
        Centred displacement (segments one after the other).
    dt : float
        Sampling interval (s).
    sigma_v : float
        Standard deviation of the velocity (sets :math:`\omega_n = \sigma_v/\sigma_x`).
    bounds : sequence of (start, stop), optional
        The record's segments.
    noise_floor : bool
        Look for a white floor of :math:`S_x`; false for a displacement integrated from an
        acceleration, whose sensor's noise is flat in acceleration: what the test
        :math:`S_a = A' + N\omega^4` finds there is a chain's higher modes (a five-storey
        chain driven at the roof: a floor edge at 14.2 rad/s, between its second and
        third modes, that left its J2 band empty).

    Raises
    ------
    HosidInputError
        If no segment holds 16 samples.
    """
    x = np.asarray(x, dtype=float)
    bounds = [(0, x.size)] if bounds is None else [(int(a), int(b)) for a, b in bounds]
    longest = max(b - a for a, b in bounds)
    M = 2 ** math.floor(math.log2(max(min(longest, max(x.size // 8, 64)), 1)))
    if M < 16:
        raise HosidInputError(f"no segment of the record holds 16 samples (longest {longest})")
    starts = tuple(a + k * M for a, b in bounds for k in range((b - a) // M))
    layout = BlockLayout(M=M, B=len(starts), dt=dt, starts=starts)
    win = get_window("hann")
    Y = block_fft(x, layout, win)[:, 1 : M // 2]
    P = np.mean(Y.real**2 + Y.imag**2, axis=0) / (2 * math.pi * layout.T * win.k2)
    w = np.arange(1, M // 2) * layout.d_omega
    Sxx = _smooth(P, math.ceil(AVERAGES / layout.B) | 1)
    Sa = w**4 * Sxx
    var_x = float(np.var(x))
    wn, wN = sigma_v / math.sqrt(var_x), math.pi / dt
    k_peak = int(np.argmax(Sxx))
    ref = (w >= 1.5 * wn) & (w <= min(2.5 * wn, 0.5 * wN))
    if ref.sum() < 3:  # resonance close to the Nyquist frequency
        ref = w >= wn
    level = float(np.median(Sa[ref]))
    edge = _edge(w, Sa, level, 1.5 * wn)
    if edge is not None:
        ref = ref & (w < edge[0])
        if ref.sum() >= 3:
            level = float(np.median(Sa[ref]))
        above = w > 1.1 * edge[1]
        floor = float(np.median(Sxx[above])) if above.sum() >= 3 and noise_floor else 0.0
    elif noise_floor:
        from scipy.optimize import nnls

        fit = (w >= 1.5 * wn) & (w <= 0.5 * wN)
        floor = 0.0
        if fit.sum() >= 3:
            scale = w[fit] ** 4 / wN**4
            coef, _ = nnls(
                np.stack([np.ones(fit.sum()), scale], 1) / Sa[fit, None], np.ones(fit.sum())
            )
            floor = float(coef[1] / wN**4)
    else:
        floor = 0.0
    return ResponseSpectrum(
        omega=w,
        Sxx=Sxx,
        omega_n=wn,
        peak=float(w[k_peak]),
        bandwidth=var_x / (math.pi * float(Sxx[k_peak])),
        level=level,
        edge=edge,
        floor=floor,
        omega_nyquist=wN,
    )
