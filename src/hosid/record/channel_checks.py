r"""Record checks of a record of several channels, or of an acceleration channel.

:func:`check_channels` (what :func:`hosid.screen.check_record` calls for such a record)
returns the checks across channels first, then the single-channel checks of
:mod:`hosid.screen` run on every live channel, each merged into one verdict per name:

``dead``
    A channel that does not move: constant within every segment (standard deviation at
    most :math:`10^{-12}\max(1, |\text{mean}|)`, the single-channel rule), all zeros
    included: ``fail``.  Its other checks are skipped.
``duplicate``
    Two channels alike: the correlation of their samples (centred in each segment)
    beyond :data:`DUPLICATE_CORRELATION` (0.9999) in absolute value: ``fail``, named
    identical or proportional (``x2 = 2 x1``).  Distinct degrees of freedom of a chain
    share a correlation of 0.9999 only when the element between them is rigid, and then
    its law cannot be identified either.
``resampled``
    A channel sampled at a lower rate than the record: ``fail`` when

    - a share of at least :data:`HELD_SHARE` (0.2) of its first differences is zero
      (held: sample-and-hold, a new value every :math:`1/(1 - s)` samples), or of its
      second differences (interpolated linearly between the slower samples), a zero
      being smaller than :math:`10^{-6}` of their root mean square; a channel on a grid
      (:mod:`hosid.screen`'s quantisation) whose non-zero steps are within 2 grid steps
      repeats values by quantisation, not by holding, and is not counted; a continuous
      response repeats no sample;
    - or its spectrum stops: the spectrum of its acceleration (the channel, or its second
      difference) falls by at least :data:`CLIFF_DROP` (1000) from :math:`[0.85, 0.95]
      \omega` (median) to everywhere above :math:`1.05\,\omega` up to the Nyquist
      frequency (maximum), at an :math:`\omega` where every other channel falls by less
      than :data:`CLIFF_OTHERS` (10) (an excitation that stops shows in every channel).
      No physical roll-off falls 1000-fold within 10 % of a frequency (an eighth-order
      anti-alias filter falls 25-fold); a channel decimated and interpolated falls by
      more than :math:`10^4` at its own Nyquist frequency.

Per channel (merged, the verdict of the worst channel with every channel's status):
a displacement channel gets :func:`hosid.screen.check_record` as it is; an acceleration
channel is integrated in its band (:mod:`hosid.spectra.integrate`) and the displacement
so obtained is checked (length, sampling, oscillator), its ``offset`` and ``trend``
giving way to ``integration`` (the band, or why there is none), and ``clipping`` and
``quantisation`` judged on the measured samples (the grid's noise against the
acceleration's variance).
"""

from __future__ import annotations

import math

import numpy as np
from scipy import signal

from ..errors import HosidInputError
from ..screen import _grid_step, check_record, clipping_check, quantisation_check
from ..spectra.integrate import integrate_acceleration
from ..verdicts import STATUSES, Check
from .core import Record

__all__ = ["CLIFF_DROP", "CLIFF_OTHERS", "DUPLICATE_CORRELATION", "HELD_SHARE", "check_channels"]

#: Two channels whose correlation exceeds this in absolute value are one.
DUPLICATE_CORRELATION = 0.9999
#: A channel with this share of vanishing first (or second) differences is held (or
#: interpolated linearly) at a lower rate.
HELD_SHARE = 0.2
#: A difference is zero below this fraction of the differences' root mean square.
ZERO = 1e-6
#: A channel's spectrum that falls this much within 10 % of a frequency stops there ...
CLIFF_DROP = 1e3
#: ... unless the other channels fall at least this much there too.
CLIFF_OTHERS = 10.0


def check_channels(record: Record, *, unit: str = "m") -> list[Check]:
    """The checks of the module docstring, in a fixed order.

    Parameters
    ----------
    record : Record
        One channel or several.
    unit : str
        The displacement's unit, for the messages.

    Raises
    ------
    HosidInputError
        If the record is too short to be judged (naming the channel).
    """
    names = record.channels
    dead = [c for c in names if _constant(record, c)]
    live = [c for c in names if c not in dead]
    checks = []
    if record.n_channels > 1:
        checks.append(_dead(record, dead))
        checks.append(_duplicate(record, live))
        checks.append(_resampled(record, live))
    elif dead:
        msg = "the record is constant: there is no response to identify"
        return [Check("oscillator", "fail", 0.0, msg)]
    per = {}
    for c in live:
        try:
            per[c] = _channel_checks(record.channel(c), unit)
        except HosidInputError as exc:
            if record.n_channels == 1:
                raise
            raise HosidInputError(f"channel {c}: {exc}") from None
    return checks + _merge(per, prefix=record.n_channels > 1)


