r"""Windows over a long record: their length and step, and the windows themselves.

A window holds :math:`W` consecutive samples of one run of the source
(:mod:`hosid.monitor.source`); the next starts :math:`S` samples later.  Every window is
fitted with the same block length, so that every window's estimate is the same
estimator on a stationary stretch, and the tracks differ only where the system does.

Defaults (:func:`choose_layout`): the first :data:`PILOT_SAMPLES` samples give the block
length :math:`T_b` a record of them would get (:func:`hosid.spectra.blocks.choose_layout`:
about 16 periods of the resonance, and 4 bins across its bandwidth), and

.. math:: W = \mathrm{clip}\!\left(\frac{T_{rec}}{20},\ 10\,T_b,\ 100\,T_b\right),
   \qquad S = W,

about 20 windows over a record of known length :math:`T_{rec}` (48 pilot blocks when
the record grows, ``--follow``).  Every window is then fitted with the block length a
single fit of :math:`W` seconds would choose (at least the 24 blocks a fit needs; the
paper oscillator's 2000 s windows get its 20.48 s blocks, the ship-roll-like
oscillator's 4096 s windows the 102.4 s blocks of the efficiency study's 4000 s
records).  Windows that do not overlap (:math:`S = W`) give independent estimates; a
shorter step gives a smoother track of correlated ones, which
the change test accounts for (:mod:`hosid.monitor.joint`).
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator
from dataclasses import dataclass

import numpy as np

from ..errors import HosidInputError
from ..spectra.blocks import MIN_BLOCKS
from .source import Piece, Source

__all__ = ["PILOT_SAMPLES", "Layout", "Window", "choose_layout", "count", "describe", "windows"]

#: Samples of the source's start that set the default block length.
PILOT_SAMPLES = 1 << 17
#: Windows over a record of known length, by default.
WINDOWS = 20
#: A default window in blocks of the pilot's length: at least, at most, and when the
#: record's length is unknown (a growing file).
MIN_PILOT_BLOCKS, MAX_BLOCKS, FOLLOW_BLOCKS = 10, 100, 48


@dataclass(frozen=True)
class Layout:
    """Window length and step (samples), sampling interval and block length (s)."""

    samples: int
    step: int
    dt: float
    block_seconds: float

    @property
    def seconds(self) -> float:
        """Window length (s)."""
        return self.samples * self.dt

    @property
    def step_seconds(self) -> float:
        """Step between window starts (s)."""
        return self.step * self.dt

    def as_dict(self) -> dict:
        """Plain numbers, for ``monitor.json`` and the report."""
        return {
            "window_seconds": self.seconds,
            "step_seconds": self.step_seconds,
            "window_samples": self.samples,
            "step_samples": self.step,
            "dt": self.dt,
            "block_seconds": self.block_seconds,
        }


@dataclass(frozen=True)
class Window:
    """Window ``index``: samples ``x`` from time ``start`` to ``end`` (exclusive)."""

    index: int
    start: float
    end: float
    x: np.ndarray


def _pilot(source: Source) -> np.ndarray:
    parts, n = [], 0
    for piece in source.pieces():
        if piece.new_run and parts:
            break
        parts.append(piece.x[: PILOT_SAMPLES - n])
        n += parts[-1].size
        if n >= PILOT_SAMPLES:
            break
    return np.concatenate(parts) if parts else np.zeros(0)


def choose_layout(
    source: Source,
    *,
    window: float | None = None,
    step: float | None = None,
    block_seconds: float | None = None,
    total_samples: int | None = None,
) -> Layout:
    """The windows of ``source`` (module docstring); ``window``, ``step`` and
    ``block_seconds`` in seconds override the defaults.

    Raises
    ------
    HosidInputError
        If the start of the source is too short or not a response, or a window would
        hold fewer than the 24 blocks a fit needs, or the step is not positive.
    """
    from ..record import Record
    from ..spectra.blocks import choose_layout as block_layout
    from ..state import RecordState

    dt = source.dt
    state = None
    if block_seconds is None or window is None:
        pilot = _pilot(source)
        try:
            state = RecordState.from_record(Record(pilot, dt), block_seconds=None)
        except HosidInputError as exc:
            raise HosidInputError(
                f"{source.path}: its first {pilot.size} samples do not set a block length "
                f"({exc}); give --window and --block-seconds"
            ) from None
    if window is None:
        pilot_block = state.layout.T
        total = FOLLOW_BLOCKS * pilot_block if total_samples is None else total_samples * dt
        shortest, longest = MIN_PILOT_BLOCKS * pilot_block, MAX_BLOCKS * pilot_block
        window = min(max(total / WINDOWS, shortest), longest)
    samples = round(window / dt)
    if block_seconds is None:  # what a single fit of one window would choose
        try:
            layout = block_layout(
                samples, dt, state.scales.sigma_v / state.scales.sigma_x,
                bandwidth=state.spectrum.bandwidth,
            )  # fmt: skip
        except HosidInputError as exc:
            raise HosidInputError(
                f"windows of {window:g} s: {exc}; use a longer --window"
            ) from None
        block_seconds = layout.T
        samples = layout.M * (samples // layout.M)  # whole blocks
    M = max(round(block_seconds / dt), 16)
    if samples < MIN_BLOCKS * M:
        raise HosidInputError(
            f"windows of {samples * dt:g} s hold {samples // M} blocks of {M * dt:g} s; a fit "
            f"needs {MIN_BLOCKS}: use --window {MIN_BLOCKS * M * dt:g} or more"
        )
    stride = samples if step is None else round(step / dt)
    if not 1 <= stride <= samples:
        raise HosidInputError(
            f"--step must lie between one sample ({dt:g} s) and the window ({samples * dt:g} s)"
        )
    return Layout(samples=samples, step=stride, dt=dt, block_seconds=M * dt)


def windows(
    pieces: Iterable[Piece | None], layout: Layout, *, tail: bool = True
) -> Iterator[Window | None]:
    """The windows of the pieces (module docstring), in order; a window never spans the
    start of a run.  A run's samples after its last whole window wait for more data;
    when the run ends (a new run starts, or the source ends) and they hold at least a
    quarter of a window, a last window ending with the run covers them (``tail``; it
    overlaps the one before, which the change test allows for), so a change late in a
    record is seen.  A ``None`` piece (a growing source's idle look) is passed on.
    """
    W, S, dt = layout.samples, layout.step, layout.dt
    index = 0
    buf = np.zeros(0)
    t_buf = 0.0  # time of buf[0]
    prev = None  # the last window of the run

    def last_window():
        nonlocal index
        if not tail or prev is None:
            return None
        fresh = buf[W - S :]  # the samples after the last window's end
        if fresh.size < W / 4:
            return None
        x = np.concatenate([prev.x, fresh])[-W:]
        end = prev.end + fresh.size * dt
        index += 1
        return Window(index - 1, end - W * dt, end, x)

    for piece in pieces:
        if piece is None:  # a growing source had nothing new
            yield None
            continue
        if piece.new_run:
            w = last_window()
            if w is not None:
                yield w
            buf, t_buf, prev = np.zeros(0), piece.t0, None
        elif buf.size == 0:
            t_buf = piece.t0
        buf = np.concatenate([buf, piece.x])
        first = 0
        while buf.size - first >= W:
            start = t_buf + first * dt
            prev = Window(index, start, start + W * dt, buf[first : first + W].copy())
            yield prev
            index += 1
            first += S
        buf, t_buf = buf[first:], t_buf + first * dt  # first <= buf.size as S <= W
    w = last_window()
    if w is not None:
        yield w


def count(total_samples: int, layout: Layout, *, tail: bool = True) -> int:
    """Windows in one run of ``total_samples`` samples (with its tail window)."""
    W, S = layout.samples, layout.step
    if total_samples < W:
        return 0
    n = 1 + (total_samples - W) // S
    fresh = total_samples - ((n - 1) * S + W)
    return n + int(tail and fresh >= W / 4)


def describe(layout: Layout) -> str:
    """One line: the windows' length, step and blocks."""
    blocks = layout.samples * layout.dt / layout.block_seconds
    overlap = max(0.0, 1.0 - layout.step / layout.samples)
    return (
        f"windows of {layout.seconds:g} s ({blocks:.0f} blocks of {layout.block_seconds:g} s) "
        f"every {layout.step_seconds:g} s" + (f" ({overlap:.0%} overlap)" if overlap else "")
    )
