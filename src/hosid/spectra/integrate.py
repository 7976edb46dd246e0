r"""Velocity and displacement from an acceleration channel, in the band where it informs.

**The measured acceleration.**  A channel declared ``acceleration`` holds
:math:`\hat a_n = \bar a_n + e_n`: the response's acceleration averaged over the sample
interval centred on :math:`t_n` (:mod:`hosid.model.chain`),

.. math:: \bar a_n = \frac{\dot x(t_n + \Delta t/2) - \dot x(t_n - \Delta t/2)}{\Delta t},

and the sensor's noise and drift :math:`e`, whose spectrum :math:`N(\omega)` does not
grow towards higher frequencies in the low band (white noise, flicker noise, a random
walk or a drift).  Integrated twice, the spectrum of the displacement recovered from
:math:`\hat a` is :math:`S_x(\omega) + N(\omega)/\omega^4`: the signal tends to the
static level :math:`S_x(0)` while the integrated noise grows without bound as
:math:`\omega \to 0`, so below some frequency the double integral of the noise and the
drift dominates and the displacement there is unknown.

**The band** :math:`[\omega_L, \omega_N)`.  Its lower edge is read off the record's
acceleration spectrum :math:`\hat S` (Welch: half-overlapping Hann blocks of :math:`M`
samples inside the segments, :math:`M` the longest power of two leaving 8 blocks, each
block's straight line fitted with the window's weights removed, so that a sensor's
offset or drift does not leak through the window's main lobe; then a running mean over
:math:`\lceil 64/B\rceil` bins, as :mod:`hosid.spectra.response`).  From the spectrum's
peak :math:`\omega_a` (sought from the 4th bin on, :data:`FIRST_BIN`; a peak there is
drift, not a response, and an error) towards lower frequencies, :math:`\hat S` falls as
:math:`\omega^4 S_x` until it reaches the floor :math:`F = \min_{\omega \le
\omega_a}\hat S` (the lowest bins for a record without noise).  :math:`\omega_L` is the
first frequency above the floor's :math:`\omega_F` at which

.. math:: \hat S(\omega) \ge G\,F, \qquad G = 10\ (:data:`BAND_RISE`)

(for one mode the lowest of the run of bins ending at :math:`\omega_a`; a lower mode
between the floor and the peak is in the band).  A lower mode below the floor's
frequency, a local peak that rises :math:`G` times above the least ordinate below it,
takes the peak's place, and so on down: the band starts below the lowest mode that
stands out of its floor, not in the valley between two modes when a higher one is the
larger (a chain's floor moving most in its second mode).

Since :math:`N` does not grow with frequency and :math:`N(\omega_F) \le \hat S(\omega_F)
= F` at the floor's frequency :math:`\omega_F < \omega_L`, every frequency of the band
has :math:`N(\omega) \le F \le \hat S(\omega)/G`: the noise's share of the acceleration,
velocity and displacement spectra alike (integration divides signal and noise by the
same :math:`\omega^2`) is at most :math:`1/G = 10\ \%` at every frequency of the band
(up to the estimate's own scatter, 12 % sd an ordinate: a white noise's floor is read
0.6-1 times its level), and the integrated noise's displacement variance is at most
:math:`2\int_{\omega_L}^\infty F\omega^{-4}\,d\omega = 2F/(3\omega_L^3)`.
Without noise the floor is at the lowest bins, where :math:`\hat S \propto \omega^4`,
and :math:`\omega_L \approx G^{1/4}` times the lowest bin frequency
:math:`2\pi/(M\Delta t)`.  The rule is deterministic: the same samples give the same
edge.

**Integration.**  Each segment is integrated on its own, in the frequency domain over
its whole length (:math:`\omega_k = 2\pi k/(n\Delta t)`): with :math:`A_k` the DFT of
the segment,

.. math:: V_k = \frac{A_k}{i\omega_k\,\mathrm{sinc}(\omega_k\Delta t/2)}, \qquad
    X_k = \frac{V_k}{i\omega_k}, \qquad \omega_L \le \omega_k < \omega_N,

and zero elsewhere (the mean, the bins below the band, the Nyquist bin).  The
:math:`\mathrm{sinc}(u) = \sin u/u` corrects the interval average: for a velocity
band-limited below :math:`\omega_N`, :math:`\bar a` is its centred difference, whose
transfer function :math:`2i\sin(\omega\Delta t/2)/\Delta t = i\omega\,\mathrm{sinc}
(\omega\Delta t/2)` the division inverts exactly (a gain of 1.11 at half the Nyquist
frequency, 1.004 at a tenth).  A point-sampling accelerometer (an instantaneous value
behind an anti-alias filter) is integrated with ``boxcar=False``.  Dropping the mean is
removing the straight line through the velocity's end points (whose periodic extension
is then continuous): the DFT of :math:`\dot x` minus that line is exactly
:math:`A_k/(i\omega_k\mathrm{sinc})` for :math:`k \ne 0`, and likewise for the
displacement, so the segment's ends do not leak a jump into the band; what remains is
the band edge's ringing within about :math:`2\pi/\omega_L` of a segment's ends
(:attr:`Integration.margin`: on 400 s of a simulated oscillator with its edge at 0.3
rad/s, 0.3-0.5 of the displacement's sd in the first and last 10 s, a few per cent beyond
20 s).

**What no integration restores.**  The displacement at the sample times also depends on
the velocity's path inside each interval, which :math:`\bar a` averages away: under a
white force of level :math:`S_0` (mass 1) the sampled displacement differs from the
integral of :math:`\bar a` by a random walk of increment variance
:math:`2\pi S_0\Delta t^3/12` a sample, a spectrum :math:`S_0\Delta t^2/(12\omega^2)`
(the trapezoid rule's error on a Brownian velocity), and the sampled velocity differs
from the integral by a white noise of spectrum :math:`S_0\Delta t^2/4` (the Brownian
bridge between the half-step velocities); a force band-limited below the Nyquist
frequency leaves neither.  They are not in the acceleration and the band rule cannot see
them; against :math:`S_x(0) = S_0/k^2` the displacement's share at :math:`\omega` is
:math:`k^2\Delta t^2/(12\omega^2)` (per unit mass; ``tests/test_integrate.py`` checks
both on a simulated oscillator).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ..errors import HosidInputError
from .blocks import windowed_fft
from .response import AVERAGES, _smooth
from .windows import get_window

__all__ = [
    "BAND_RISE",
    "FIRST_BIN",
    "Band",
    "Integration",
    "acceleration_band",
    "integrate_acceleration",
]

#: The band starts where the acceleration spectrum has risen to this multiple of its
#: low-frequency floor (module docstring): the noise's share in the band is at most 1/G.
BAND_RISE = 10.0
#: The peak of the acceleration spectrum is sought from this bin on (below: trend, drift).
FIRST_BIN = 4
#: Fewest blocks of the band's spectrum (the block length is the longest power of two
#: that leaves them).
BAND_BLOCKS = 8


@dataclass(frozen=True)
class Band:
    """The band of an acceleration record (module docstring); frequencies in rad/s."""

    omega_low: float  # the band's lower edge
    omega_nyquist: float
    floor: float  # F, the acceleration spectrum's low-frequency floor
    omega_floor: float  # where the floor is reached
    omega_peak: float  # the acceleration spectrum's peak
    omega: np.ndarray  # the spectrum's frequencies (bins 1 .. M/2 - 1)
    spectrum: np.ndarray  # the smoothed two-sided acceleration spectrum


@dataclass(frozen=True, eq=False)
class Integration:
    """Displacement and velocity integrated from an acceleration channel in its band."""

    displacement: np.ndarray
    velocity: np.ndarray
    acceleration: np.ndarray  # the measured acceleration in the band (not sinc-corrected)
    band: Band
    boxcar: bool
    n_segments: int
    #: the velocity's spectral derivative: the acceleration in the band with the interval
    #: average's sinc undone (what a displacement record's second derivative would be)
    corrected: np.ndarray | None = None

    @property
    def omega_low(self) -> float:
        """The band's lower edge (rad/s)."""
        return self.band.omega_low

    @property
    def margin(self) -> float:
        r"""Seconds at each end of a segment that carry the band edge's ringing,
        :math:`2\pi/\omega_L`.
        """
        return 2.0 * math.pi / self.band.omega_low

    def describe(self) -> str:
        """One sentence for the report."""
        b = self.band
        seg = f"{self.n_segments} segments each on its own" if self.n_segments > 1 else "whole"
        gain = "interval-average gain 1/sinc(w dt/2) corrected" if self.boxcar else "point samples"
        return (
            f"integrated above {b.omega_low:.3g} rad/s, where the acceleration spectrum has "
            f"risen to {BAND_RISE:g} times its floor {b.floor:.3g} (reached at "
            f"{b.omega_floor:.3g} rad/s), up to the Nyquist frequency {b.omega_nyquist:.4g} "
            f"rad/s ({seg}; {gain}; the first and last {self.margin:.3g} s of a segment "
            "carry the band edge's ringing)"
        )