def _pieces(record: Record, c: str) -> list[np.ndarray]:
    return record.split(record.channel(c).x)


def _constant(record: Record, c: str) -> bool:
    y = record.channel(c).x
    sd = math.sqrt(sum(float(np.sum((p - p.mean()) ** 2)) for p in record.split(y)) / y.size)
    return not sd > 1e-12 * max(1.0, abs(float(np.mean(y))))


def _dead(record: Record, dead: list[str]) -> Check:
    if not dead:
        return Check("dead", "pass", 0.0, f"every channel moves ({', '.join(record.channels)})")
    c = dead[0]
    y = record.channel(c).x
    what = "all zeros" if not np.any(y) else f"constant at {float(np.mean(y)):.4g}"
    more = f" (dead too: {', '.join(dead[1:])})" if len(dead) > 1 else ""
    return Check(
        "dead",
        "fail",
        float(len(dead)),
        f"channel {c} is dead: {what} over its {record.n} samples: a disconnected or broken "
        f"sensor?{more}",
    )


def _centred(record: Record, c: str) -> np.ndarray:
    """Channel ``c`` centred in each segment."""
    return np.concatenate([p - p.mean() for p in _pieces(record, c)])


def _duplicate(record: Record, live: list[str]) -> Check:
    """The most correlated pair of live channels (module docstring)."""
    if len(live) < 2:
        return Check("duplicate", "pass", None, "fewer than two live channels to compare")
    centred = {c: _centred(record, c) for c in live}
    pairs = [(a, b) for i, a in enumerate(live) for b in live[i + 1 :]]
    corr = [
        float(centred[a] @ centred[b])
        / math.sqrt(float(centred[a] @ centred[a]) * float(centred[b] @ centred[b]))
        for a, b in pairs
    ]
    k = int(np.argmax(np.abs(corr)))
    (a, b), r = pairs[k], corr[k]
    if abs(r) <= DUPLICATE_CORRELATION:
        msg = f"no two channels alike: largest correlation {r:.4g} ({a}, {b})"
        return Check("duplicate", "pass", abs(r), msg)
    if np.array_equal(record.channel(a).x, record.channel(b).x):
        how = "identical"
    else:
        slope = float(centred[a] @ centred[b]) / float(centred[a] @ centred[a])
        how = f"proportional: {b} = {slope:.4g} {a} (+ a constant)"
    return Check(
        "duplicate",
        "fail",
        abs(r),
        f"channels {a} and {b} are {how} (correlation {r:.6g}): one sensor recorded twice, or "
        "a rigid link whose law cannot be identified",
    )


def _held(y: np.ndarray, pieces: list[np.ndarray]) -> tuple[float, int]:
    """The larger share of vanishing first or second differences, and its order."""
    step = _grid_step(y)
    best = (0.0, 1)
    for order in (1, 2):
        d = np.concatenate([np.diff(p, order) for p in pieces])
        rms = math.sqrt(float(np.mean(d**2)))
        if not rms > 0:
            continue
        zero = np.abs(d) <= ZERO * rms
        if step and zero.any() and not zero.all():
            if np.median(np.abs(d[~zero])) <= 2.0 * step:
                continue  # the repeats of a quantised channel
        best = max(best, (float(np.mean(zero)), order))
    return best


def _sides(P: np.ndarray, k: int) -> tuple[float, float]:
    """The level just below bin ``k`` (median over 0.85-0.95 of its frequency) and the
    largest level from 1.05 of it up to the Nyquist frequency.
    """
    lo = P[int(0.85 * k) : max(int(0.95 * k), int(0.85 * k) + 1)]
    return float(np.median(lo)), float(np.max(P[min(math.ceil(1.05 * k), P.size - 1) :]))


def _spectrum(record: Record, c: str, nperseg: int) -> np.ndarray:
    """Welch spectrum of channel ``c``'s acceleration (the channel, or its second
    difference), pooled over the segments that hold a block; bins 1 .. nperseg/2.
    """
    ch = record.channel(c)
    order = 0 if ch.measured[0] == "acceleration" else 2
    pieces = [np.diff(p, order) for p in record.split(ch.x) if p.size - order >= nperseg]
    return sum(p.size * signal.welch(p, nperseg=nperseg, window="hann")[1] for p in pieces)[1:]


