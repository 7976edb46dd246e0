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

**Acceleration channels** are integrated in their band :math:`[\omega_L, \omega_N)`
(:func:`hosid.spectra.integrate.integrate_acceleration`): displacement and velocity by
division by :math:`i\omega\,\mathrm{sinc}(\omega\Delta t/2)` and :math:`i\omega`, the
acceleration as the velocity's spectral derivative (the interval average's sinc
undone).  The integrated velocity interpolates the exact velocity samples at the half
steps, so its power above the Nyquist frequency comes back folded into the band: its
variance is the velocity's, and it needs no restoration there (what a displacement
channel lacks, :math:`\pi^2S_0/6m^2\omega_N`, an acceleration channel holds as aliases).
What it lacks is below :math:`\omega_L`, restored by the components from the model's
static response (:mod:`hosid.components.chain_features`).

The common block layout (:func:`hosid.spectra.blocks.choose_layout`) is chosen for the
slowest channel, its smallest equivalent frequency :math:`\sigma_{\dot q}/\sigma_q`, and
not lengthened for a narrow resonance (as a single oscillator's is): the components of a
system look at the inferred forces, flat at the truth whatever the blocks resolve, and
the identities are martingale increments over any block, so more blocks only estimate
the equations' covariance better (2000 s of the study's 2-dof chain: 97 blocks of
20.5 s, against 48 of 41 s with the resonance's bandwidth).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from .errors import HosidInputError
from .model.terms import Scales
from .record import Record
from .spectra.blocks import BlockLayout, choose_layout, distinct_bounds, windowed_fft
from .spectra.integrate import Band, integrate_acceleration
from .spectra.response import ResponseSpectrum, response_spectrum
from .spectra.windows import Window, get_window
from .state import RecordState, _level

__all__ = ["ChainState", "Channel"]


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
    ) -> ChainState:
        """The state of ``record`` (its channels in order, each a displacement or an
        acceleration: :attr:`hosid.record.Record.measured`).

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
        cols, channels = [], []
        for name, kind in zip(record.channels, record.measured, strict=True):
            if kind == "displacement":
                st = singles[name]
                cols.append((st.x, st.v, st.a))
                channels.append(Channel(name, kind, st.offset, st.scales, st.spectrum))
            else:
                got = integrate_acceleration(record.channel(name).x, record.dt,
                                             bounds=record.bounds)  # fmt: skip
                cols.append((got.displacement, got.velocity, got.corrected))
                channels.append(_acceleration_channel(record, name, got))
        q, v, a = (np.stack([c[k] for c in cols]) for k in range(3))
        distinct, repeats = distinct_bounds(q[0], record.bounds)
        omega_n = min(c.scales.omega_n for c in channels)
        layout = choose_layout(
            sum(b - a_ for a_, b in distinct),
            record.dt,
            omega_n,
            block_seconds=block_seconds,
            bounds=distinct,
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

    def band_notes(self) -> list[str]:
        """One sentence per acceleration channel: the band it was integrated in."""
        notes = []
        for c in self.channels:
            if c.band is not None:
                notes.append(
                    f"channel {c.name} (acceleration): displacement and velocity integrated "
                    f"in [{c.band.omega_low:.3g}, {c.band.omega_nyquist:.4g}) rad/s, where the "
                    f"acceleration spectrum has risen to 10 times its floor {c.band.floor:.3g}"
                    "; the identities are restored for the static response below it"
                )
        return notes


def _acceleration_channel(record: Record, name: str, got) -> Channel:
    """The channel of an integrated acceleration (its level set later)."""
    sx, sv = float(np.std(got.displacement)), float(np.std(got.velocity))
    if not (sx > 0 and sv > 0 and math.isfinite(sv / sx)):
        raise HosidInputError(f"channel {name!r} is constant: it has no response to identify")
    spectrum = response_spectrum(got.displacement, record.dt, sigma_v=sv, bounds=record.bounds)
    scales = Scales(sx, sv, 0.0, record.dt, spectrum.edge)
    return Channel(name, "acceleration", 0.0, scales, spectrum, got.band)


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
