r"""The force's level above the J2 band: :math:`S_0` from every sampled frequency.

Far above the resonance the inferred force :math:`X = \ddot x + g` (eq 45) is the
excitation itself, and each periodogram ordinate measures its level.  J2 (a Hann window,
up to :math:`6\,\omega_n`, :mod:`hosid.components.spectral`) uses a small share of the
record's ordinates; the rest, up to the Nyquist frequency, is what an increment-based
regression's residual variance feeds on.  The generator identities need the level
(their diffusion :math:`D = \pi S_0`), so the precision of :math:`S_0` sets that of the
equivalent damping (:math:`a_{1eq}\sigma_v^2 \approx \pi S_0`, energy balance): with
J2's share alone a ship-roll-like record's :math:`S_0` scattered by 3.5 % and its
:math:`a_{1eq}` by 10.5 %, where an instrumental-variable drift regression reached
0.6 % and 9.0 % (``analyses/peers.py``).

Per block :math:`b` (boxcar: its ordinates at the Fourier frequencies of a flat spectrum
are uncorrelated, where a Hann window's neighbours share half their information) and
bin :math:`\omega_k` from the top of J2's band to :math:`0.9\,\omega_N` (below half the
frequency where the response falls into a noise floor, :data:`FLOOR`),

.. math:: m_b(\theta) = \frac1K\sum_k\frac{|X_{bk}(\theta)|^2}{2\pi T\,S_0\,A(\omega_k)} - 1,
    \qquad A(\omega) = \sum_{j\in\mathbb Z}\Big(\frac{\omega}{\omega + 2j\omega_N}\Big)^4,

a block mean with expectation 0: the sampled displacement carries the aliases
:math:`\hat x(\omega + 2j\omega_N)`, which the spectral derivatives and the drift
features of the sampled record turn into the force's aliases times
:math:`(\omega/(\omega + 2j\omega_N))^2` (far above the resonance, where
:math:`\ddot x \approx f`; the drift's share there is :math:`O(\omega_n^2/\omega^2)`).
:math:`X` is affine in the drift coefficients, so :math:`\bar m` is a quadratic form in
:math:`\lambda = (1, \theta_{drift})` over :math:`S_0`: the bins are summed once.  The
equation is offered only where its model holds and was measured: a white Gaussian force
(Poisson impulses keep J2's equations: their level above the band holds too, but their
fits and its sampling-bias correction were measured without it), no shape, edge, corner
or noise floor in the model, and at least 16 bins.

The blocks that hold a segment's first or last 32 samples are left out (their influence
is zero): the spectral derivative (:func:`hosid.spectra.derivatives.derivatives`) wraps
the segment around, and the slope's mismatch at the wrap is a kink whose second
derivative is a band-limited spike of area :math:`\Delta\dot x`.  Its power per
ordinate, :math:`\Delta\dot x^2/2\pi T`, is flat in frequency and lands in the first
block: it raised that block's level by 17.5 % on average over 40 ship-roll-like records
(0.37 % on the whole :math:`S_0`, half a standard deviation) and by 0.4 % in the paper's
oscillator.  A Hann window (J2) tapers it away.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..model.excitation import Spectrum
from ..model.model import Model
from ..state import RecordState
from .base import Moments, feature_ffts, restoration
from .spectral import default_band

__all__ = ["Level", "alias_factor"]

#: The band's top, in units of the Nyquist frequency.
TOP = 0.9
#: The band's top below a noise floor, in units of the frequency where the response falls
#: into it (J2's cap too).  The floor's share of the level grows as the fourth power of
#: the frequency: white noise of sd 0.02 on a record of the paper's oscillator (sigma_x
#: 1.16; no ``measurement_noise`` in the model) put S0 3.7 % high (Hansen's p 0.005), where
#: a fifth of that frequency would have kept the level out.  But clean simulated records
#: at S0 >= 400 show a "floor" at 130-290 rad/s (the aliases near the Nyquist frequency),
#: and a fifth would drop the level from most of them; the efficiency study ran with a half.
FLOOR = 0.5
#: Fewer bins, or blocks away from the segments' ends, than these: no equation.
MIN_BINS = 16
MIN_BLOCKS = 8
#: Samples at each end of a segment whose derivatives the spectral derivative's
#: periodic extension spoils (module docstring).
GUARD = 32


def alias_factor(omega: np.ndarray, omega_nyquist: float, terms: int = 64) -> np.ndarray:
    r""":math:`A(\omega)` of the module docstring (``terms`` aliases each side; the tail
    beyond is below :math:`10^{-6}` for :math:`\omega \le \omega_N`).
    """
    w = np.asarray(omega, dtype=float)[..., None]
    j = np.arange(-terms, terms + 1)
    return np.sum((w / (w + 2.0 * j * omega_nyquist)) ** 4, axis=-1)


def end_blocks(state: RecordState, guard: int = GUARD) -> np.ndarray:
    """Blocks holding one of the first or last ``guard`` samples of a segment, ``(B,)``."""
    first = state.layout.offsets
    last = first + state.layout.M - 1
    out = np.zeros(first.size, dtype=bool)
    for a, b in state.record.bounds:
        out |= (first < a + guard) & (last >= a)
        out |= (last > b - 1 - guard) & (first <= b - 1)
    return out


@dataclass(frozen=True)
class Level:
    """The level component (module docstring)."""

    name: str = "level"

    def band(self, state: RecordState) -> tuple[float, float]:
        r"""``(lo, hi)`` in rad/s: from J2's default top to :math:`0.9\,\omega_N`."""
        sp = state.spectrum
        hi = min(TOP * state.scales.omega_nyquist, FLOOR * sp.floor_edge)
        return default_band(state)[1], hi

    def bins(self, state: RecordState) -> np.ndarray:
        """The band's Fourier bins above J2's (:meth:`band`)."""
        lo, hi = self.band(state)
        L = state.layout
        bins = L.bins(lo, hi, k_min=2)
        return bins[bins * L.d_omega > lo]  # J2's own bins stay J2's

    def skipped(self, state: RecordState, model: Model) -> str | None:
        """Why the equation does not hold for ``model`` on ``state`` (``None``: it does)."""
        if not Spectrum(model).white or model.has("wc") or model.has("noise_sd"):
            return "the force is not white or the model has a noise floor"
        if model.has("rate"):
            return "Poisson impulses (not measured with the level yet)"
        if state.noise is not None:
            return "the record was denoised"
        if state.spectrum.band_limited:
            return "the excitation stops below the Nyquist frequency"
        n = self.bins(state).size
        if n < MIN_BINS:
            return f"{n} bins above J2's band"
        inner = int((~end_blocks(state)).sum())
        if inner < MIN_BLOCKS:
            return f"{inner} blocks away from the segments' ends"
        return None

    def prepare(self, state: RecordState, model: Model, pilot: np.ndarray) -> Moments:
        """Per-block quadratic forms of the band (module docstring); no equation where the
        model does not hold (``Moments.k == 0``).
        """
        th0 = np.asarray(pilot, dtype=float)
        L = state.layout
        why = self.skipped(state, model)
        if why is not None:
            return Moments.empty(self.name, L.B, why)
        bins, nd = self.bins(state), model.n_drift
        s2, _ = restoration(state, model, th0)
        Y = feature_ffts(state, model, s2, bins, window="boxcar")  # (F, B, K), cached
        omega = bins * L.d_omega
        weight = 1.0 / (2 * math.pi * L.T * alias_factor(omega, state.scales.omega_nyquist))
        K = bins.size
        Q = np.einsum("ibk,jbk,k->bij", Y, Y.conj(), weight).real / K  # (B, F, F)
        keep = ~end_blocks(state)
        Qbar = Q[keep].mean(axis=0)
        i_S0 = model.index("S0")

        def mean(theta):
            th = np.asarray(theta, dtype=float)
            lam = np.concatenate([np.ones((*th.shape[:-1], 1)), th[..., :nd]], axis=-1)
            q = np.einsum("...i,ij,...j->...", lam, Qbar, lam)
            return (q / th[..., i_S0] - 1.0)[..., None]

        lam0 = np.concatenate([[1.0], th0[:nd]])
        u = np.einsum("i,bij,j->b", lam0, Q, lam0) / th0[i_S0]
        u = np.where(keep, (u - u[keep].mean()) * (L.B / keep.sum()), 0.0)
        return Moments(
            component=self.name,
            labels=("level S0",),
            mean=mean,
            influence=u[:, None],
            info={
                "band_rad_s": [float(omega[0]), float(omega[-1])],
                "bins": int(K),
                "blocks": int(keep.sum()),
            },
        )