def _bounds(n: int, bounds) -> list[tuple[int, int]]:
    return [(0, n)] if bounds is None else [(int(a), int(b)) for a, b in bounds]


def _weighted_line(blocks: np.ndarray, h: np.ndarray) -> np.ndarray:
    """Each block's straight line fitted with the window's weights ``h``: removed, it
    leaves the windowed block without mean or slope (an offset or a drift of the sensor
    would leak through the window's main lobe), and it is small for the derivative of a
    stationary response (an unweighted fit is not: its mean is the velocity's change
    over the block).
    """
    u = np.arange(blocks.shape[-1]) - (blocks.shape[-1] - 1) / 2.0
    basis = np.stack([np.ones_like(u), u])
    gram = (basis * h) @ basis.T
    coef = np.linalg.solve(gram, (basis * h) @ blocks.T)
    return (basis.T @ coef).T


def acceleration_band(
    a: np.ndarray, dt: float, *, bounds: Sequence[tuple[int, int]] | None = None
) -> Band:
    """The band of an acceleration record (module docstring).

    Parameters
    ----------
    a : ndarray
        Acceleration samples (segments one after the other).
    dt : float
        Sampling interval (s).
    bounds : sequence of (start, stop), optional
        The record's segments.

    Raises
    ------
    HosidInputError
        If no segment holds enough samples for the spectrum, if the record is constant,
        or if its spectrum is largest at the lowest frequencies (drift, not a response).
    """
    a = np.asarray(a, dtype=float)
    bounds = _bounds(a.size, bounds)
    longest = max(b - s for s, b in bounds)
    total = sum(b - s for s, b in bounds)
    M = 2 ** math.floor(math.log2(max(min(longest, 2 * total // (BAND_BLOCKS + 1)), 1)))
    if M < 8 * FIRST_BIN:
        raise HosidInputError(
            f"acceleration record too short for its band: longest segment {longest} samples"
        )
    blocks = np.concatenate(
        [
            np.lib.stride_tricks.sliding_window_view(a[s:b], M)[:: M // 2]
            for s, b in bounds
            if b - s >= M
        ]
    )
    win = get_window("hann")
    blocks = blocks - _weighted_line(blocks, win.samples(M))
    Y = windowed_fft(blocks, dt, win)[:, 1 : M // 2]
    P = np.mean(Y.real**2 + Y.imag**2, axis=0) / (2.0 * math.pi * M * dt * win.k2)
    S = _smooth(P, math.ceil(AVERAGES / blocks.shape[0]) | 1)
    omega = 2.0 * math.pi * np.arange(1, M // 2) / (M * dt)
    if not np.max(S) > 0:
        raise HosidInputError("the acceleration record is constant: there is nothing to integrate")
    first = FIRST_BIN - 1
    k_a = first + int(np.argmax(S[first:]))
    if k_a == first:
        raise HosidInputError(
            f"the acceleration spectrum is largest at its lowest frequencies "
            f"({omega[first]:.3g} rad/s and below): drift, not a response"
        )
    k_f, k_low = _run(S, k_a)
    while True:  # a lower mode below the floor, standing out of its own (docstring)
        peaks = [k for k in range(first + 1, k_f) if S[k - 1] <= S[k] >= S[k + 1]]
        k_b = max(peaks, key=lambda k: S[k], default=None)
        if k_b is None or S[k_b] < BAND_RISE * np.min(S[: k_b + 1]):
            break
        k_f, k_low = _run(S, k_b)
    F = float(S[k_f])
    return Band(
        omega_low=float(omega[k_low]),
        omega_nyquist=math.pi / dt,
        floor=F,
        omega_floor=float(omega[k_f]),
        omega_peak=float(omega[k_a]),
        omega=omega,
        spectrum=S,
    )


def _run(S: np.ndarray, k: int) -> tuple[int, int]:
    """The floor's bin below bin ``k`` and the band's first bin: the first above the floor
    at which the spectrum ``S`` has risen to :data:`BAND_RISE` times it (``k + 1`` if
    none).
    """
    k_f = int(np.argmin(S[: k + 1]))
    risen = np.flatnonzero(S[k_f : k + 1] >= BAND_RISE * S[k_f])
    return k_f, k_f + int(risen[0]) if risen.size else k + 1


def integrate_acceleration(
    a: np.ndarray,
    dt: float,
    *,
    bounds: Sequence[tuple[int, int]] | None = None,
    omega_low: float | None = None,
    boxcar: bool = True,
) -> Integration:
    """Velocity and displacement of an acceleration record in its band (module docstring).

    Parameters
    ----------
    a : ndarray
        Acceleration samples (segments one after the other).
    dt : float
        Sampling interval (s).
    bounds : sequence of (start, stop), optional
        The record's segments; each is integrated on its own.
    omega_low : float, optional
        The band's lower edge (rad/s); default :func:`acceleration_band`'s.
    boxcar : bool
        The samples are interval averages (hosid's acceleration channels); ``False`` for
        point samples.

    Returns
    -------
    Integration
        ``displacement``, ``velocity`` and the band-limited ``acceleration``, aligned
        with ``a``; the band and a description.

    Raises
    ------
    HosidInputError
        As :func:`acceleration_band`, or if ``omega_low`` is not positive and below the
        Nyquist frequency.
    """
    a = np.asarray(a, dtype=float)
    bounds = _bounds(a.size, bounds)
    band = acceleration_band(a, dt, bounds=bounds)
    if omega_low is not None:
        if not (0.0 < omega_low < band.omega_nyquist):
            raise HosidInputError(
                f"omega_low must be between 0 and the Nyquist frequency "
                f"{band.omega_nyquist:.4g} rad/s, got {omega_low!r}"
            )
        band = dataclasses.replace(band, omega_low=float(omega_low))
    x, v, acc, corrected = (np.zeros_like(a) for _ in range(4))
    for s, b in bounds:
        n = b - s
        w = 2.0 * math.pi * np.fft.rfftfreq(n, dt)
        A = np.fft.rfft(a[s:b])
        keep = (w >= band.omega_low) & (w < band.omega_nyquist * (1.0 - 1e-12))
        keep[0] = False
        A = np.where(keep, A, 0.0)
        gain = np.sinc(w * dt / (2.0 * math.pi)) if boxcar else np.ones_like(w)
        iw = 1j * np.where(keep, w * gain, 1.0)
        V = A / iw
        x[s:b] = np.fft.irfft(V / (1j * np.where(keep, w, 1.0)), n)
        v[s:b] = np.fft.irfft(V, n)
        acc[s:b] = np.fft.irfft(A, n)
        corrected[s:b] = np.fft.irfft(A / np.where(keep, gain, 1.0), n)
    return Integration(x, v, acc, band, bool(boxcar), len(bounds), corrected)


def integrate_in_time(
    a: np.ndarray,
    dt: float,
    *,
    omega_low: float,
    bounds: Sequence[tuple[int, int]] | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    r"""The state of an interval-averaged acceleration record at the half steps
    :math:`t_n + \Delta t/2`: displacement, velocity and acceleration above ``omega_low``.

    Since :math:`\bar a_n\Delta t = \dot x(t_n + \Delta t/2) - \dot x(t_n - \Delta t/2)`
    (module docstring), the running sum :math:`\Delta t\sum_{k\le n}\bar a_k` is the
    velocity at the half steps exactly, up to a constant, and the trapezoid sum of those
    velocities the displacement there, up to a line (and the trapezoid rule's random walk,
    of spectrum :math:`S_0\Delta t^2/12\omega^2`) and the trapezoid rule's gain: on the
    sampled velocity the sum's transfer function is :math:`\Delta t/(2i\tan u)`,
    :math:`u = \omega\Delta t/2`, against the integral's :math:`1/(i\omega)`, a gain
    :math:`u/\tan u \approx 1 - u^2/3`.  Subtracting :math:`\Delta t^2/12` times the
    acceleration (the Euler-Maclaurin correction of the trapezoid rule) leaves
    :math:`u/\tan u + u^2/3 = 1 - u^4/45 - \dots`: at 7 rad/s and :math:`\Delta t` =
    0.02 s the displacement's variance was 0.33 % short before, :math:`10^{-6}` after
    (uncorrected, the cubic spring between the masses of the 2-dof chain came out 2.6
    bound-sd high on 12 records from accelerations; corrected, 0.8).  Both are high-passed
    by a fourth-order Butterworth filter at ``omega_low`` run forwards and backwards (zero
    phase, gain :math:`(\omega/\omega_L)^8/(1 + (\omega/\omega_L)^8)`, polynomial trends
    of degree 3 removed), whose transients decay within a few :math:`1/\omega_L` of a
    segment's ends; the acceleration is the filtered velocity's spectral derivative
    (:func:`hosid.spectra.derivatives.derivatives`).  Unlike the Fourier integration of
    :func:`integrate_acceleration`, nothing here takes the segment to be periodic: a sharp
    edge there spreads the periodic extension's kink over the whole segment.  Each
    segment is integrated on its own.
    """
    from scipy import signal

    from .derivatives import derivatives

    a = np.asarray(a, dtype=float)
    sos = signal.butter(4, omega_low / (math.pi / dt), btype="highpass", output="sos")
    x, v, acc = (np.zeros_like(a) for _ in range(3))
    for s, b in _bounds(a.size, bounds):
        vel = dt * np.cumsum(a[s:b])
        vel -= vel.mean()
        disp = dt * np.concatenate([[0.0], np.cumsum(0.5 * (vel[1:] + vel[:-1]))])
        pad = min(b - s - 1, round(4.0 * 2.0 * math.pi / omega_low / dt))
        v[s:b] = signal.sosfiltfilt(sos, vel, padlen=pad)
        x[s:b] = signal.sosfiltfilt(sos, disp - disp.mean(), padlen=pad)
        acc[s:b] = derivatives(v[s:b], dt)[0]
        x[s:b] -= dt**2 / 12.0 * acc[s:b]  # the trapezoid rule's gain (docstring)
    return x, v, acc
