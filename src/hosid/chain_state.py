r"""A record of several channels turned once into the state of a system's components.

:class:`ChainState` holds, for every degree of freedom of a system (one record channel
each, in the system's order), the displacement :math:`q_d`, velocity :math:`\dot q_d`
and acceleration :math:`\ddot q_d` at the sample times, one block layout and window
shared by all channels, and each channel's scales and response spectrum
(:mod:`hosid.spectra.response`).  Arrays have the channel first: ``q`` is ``(n, N)``,
``blocks["q"]`` is ``(n, B, M)``.

**Displacement channels** are prepared exactly as a single oscillator's record
(:class:`hosid.state.RecordState`: centred, one spectral derivative of each segment for
velocity and acceleration); a one-channel displacement record gives the single
oscillator's state, layout and scales unchanged.  The velocity such a channel lacks above
the Nyquist frequency is restored by the components (:mod:`hosid.components.chain_features`).

**Acceleration channels** hold interval averages, :math:`\bar a_n\Delta t = \dot
q(t_n + \Delta t/2) - \dot q(t_n - \Delta t/2)` (:mod:`hosid.model.chain`), so their running
sum is the velocity at the half steps exactly, and its trapezoid sum the displacement
there (:func:`hosid.spectra.integrate.integrate_in_time`), both high-passed at the
channel's band edge :math:`\omega_L` (:func:`hosid.spectra.integrate.acceleration_band`:
below it a sensor's noise and drift would dominate) by a zero-phase Butterworth filter;
the acceleration is the filtered velocity's spectral derivative.  The state of such a
channel is at the half steps :math:`t_n + \Delta t/2` (a displacement channel in the same
record is moved there by a spectral half-sample shift, so that all channels share their
times; the statistics are stationary, so the common shift does not matter).  Its velocity
*samples* are exact: pointwise statistics need no restoration above the Nyquist frequency
(what a displacement channel lacks there, :math:`\pi^2S_0/6m^2\omega_N`, a differentiated
record lacks; these samples are the velocity itself).  What the displacement lacks is its
part below the band's filter, and what it holds in excess the trapezoid rule's random walk
(spectrum :math:`S_0\Delta t^2/12m^2\omega^2`): the components restore both
(:mod:`hosid.components.chain_features`), the identities the random walk and, for the
missing part, their statistics extrapolated from the band edge and twice it
(:meth:`ChainState.rebanded`).  A Fourier integration of the whole segment
(:func:`hosid.spectra.integrate.integrate_acceleration`, the record checks') takes it to be
periodic, and its sharp edge spreads the periodic extension's kink over the segment: on
2000 s of the study's 2-dof chain (:math:`\omega_L` = 0.1 rad/s) its displacement's error
was 108 % of the variance over the whole record and 12 % in its middle 90 %, against
0.3 % here (the missing part and the random walk, both restored).  The filter's transients
decay within a period :math:`2\pi/\omega_L` of a segment's ends: the blocks stay
:data:`MARGIN` periods away from them.

The common block layout (:func:`hosid.spectra.blocks.choose_layout`) is chosen for the
slowest channel, its smallest equivalent frequency :math:`\sigma_{\dot q}/\sigma_q`, and
not lengthened for a narrow resonance (as a single oscillator's is): the components of a
system look at the inferred forces, flat at the truth whatever the blocks resolve, and
the identities are martingale increments over any block, so more blocks only estimate
the equations' covariance better (2000 s of the study's 2-dof chain: 97 blocks of
20.5 s, against 48 of 41 s with the resonance's bandwidth).
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
    choose_layout,
    distinct_bounds,
    inner_bounds,
    windowed_fft,
)
from .spectra.derivatives import derivatives
from .spectra.integrate import Band, acceleration_band, integrate_in_time
from .spectra.response import ResponseSpectrum, response_spectrum
from .spectra.windows import Window, get_window
from .state import RecordState, _level

__all__ = ["MARGIN", "ChainState", "Channel"]

#: Periods :math:`2\pi/\omega_L` of an acceleration channel's band edge left out at each
#: end of a segment (the filter's transients).
MARGIN = 1.0


@dataclass(frozen=True)
class Channel:
    """One channel of a :class:`ChainState`: its name, what it measured, its mean (a
    displacement's offset; 0 for an integrated acceleration), scales, response spectrum
    and, for an acceleration, the integration band.
    """

    name: str
    kind: str
    offset: float
    scales: Scales
    spectrum: ResponseSpectrum
    band: Band | None = None

    @property
    def omega_low(self) -> float:
        """The lower edge of the channel's band (rad/s; 0 for a displacement)."""
        return 0.0 if self.band is None else self.band.omega_low


@dataclass(frozen=True, eq=False)
class ChainState:
    """Channels of one record prepared once (module docstring); build with
    :meth:`from_record`.
    """

    record: Record
    q: np.ndarray  # (n, N) displacements, centred unless ``centred`` is False
    v: np.ndarray  # (n, N)
    a: np.ndarray  # (n, N)
    channels: tuple[Channel, ...]
    layout: BlockLayout
    window: Window
    centred: bool = True
    repeats: list | None = None
    #: the single oscillator's own state, when the record is one displacement channel
    single: RecordState | None = None
    _cache: dict = field(default_factory=dict, repr=False)

    @classmethod
    def of(cls, state: RecordState) -> ChainState:
        """The one-channel state that a single oscillator's ``state`` is, sharing its
        arrays (made once per ``state``).
        """

        def make():
            rec = state.record
            ch = Channel(rec.channels[0], "displacement", state.offset, state.scales,
                         state.spectrum)  # fmt: skip
            stack = [y[None, :] for y in (state.x, state.v, state.a)]
            return cls(rec, *stack, (ch,), state.layout, state.window, state.centred,
                       state.repeats, state)  # fmt: skip

        key = ("chain state",)
        if key not in state._fft_cache:
            state._fft_cache[key] = make()
        return state._fft_cache[key]

    @classmethod
    def from_record(
        cls,
        record: Record,
        *,
        block_seconds: float | None = None,
        window: str = "hann",
        centred: bool = True,
        target_blocks: int | None = None,
    ) -> ChainState:
        """The state of ``record`` (its channels in order, each a displacement or an
        acceleration: :attr:`hosid.record.Record.measured`); a record of several channels
        is cut into at least ``target_blocks`` blocks where the block length allows
        (:func:`hosid.spectra.blocks.choose_layout`).

        Raises
        ------
        HosidInputError
            If a channel is constant, an acceleration has no band, or the record is too
            short for the blocks.
        """
        singles = {}
        for name, kind in zip(record.channels, record.measured, strict=True):
            if kind == "displacement":
                one = record.channel(name)
                singles[name] = RecordState.from_record(
                    one, block_seconds=block_seconds, window=window, centred=centred
                )
        if record.n_channels == 1 and record.measured[0] == "displacement":
            return cls.of(singles[record.channels[0]])  # the single oscillator's state
        accel = [c for c, k in zip(record.channels, record.measured, strict=True)
                 if k == "acceleration"]  # fmt: skip
        integrated = _integrate(record, accel)
        cols, channels = [], []
        for name, kind in zip(record.channels, record.measured, strict=True):
            if kind == "displacement":
                st = singles[name]
                cols.append(_half_step(st, record) if accel else (st.x, st.v, st.a))
                channels.append(Channel(name, kind, st.offset, st.scales, st.spectrum))
            else:
                band, got = integrated[name]
                cols.append(got)
                channels.append(_acceleration_channel(record, name, got, band))
        q, v, a = (np.stack([c[k] for c in cols]) for k in range(3))
        margin = max((round(MARGIN * 2 * math.pi / band.omega_low / record.dt)
                      for band, _ in integrated.values()), default=0)  # fmt: skip
        inner = inner_bounds(record.bounds, margin)
        if not inner:
            raise HosidInputError("the record is too short for its acceleration channels' band")
        distinct, repeats = distinct_bounds(q[0], inner)
        omega_n = min(c.scales.omega_n for c in channels)
        layout = choose_layout(
            sum(b - a_ for a_, b in distinct),
            record.dt,
            omega_n,
            block_seconds=block_seconds,
            bounds=distinct,
            target_blocks=target_blocks,
        )
        win = get_window(window)
        channels = [_with_level(c, a[k], layout, win) for k, c in enumerate(channels)]
        return cls(record, q, v, a, tuple(channels), layout, win, centred, repeats)

    # ----------------------------------------------------------------- shapes
    @property
    def n(self) -> int:
        """Number of channels."""
        return len(self.channels)

    @property
    def dt(self) -> float:
        """Sampling interval (s)."""
        return self.record.dt

    @property
    def names(self) -> tuple[str, ...]:
        """The channels' names (the system's dofs)."""
        return tuple(c.name for c in self.channels)

    @property
    def omega_nyquist(self) -> float:
        r""":math:`\pi/\Delta t` (rad/s)."""
        return math.pi / self.dt

    @cached_property
    def blocks(self) -> dict[str, np.ndarray]:
        """``q``, ``v``, ``a`` cut into blocks, each ``(n, B, M)``."""
        return {k: self.layout.take(getattr(self, k)) for k in ("q", "v", "a")}

    @cached_property
    def block_edges(self) -> tuple[np.ndarray, np.ndarray]:
        """First sample of every block and the sample one block length later, held inside
        the block's segment (the ends of the identities' boundary terms).
        """
        first = self.layout.offsets
        stops = np.array([b for _, b in self.record.bounds])
        seg = np.searchsorted(np.array(self.record.segments), first, side="right") - 1
        return first, np.minimum(first + self.layout.M, stops[seg] - 1)

    def cached(self, key, make):
        """A value computed once per state under ``key`` (``make()`` computes it)."""
        if key not in self._cache:
            self._cache[key] = make()
        return self._cache[key]

    def block_fft(self, key, signal_fn, bins: np.ndarray, window=None) -> np.ndarray:
        """Windowed block transforms of a signal built from the blocks, cached under
        ``key``: ``signal_fn(blocks) -> (..., B, M)`` gives ``(..., B, len(bins))``.
        """
        win = self.window if window is None else get_window(window)

        def make():
            return windowed_fft(signal_fn(self.blocks), self.dt, win, bins)

        return self.cached(("fft", key, bins.tobytes(), win.name), make)

    def describe(self) -> dict:
        """Scales, bands and layout as plain numbers (for attrs and reports; the single
        oscillator's own for one displacement channel).
        """
        if self.single is not None:
            return self.single.describe()
        per = {}
        for c in self.channels:
            per[c.name] = {
                "measured": c.kind,
                "sigma_q": c.scales.sigma_x,
                "sigma_v_band": c.scales.sigma_v,
                "omega_n": c.scales.omega_n,
                "offset": c.offset,
                **c.spectrum.describe(),
            }
            if c.band is not None:
                per[c.name]["band_rad_s"] = [c.band.omega_low, c.band.omega_nyquist]
        return {
            "channels": per,
            "omega_nyquist": self.omega_nyquist,
            "centred": self.centred,
            **self.layout.as_dict(),
            "segments": self.record.n_segments,
            "window": self.window.name,
        }

    def rebanded(self, factor: float) -> ChainState:
        """The same record with every acceleration channel integrated above ``factor``
        times its band edge, on this state's blocks (made once per state and factor).
        """

        def make():
            q, v, a = self.q.copy(), self.v.copy(), self.a.copy()
            channels = list(self.channels)
            for k, c in enumerate(self.channels):
                if c.band is None:
                    continue
                band = dataclasses.replace(c.band, omega_low=factor * c.band.omega_low)
                x = self.record.channel(c.name).x
                q[k], v[k], a[k] = integrate_in_time(
                    x, self.dt, omega_low=band.omega_low, bounds=self.record.bounds
                )
                channels[k] = dataclasses.replace(c, band=band)
            return ChainState(self.record, q, v, a, tuple(channels), self.layout, self.window,
                              self.centred, self.repeats)  # fmt: skip

        return self.cached(("rebanded", float(factor)), make)

    def band_notes(self) -> list[str]:
        """One sentence per acceleration channel: the band it was integrated in."""
        notes = []
        for c in self.channels:
            if c.band is not None:
                notes.append(
                    f"channel {c.name} (acceleration): velocity and displacement integrated in "
                    f"time above {c.band.omega_low:.3g} rad/s (where the acceleration spectrum "
                    f"has risen to 10 times its floor {c.band.floor:.3g}; zero-phase Butterworth "
                    f"high-pass) up to the Nyquist frequency {c.band.omega_nyquist:.4g} rad/s; "
                    f"the first and last {MARGIN * 2 * math.pi / c.band.omega_low:.3g} s of a "
                    "segment left out"
                )
        return notes


def _integrate(record: Record, names: list[str]) -> dict:
    """The acceleration channels ``names``: their band and their state at the half steps
    (module docstring).
    """
    out = {}
    for c in names:
        a = record.channel(c).x
        band = acceleration_band(a, record.dt, bounds=record.bounds)
        got = integrate_in_time(a, record.dt, omega_low=band.omega_low, bounds=record.bounds)
        out[c] = (band, got)
    return out


def _half_step(st: RecordState, record: Record):
    r"""A displacement channel's state moved half a sample later (a spectral shift of each
    segment's displacement, its end points' line shifted alike), to the half steps of the
    record's acceleration channels.
    """
    dt = record.dt
    pieces = []
    for p in record.split(st.x):
        n = p.size
        slope = (p[-1] - p[0]) / ((n - 1) * dt)
        line = p[0] + slope * dt * np.arange(n)
        w = 2.0 * np.pi * np.fft.rfftfreq(n, dt)
        moved = np.fft.irfft(np.fft.rfft(p - line) * np.exp(0.5j * w * dt), n)
        pieces.append(moved + line + 0.5 * slope * dt)
    x = np.concatenate(pieces)
    v, a = (np.concatenate(d) for d in zip(*(derivatives(p, dt) for p in record.split(x)),
                                            strict=True))  # fmt: skip
    return x, v, a


def _acceleration_channel(record: Record, name: str, got, band: Band) -> Channel:
    """The channel of an integrated acceleration (its level set later)."""
    x, v, _ = got
    sx, sv = float(np.std(x)), float(np.std(v))
    if not (sx > 0 and sv > 0 and math.isfinite(sv / sx)):
        raise HosidInputError(f"channel {name!r} is constant: it has no response to identify")
    spectrum = response_spectrum(
        x, record.dt, sigma_v=sv, bounds=record.bounds, noise_floor=False
    )  # no displacement noise floor in an integrated acceleration
    scales = Scales(sx, sv, 0.0, record.dt, spectrum.edge)
    return Channel(name, "acceleration", 0.0, scales, spectrum, band)


def _with_level(c: Channel, a: np.ndarray, layout: BlockLayout, win: Window) -> Channel:
    """The channel with the rough force level of its acceleration (priors' scale) on the
    common layout, where it had none.
    """
    if c.scales.S0 > 0:
        return c
    top = c.spectrum.edge[0] if c.spectrum.edge else None
    level = _level(a, layout, win, c.scales.omega_n, top)
    s = c.scales
    return Channel(c.name, c.kind, c.offset, Scales(s.sigma_x, s.sigma_v, level, s.dt,
                   s.band_edge), c.spectrum, c.band)  # fmt: skip