def _stops(record: Record, live: list[str]) -> list[str]:
    """Channels whose spectrum stops where the others' does not (module docstring)."""
    n = max(b - a for a, b in record.bounds)
    nperseg = 2 ** min(10, int(math.log2(max(n // 4, 16))))
    spectra = {c: _spectrum(record, c, nperseg) for c in live}
    K = nperseg // 2
    bins = range(max(K // 20, 8), int(0.9 * K))
    falls = {}
    for c, P in spectra.items():
        falls[c] = np.zeros(K)
        for k in bins:
            lo, hi = _sides(P, k)
            falls[c][k] = lo / max(hi, 1e-300)
    wN, out = math.pi / record.dt, []
    for c, P in spectra.items():
        others = np.max([falls[o] for o in live if o != c], axis=0)
        ok = (falls[c] >= CLIFF_DROP) & (others < CLIFF_OTHERS)
        if ok.any():
            k = int(np.argmax(np.where(ok, falls[c], 0.0)))
            # the cliff: the last bin near k above the geometric mean of its two sides
            near = np.arange(int(0.85 * k), min(math.ceil(1.05 * k) + 1, K))
            w = wN * (near[P[near] >= math.sqrt(np.prod(_sides(P, k)))][-1] + 1) / K
            out.append(
                f"channel {c}: its spectrum falls {falls[c][k]:.2g}-fold at {w:.4g} rad/s and "
                f"stays down to the Nyquist frequency {wN:.4g} rad/s, where the other channels "
                "do not: sampled at a lower rate and interpolated?"
            )
    return out


def _resampled(record: Record, live: list[str]) -> Check:
    """Channels held, interpolated or band-limited at a lower rate (module docstring)."""
    flagged = []
    for c in live:
        share, order = _held(record.channel(c).x, _pieces(record, c))
        if share >= HELD_SHARE:
            every = 1.0 / max(1.0 - share, 1e-12)
            how = "held" if order == 1 else "interpolated linearly"
            flagged.append(
                f"channel {c}: {100 * share:.0f} % of its {'first' if order == 1 else 'second'}"
                f" differences vanish: {how} between samples taken every {every:.3g} samples "
                f"({every * record.dt:.3g} s), not every {record.dt:.3g} s"
            )
    if len(live) > 1 and not flagged:
        flagged = _stops(record, live)
    if not flagged:
        msg = (
            "every channel sampled at the record's rate: no held or interpolated samples, no "
            "spectrum stopping below the Nyquist frequency"
        )
        return Check("resampled", "pass", 0.0, msg)
    more = f" ({len(flagged) - 1} more channels)" if len(flagged) > 1 else ""
    return Check("resampled", "fail", float(len(flagged)), flagged[0] + more)


def _channel_checks(ch: Record, unit: str) -> list[Check]:
    """The single-channel checks of one channel (module docstring)."""
    if ch.measured[0] == "displacement":
        return check_record(ch, unit=unit)
    try:
        done = integrate_acceleration(ch.x, ch.dt, bounds=ch.bounds)
    except HosidInputError as exc:
        return [Check("integration", "fail", None, f"cannot integrate: {exc}")]
    disp = Record(done.displacement, ch.dt, ch.name, ch.segments)
    checks = check_record(disp, unit=unit)
    y = ch.x
    lo, hi = float(np.min(y)), float(np.max(y))
    tol = 1e-9 * (hi - lo)
    share = float(np.mean(y <= lo + tol) + np.mean(y >= hi - tol))
    step = _grid_step(y) or 0.0
    var = float(np.var(y))
    raw = {
        "clipping": clipping_check(share, lo, hi, f"{unit}/s^2"),
        "quantisation": quantisation_check(
            step, step**2 / 12.0 / var if var > 0 else 0.0, f"{unit}/s^2", "acceleration"
        ),
        "offset": Check("integration", "pass", done.omega_low, done.describe()),
    }
    out = [raw.get(c.name, c) for c in checks if c.name != "trend"]
    return out


def _merge(per: dict[str, list[Check]], *, prefix: bool) -> list[Check]:
    """One verdict per check name: the worst channel's, with every channel's status."""
    names = []
    for checks in per.values():
        names += [c.name for c in checks if c.name not in names]
    out = []
    for name in names:
        got = {ch: c for ch, checks in per.items() for c in checks if c.name == name}
        worst = max(got.values(), key=lambda c: STATUSES.index(c.status))
        ch = next(k for k, c in got.items() if c is worst)
        if not prefix:
            out.append(worst)
            continue
        each = ", ".join(f"{k} {c.status}" for k, c in got.items())
        msg = f"channel {ch}: {worst.message} (channels: {each})"
        out.append(Check(name, worst.status, worst.value, msg))
    return out
