r"""The record turned once into the state every likelihood component reuses.

:class:`RecordState` holds the displacement (and its offset), one spectral derivative
of the whole record for velocity and acceleration, the block layout, the window and
the record's scales.  Velocity and acceleration are taken in the frequency domain,
:math:`\dot x = \mathcal F^{-1}[i\omega\,\mathcal F x]`,
:math:`\ddot x = \mathcal F^{-1}[-\omega^2\mathcal F x]` below the Nyquist frequency
:math:`\omega_N = \pi/\Delta t`, after removing the straight line through the end
points (its slope is added back to the velocity), on the remainder's sine series
(:func:`hosid.spectra.derivatives.derivatives`), so that the extension keeps the
record's slope at both ends.  A record in segments is differentiated segment by
segment, and its blocks lie inside the segments (:mod:`hosid.spectra.blocks`): no
statistic spans a gap.

A smooth state (a coloured force) holds the jerk too
(:func:`hosid.spectra.derivatives.smooth_derivatives`), whose error at a segment's end
is about its own sd and decays as :math:`1/k` over :math:`k` samples (6 records of the
ship-roll-like oscillator under a filter at its resonance: 1.2 sd at the end sample,
3 % at 10-30 samples, 1 % at 30-100).  Its blocks keep :data:`JERK_MARGIN` times the
end fits' length clear of each end (a segment shorter than the two margins holds no
block; a record with no longer one keeps its ends).  Without the margin the first
block's squared influence on the six identities of the augmented state
(:mod:`hosid.components.jets`, boundary terms in the jerk) was 1.1-7.0 times the mean
block's over 8 such records (the first identity's: 0.7 with it).

**The velocity above the band.**  A sampled record holds no velocity power above
:math:`\omega_N`, and its aliases put some back.  For an excitation spectrum
:math:`S_0L(\omega)` the displacement spectrum far above resonance is
:math:`S_0L(\omega)/\omega^4`, and the variance the spectral velocity lacks is

.. math::

    s^2 = S_0\int_{-\omega_N}^{\omega_N}\sum_{j\ne0}
        \Big[\frac{1}{(\omega+2j\omega_N)^2}-\frac{\omega^2}{(\omega+2j\omega_N)^4}\Big]
        L(\omega+2j\omega_N)\,d\omega
    = \frac{\pi^2}{6}\,\frac{S_0}{\omega_N}\quad(L = 1),

(:func:`velocity_deficit`; 1.5 % of :math:`E[\dot x^2]` at the paper's point, 4 % at
:math:`S_0 = 1000`).  The missing part is nearly independent of the velocity in the
band, so every statistic of a function :math:`h` of the velocity is restored as
:math:`h + \tfrac12 s^2 h''` (:mod:`hosid.components.identities`).  A simulated record
confirms the correction to 0.1 % for :math:`E|\dot x|^3`, :math:`E\dot x^4` and
:math:`E[x^2\dot x^2]`.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from .errors import HosidInputError
from .model.terms import Scales
from .record import Record
from .spectra.blocks import (
    BlockLayout,
    block_fft,
    choose_layout,
    distinct_bounds,
    inner_bounds,
    windowed_fft,
)
from .spectra.derivatives import (
    C_ALIAS,
    derivatives,
    jet_deficit,
    smooth_derivatives,
    velocity_deficit,
)
from .spectra.response import ResponseSpectrum, response_spectrum
from .spectra.tail import difference_gain, difference_periodogram
from .spectra.windows import Window, get_window

__all__ = [
    "C_ALIAS",
    "RecordState",
    "derivatives",
    "jet_deficit",
    "smooth_derivatives",
    "velocity_deficit",
]

#: End-fit lengths (an eighth of a period each) that a smooth state's blocks keep clear of
#: each end of a segment (module docstring).
JERK_MARGIN = 2


@dataclass(frozen=True, eq=False)
class RecordState:
    """A record prepared once (module docstring); build with :meth:`from_record`."""

    record: Record
    x: np.ndarray  # displacement, centred unless ``centred`` is False
    offset: float  # the record's mean
    v: np.ndarray
    a: np.ndarray
    layout: BlockLayout
    window: Window
    scales: Scales
    spectrum: ResponseSpectrum
    centred: bool = True
    noise: dict | None = None  # the noise floor and the filter's velocity loss, if denoised
    repeats: list | None = None  # per segment, (lag, r) if it repeats itself, else None
    j: np.ndarray | None = None  # the jerk (third derivative) of a smooth state
    _fft_cache: dict = field(default_factory=dict, repr=False)

    @classmethod
    def from_record(
        cls,
        record: Record,
        *,
        block_seconds: float | None = None,
        window: str = "hann",
        centred: bool = True,
        denoise: bool = False,
        smooth: bool = False,
    ) -> RecordState:
        """Derivatives, scales, response spectrum (:mod:`hosid.spectra.response`) and
        block layout of ``record``; with ``denoise`` the displacement is Wiener-filtered
        first (:func:`noise_floor`); with ``smooth`` (a coloured force, whose response is
        smooth) the derivatives up to the jerk are taken with :func:`smooth_derivatives`.

        Raises
        ------
        HosidInputError
            If the record is constant or too short for the blocks.
        """
        offset = float(np.mean(record.x))
        raw = xc = record.x - offset
        noise = None
        if denoise:
            xc, noise = noise_floor(xc, record.dt, bounds=record.bounds)
        v, a = (
            np.concatenate(d)
            for d in zip(*(derivatives(p, record.dt) for p in record.split(xc)), strict=True)
        )
        sigma_x, sigma_v = float(np.std(xc)), float(np.std(v))
        if not (sigma_x > 0 and sigma_v > 0 and math.isfinite(sigma_v / sigma_x)):
            raise HosidInputError("the record is constant: it has no response to identify")
        omega_n = sigma_v / sigma_x
        jerk = None
        if smooth:  # an eighth of a period at each end fits the end derivatives
            n_fit = round(2.0 * math.pi / omega_n / record.dt / 8.0)
            v, a, jerk = (
                np.concatenate(d)
                for d in zip(
                    *(smooth_derivatives(p, record.dt, n_fit) for p in record.split(xc)),
                    strict=True,
                )
            )
            sigma_v = float(np.std(v))
        # the landmarks of the record as measured: a Wiener-filtered record's acceleration
        # falls above the noise's edge as if its force stopped there
        spectrum = response_spectrum(raw, record.dt, sigma_v=sigma_v, bounds=record.bounds)
        distinct, repeats = distinct_bounds(xc, record.bounds)
        if smooth:  # blocks clear of the jerk's error at each end (module docstring)
            m = JERK_MARGIN * max(n_fit, 8)
            distinct = inner_bounds(distinct, m) or distinct
        layout = choose_layout(
            sum(b - a for a, b in distinct),
            record.dt,
            omega_n,
            block_seconds=block_seconds,
            bounds=distinct,
            bandwidth=spectrum.bandwidth,
        )
        win = get_window(window)
        top = spectrum.edge[0] if spectrum.edge else None
        level = _level(a, layout, win, omega_n, top)
        scales = Scales(sigma_x, sigma_v, level, record.dt, spectrum.edge)
        x = xc if centred else xc + offset
        return cls(
            record, x, offset, v, a, layout, win, scales, spectrum, centred, noise, repeats, jerk
        )

    def recentred(self, centred: bool) -> RecordState:
        """The same state with the displacement centred or as recorded."""
        if centred == self.centred:
            return self
        x = self.x - self.offset if centred else self.x + self.offset
        return dataclasses.replace(self, x=x, centred=centred, _fft_cache={})

    def repeat_note(self) -> str | None:
        """One sentence on the segments that repeat themselves, or ``None``."""
        found = [r for r in (self.repeats or []) if r is not None]
        if not found:
            return None
        lags = sorted({lag for lag, _ in found})
        sign = "antiperiodic (an odd periodic input)" if found[0][1] < 0 else "periodic"
        return (
            f"{len(found)} of {len(self.repeats)} segments repeat themselves after "
            f"{', '.join(map(str, lags))} samples (autocorrelation "
            f"{min(r for _, r in found):+.4f} to {max(r for _, r in found):+.4f}: {sign}); "
            "blocks are taken before the repeat only"
        )

    @property
    def dt(self) -> float:
        """Sampling interval (s)."""
        return self.record.dt

    @cached_property
    def blocks(self) -> dict[str, np.ndarray]:
        """``x``, ``v``, ``a`` (and ``j`` of a smooth state) cut into blocks, each
        ``(B, M)``.
        """
        keys = ("x", "v", "a") if self.j is None else ("x", "v", "a", "j")
        return {k: self.layout.take(getattr(self, k)) for k in keys}

    @cached_property
    def block_edges(self) -> tuple[np.ndarray, np.ndarray]:
        """First sample of every block and the sample one block length later (the next
        block's first), held inside the block's segment: the ends of the boundary terms
        of the generator identities.
        """
        first = self.layout.offsets
        stops = np.array([b for _, b in self.record.bounds])
        seg = np.searchsorted(np.array(self.record.segments), first, side="right") - 1
        return first, np.minimum(first + self.layout.M, stops[seg] - 1)

    def block_fft(self, key, signal_fn, bins: np.ndarray, window=None) -> np.ndarray:
        """Windowed block FFT of a signal built from the blocks, cached under ``key``.

        ``signal_fn(blocks) -> (B, M)``; the result is ``(B, len(bins))``; ``window``:
        the state's own (default) or another (e.g. ``"boxcar"``).
        """
        win = self.window if window is None else get_window(window)
        full = (key, bins.tobytes(), win.name)
        if full not in self._fft_cache:
            y = signal_fn(self.blocks)
            self._fft_cache[full] = windowed_fft(y, self.dt, win, bins)
        return self._fft_cache[full]

    def periodogram(self, key: str, bins: np.ndarray) -> np.ndarray:
        """Block-averaged two-sided spectrum of ``x``, ``v`` or ``a`` on ``bins``."""
        Y = self.block_fft(("spectrum", key), lambda b: b[key], bins)
        L = self.layout
        return np.mean(Y.real**2 + Y.imag**2, axis=0) / (2 * math.pi * L.T * self.window.k2)

    def describe(self) -> dict:
        """Scales and layout as plain numbers (for attrs and reports)."""
        s = self.scales
        return {
            "sigma_x": s.sigma_x,
            "sigma_v_band": s.sigma_v,
            "omega_n": s.omega_n,
            "omega_nyquist": s.omega_nyquist,
            "offset": self.offset,
            "centred": self.centred,
            **self.layout.as_dict(),
            "segments": self.record.n_segments,
            "repeating_segments": self.repeat_note(),
            "window": self.window.name,
            **self.spectrum.describe(),
        }


def noise_floor(x: np.ndarray, dt: float, *, bounds=None) -> tuple[np.ndarray, dict]:
    r"""Remove white measurement noise from a displacement record (Wiener filter).

    The whole-record periodogram of the second difference (:mod:`hosid.spectra.tail`:
    flat in the tail, so the resonance does not leak into it) is fitted on
    :math:`[6\omega_e, \omega_N)` (:math:`\omega_e = \sigma_{\dot x}/\sigma_x`) as
    :math:`|D|^2[A\sum_j(\omega + 2j\omega_N)^{-4} + N]` (the response's tail folded by
    the sampling, and the noise floor) by non-negative least squares in relative error.
    (The plain periodogram leaked a light resonance's power into a floor, and below
    :math:`6\omega_e` the tail's :math:`\omega^{-6}` term, absent from the fit, went into
    :math:`N`: on clean ship-roll records the noise came out at up to
    :math:`1.5\times10^{-3}`, 25 times a noise at 5 Cramer-Rao sd, and the filter took
    the tail away as if the force stopped there.)  The record is filtered with
    :math:`G = A\omega^{-4}/(A\omega^{-4} + N)` above :math:`3\omega_e`.  The
    velocity variance the filter removes from the response, net of the filtered noise
    it lets through,
    :math:`\Delta s^2 = 2\int_{3\omega_e}^{\omega_N}[(1 - G^2)A\omega^{-2} -
    G^2N\omega^2]\,d\omega`, is added to the restoration.

    Returns the filtered record and ``{"A", "N", "sd", "extra_deficit"}`` (``sd`` is
    :math:`\sqrt{2\pi N/\Delta t}`, the noise standard deviation).  A record in
    segments (``bounds``, :attr:`hosid.record.Record.bounds`) is filtered segment by
    segment, with one fit to the chunks of all their periodograms.
    """
    from scipy.optimize import nnls

    pieces = [x[a:b] for a, b in (bounds or [(0, x.size)])]
    v = np.concatenate([derivatives(p, dt)[0] for p in pieces])
    we = float(np.std(v) / np.std(x))
    wN = math.pi / dt
    chunks = []
    for p in pieces:
        w = 2.0 * np.pi * np.fft.rfftfreq(p.size - 2, dt)
        # the displacement's periodogram, through the difference's flat spectrum
        Pd = difference_periodogram(p[None, :], dt, slice(None))[0]
        P = Pd / np.maximum(difference_gain(w, dt), 1e-300)
        # average the periodogram over chunks of 64 neighbouring bins before the fit
        k = np.flatnonzero((w >= 6.0 * we) & (w < wN))
        width = 64 if k.size >= 256 else 1
        k = k[: (k.size // width) * width].reshape(-1, width)
        chunks.append((P[k].mean(axis=1), w[k].mean(axis=1)))
    Ps, ws = (np.concatenate(c) for c in zip(*chunks, strict=True))
    if Ps.size < 16:
        raise HosidInputError(
            "measurement_noise needs a spectral tail above 6 w_n: the sampling is too coarse"
        )
    tail = sum((ws + 2 * j * wN) ** -4.0 for j in range(-20, 21))  # the folded w^-4 tail
    coef, _ = nnls(np.stack([tail / Ps, 1.0 / Ps], axis=1), np.ones_like(Ps))
    A, N = float(coef[0]), float(coef[1])
    info = {"A": A, "N": N, "sd": math.sqrt(2 * math.pi * N / dt), "extra_deficit": 0.0}
    if N <= 0 or A <= 0:
        return x, info
    wg = np.linspace(3.0 * we, wN, 4001)
    g = A * wg**-4.0 / (A * wg**-4.0 + N)
    info["extra_deficit"] = float(
        2.0 * np.trapezoid((1 - g**2) * A * wg**-2.0 - g**2 * N * wg**2, wg)
    )
    out = []
    for p in pieces:
        w = 2.0 * np.pi * np.fft.rfftfreq(p.size, dt)
        G = np.ones_like(w)
        hf = w >= 3.0 * we
        G[hf] = A * w[hf] ** -4.0 / (A * w[hf] ** -4.0 + N)
        out.append(np.fft.irfft(np.fft.rfft(p) * G, p.size))
    return np.concatenate(out), info


def _level(
    a: np.ndarray, layout: BlockLayout, window: Window, omega_n: float, edge: float | None
) -> float:
    r"""A rough excitation level: the median acceleration periodogram on
    :math:`[3\omega_n, 5\omega_n]` (clipped to half the Nyquist frequency and below the
    excitation's edge), where the response acceleration follows the force; a scale for
    priors, not an estimator.
    """
    top = 0.5 * math.pi / layout.dt if edge is None else min(0.5 * math.pi / layout.dt, edge)
    bins = layout.bins(min(3 * omega_n, 0.5 * top), min(5 * omega_n, top), k_min=2)
    if bins.size == 0:
        bins = np.arange(2, layout.M // 2)
    Y = block_fft(a, layout, window, bins)
    P = np.mean(Y.real**2 + Y.imag**2, axis=0) / (2 * math.pi * layout.T * window.k2)
    level = float(np.median(P))
    if not (level > 0 and math.isfinite(level)):
        raise HosidInputError("the record has no acceleration spectrum to scale the priors")
    return level
