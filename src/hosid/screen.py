r"""Record checks before any estimation: can hosid describe this record at all.

:func:`check_record` looks at the samples once (moments, block periodograms with
:func:`scipy.signal.spectrogram`, block means, the sample grid) and returns one
:class:`hosid.verdicts.Check` per question:

``length``
    Enough samples for :data:`~hosid.spectra.blocks.MIN_BLOCKS` blocks of at least
    :data:`~hosid.spectra.blocks.MIN_PERIODS` periods of the resonance (a shorter record
    is bad input: :class:`~hosid.errors.HosidInputError`, exit code 2).
``sampling``
    The equivalent frequency :math:`\omega_e = \sqrt{\int\omega^2S_x/\int S_x}` (the
    :math:`\sigma_{\dot x}/\sigma_x` of the fit) well below the Nyquist frequency
    :math:`\omega_N`.
``offset``
    The record's mean: removed before the fit (or modelled, with the
    ``excitation_mean`` or ``quadratic_stiffness`` terms); reported in the record's unit.
    For a record in segments, the root mean square of the segments' means about their
    common mean in standard errors, :math:`\sqrt{2\pi S_x(0)/T_i}` (about 1 when the
    segments come from one stationary response).
``trend``
    The least-squares slope over each segment in units of its standard error under
    stationarity, :math:`z = \hat b/\mathrm{se}(\hat b)`,
    :math:`\mathrm{se}^2 = 2\pi S_x(0)/(\Delta t\sum(t_i-\bar t)^2)`.
``clipping``
    The share of samples at the record's extreme values (a saturated sensor piles them
    up there; a continuous signal has one sample at each).
``quantisation``
    The step :math:`\Delta` of the sample grid, if any, and the share of the velocity's
    variance that its white noise (:math:`\Delta^2/12` spread to :math:`\omega_N`) takes,
    :math:`\Delta^2\omega_N^2/(36\,\sigma_{\dot x}^2)`: the spectral velocity sees the
    noise up to the Nyquist frequency.
``oscillator``
    Whether a randomly excited oscillator describes the record: a spectrum that falls off
    above its resonance (white noise does not: *flatness*, the mean level over
    :math:`[0.5, 0.9]\,\omega_N` over the peak level), a peak that varies from block to
    block as a random response does (tones do not: *variation*, the coefficient of
    variation over blocks of the 3 largest ordinates of the block periodograms, about 1
    for a Gaussian response, about 0 for tones; and *line share*, the variance in the 5
    largest ordinates of a whole-record periodogram, about 1 for a few tones, even
    beating ones), and a stationary level (a random walk or
    a drift is not: *wander*, the variance of block means of 16 periods over the
    variance).

A record of several channels, or of an acceleration, is judged channel by channel and
across channels (:mod:`hosid.record.channel_checks`).  A ``fail`` means the record is
outside what hosid describes: :func:`hosid.fit` and
:func:`hosid.estimate` raise :class:`~hosid.errors.RecordRejected` (exit code 3 on the
command line) unless forced.  The thresholds, :data:`THRESHOLDS`, are set from simulated
records (``analyses/record_checks.py``, which measures their false-alarm rate on good
records of every regime and their detection rate on bad ones;
``analyses/results/record_checks.md``).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from scipy import signal

from .errors import HosidInputError, RecordRejected
from .record import Record
from .spectra.blocks import MIN_BLOCKS, MIN_PERIODS, PERIODS
from .verdicts import Check

__all__ = [
    "THRESHOLDS",
    "check_record",
    "clipping_check",
    "quantisation_check",
    "record_statistics",
    "reject_failures",
]

#: ``(warn, fail)`` thresholds of each checked statistic (module docstring); ``None``:
#: that level is not used.
THRESHOLDS: dict[str, tuple[float | None, float | None]] = {
    "sampling": (0.30, 0.45),  # omega_e / omega_N
    "trend": (6.0, None),  # |z| of the slope
    "levels": (4.0, None),  # rms z of the segments' means about their common mean
    "clipping": (0.001, 0.01),  # share of samples at the extremes
    "quantisation": (0.01, 0.5),  # quantisation noise's share of the velocity variance
    "flatness": (None, 0.05),  # mean level over [0.5, 0.9] omega_N / peak level
    "variation": (None, 0.35),  # block-to-block variation at the peak (fails at or BELOW)
    "line_share": (None, 0.8),  # variance share of the 5 largest whole-record ordinates
    "wander": (None, 0.5),  # variance of block means / variance
}


def _status(name: str, value: float) -> str:
    warn, fail = THRESHOLDS[name]
    if fail is not None and value >= fail:
        return "fail"
    if warn is not None and value >= warn:
        return "warn"
    return "pass"


def _spectra(pieces: Sequence[np.ndarray], dt: float, nperseg: int):
    """Block periodograms of the pieces (Hann, no overlap), two-sided per rad/s:
    ``omega`` and ``(blocks, K)``.
    """
    blocks = []
    for y in pieces:
        if y.size >= nperseg:
            f, _, P = signal.spectrogram(
                y, fs=1.0 / dt, window="hann", nperseg=nperseg, noverlap=0, detrend="constant"
            )
            blocks.append(P.T)
    if not blocks:
        y = max(pieces, key=len)
        f, _, P = signal.spectrogram(y, fs=1.0 / dt, window="hann", nperseg=y.size)
        blocks.append(P.T)
    return 2.0 * math.pi * f, np.concatenate(blocks) / (4.0 * math.pi)


def _steadiness(P: np.ndarray) -> float:
    """Coefficient of variation over blocks of the 3 largest ordinates of the mean
    spectrum: about 1 for a random response, about 0 for tones.
    """
    if P.shape[0] < 4:
        return 1.0
    mean = P.mean(axis=0)
    top = np.argsort(mean[1:])[-3:] + 1
    return float(np.mean(P[:, top].std(axis=0) / P[:, top].mean(axis=0)))


def _trend_z(pieces: Sequence[np.ndarray], dt: float, S0_x: float) -> float:
    """The pooled slope's z (module docstring)."""
    num = den = 0.0
    for y in pieces:
        t = dt * np.arange(y.size)
        tc = t - t.mean()
        num += float(tc @ (y - y.mean()))
        den += float(tc @ tc)
    if den <= 0 or S0_x <= 0:
        return 0.0
    slope = num / den
    return abs(slope) / math.sqrt(2.0 * math.pi * S0_x / (dt * den))


def _grid_step(x: np.ndarray) -> float | None:
    """The step of the grid the samples lie on, or ``None`` when they are continuous."""
    u = np.unique(x)
    if u.size < 2 or u.size > x.size // 4:
        return None
    step = float(np.min(np.diff(u)))
    k = (u - u[0]) / step
    return step if np.max(np.abs(k - np.round(k))) < 0.01 else None


def _line_share(pieces: Sequence[np.ndarray]) -> float:
    """Variance share of the 5 largest ordinates of each piece's Hann periodogram."""
    share, weight = 0.0, 0
    for y in pieces:
        P = np.abs(np.fft.rfft((y - y.mean()) * signal.get_window("hann", y.size))) ** 2
        P[0] = 0.0
        if P.sum() > 0:
            share += y.size * float(np.sort(P)[-5:].sum() / P.sum())
            weight += y.size
    return share / weight if weight else 0.0


def _wander(pieces: Sequence[np.ndarray], block: int, var: float) -> float:
    """Variance of block means (about their segment's mean) over the variance."""
    means = [
        y[: (y.size // block) * block].reshape(-1, block).mean(axis=1) - y.mean()
        for y in pieces
        if y.size >= 2 * block
    ]
    if not means:
        return 0.0
    m = np.concatenate(means)
    return float(np.var(m) / var) if var > 0 else 0.0


def _levels(pieces: Sequence[np.ndarray], dt: float, S0_x: float) -> float:
    r"""Root mean square of the segments' means about their common mean, in standard
    errors :math:`\sqrt{2\pi S_x(0)/T_i}` (about 1 for segments of one stationary
    response; 0 for a record of one segment).
    """
    if len(pieces) < 2 or S0_x <= 0:
        return 0.0
    m = np.array([y.mean() for y in pieces])
    w = np.array([y.size * dt for y in pieces]) / (2.0 * math.pi * S0_x)  # 1 / se^2
    centre = float(np.sum(w * m) / np.sum(w))
    return math.sqrt(float(np.mean(w * (m - centre) ** 2)))


def record_statistics(record: Record) -> dict[str, float]:
    """The numbers the checks judge (module docstring), in the record's units.

    Keys: ``n``, ``duration``, ``mean``, ``sd`` (within segments), ``omega_e``,
    ``omega_nyquist``, ``sampling``, ``needed_duration``, ``used_duration``, ``trend_z``,
    ``levels_z``, ``clipped_share``, ``low``, ``high``, ``grid_step`` (0 for continuous
    values), ``quantisation_share``, ``flatness``, ``variation``, ``line_share``,
    ``wander``; for a constant record only the first four and ``constant = 1``.
    One channel only (else :class:`~hosid.errors.HosidInputError`).
    """
    if record.n_channels > 1:
        raise HosidInputError("record_statistics takes one channel: use record.channel(name)")
    pieces = record.split(record.x)  # no statistic spans a gap between segments
    x, dt = record.x, record.dt
    mean = float(np.mean(x))
    sd = math.sqrt(sum(float(np.sum((y - y.mean()) ** 2)) for y in pieces) / x.size)
    wN = math.pi / dt
    out = {"n": float(record.n), "duration": record.duration, "mean": mean, "sd": sd}
    if not sd > 1e-12 * max(1.0, abs(mean)):
        return {**out, "constant": 1.0}
    # a first frequency scale from differences sets the blocks of the periodograms
    w_fd = float(np.std(np.diff(x)) / dt / sd)
    period = 2.0 * math.pi / max(w_fd, 1e-12)
    longest = max(y.size for y in pieces)
    nperseg = int(min(max(256, 2 ** round(math.log2(max(PERIODS * period / dt, 2.0)))), longest))
    omega, P = _spectra(pieces, dt, nperseg)
    S = P.mean(axis=0)
    d = float(omega[1] - omega[0])
    we = math.sqrt(float(np.sum(omega**2 * S) / np.sum(S)))
    step = _grid_step(x) or 0.0
    S_low = float(np.median(S[1:4])) if S.size > 4 else float(S[0])
    var_v = float(np.sum(omega**2 * S) * d * 2.0)
    peak = float(np.max(S[1:])) if S.size > 1 else float(S[0])
    high = (omega >= 0.5 * wN) & (omega <= 0.9 * wN)
    lo, hi = float(np.min(x)), float(np.max(x))
    tol = 1e-9 * (hi - lo)
    block = max(16, round(PERIODS * 2.0 * math.pi / we / dt))
    return {
        **out,
        "constant": 0.0,
        "omega_e": we,
        "omega_nyquist": wN,
        "sampling": we / wN,
        "needed_duration": MIN_BLOCKS * MIN_PERIODS * 2.0 * math.pi / we,
        "used_duration": sum(y.size for y in pieces) * dt,
        "trend_z": _trend_z(pieces, dt, S_low),
        "levels_z": _levels(pieces, dt, S_low),
        "clipped_share": float(np.mean(x <= lo + tol) + np.mean(x >= hi - tol)),
        "low": lo,
        "high": hi,
        "grid_step": step,
        # white noise Delta^2/12 up to omega_N, against the velocity's variance
        "quantisation_share": step**2 / 12.0 * wN**2 / 3.0 / var_v,
        "flatness": float(np.mean(S[high]) / peak) if high.any() and peak > 0 else 0.0,
        "variation": _steadiness(P),
        "line_share": _line_share(pieces),
        "wander": _wander(pieces, block, sd**2),
    }


def check_record(record: Record, *, unit: str = "m") -> list[Check]:
    """The checks of the module docstring, in a fixed order.

    Parameters
    ----------
    record : Record
    unit : str
        The displacement's unit, for the messages.

    Raises
    ------
    HosidInputError
        If the record is too short to be judged (the ``length`` check).
    """
    if record.n_channels > 1 or "acceleration" in record.measured:
        from .record.channel_checks import check_channels

        return check_channels(record, unit=unit)
    st = record_statistics(record)
    if st["constant"]:
        msg = "the record is constant: there is no response to identify"
        return [Check("oscillator", "fail", 0.0, msg)]
    we, wN, sd = st["omega_e"], st["omega_nyquist"], st["sd"]
    need, have = st["needed_duration"], st["used_duration"]
    ratio = st["sampling"]
    z, share, q = st["trend_z"], st["clipped_share"], st["quantisation_share"]
    if have < need:  # nothing else can be judged on too short a record: bad input
        raise HosidInputError(
            f"record of {have:.4g} s is too short for its {we:.4g} rad/s response: "
            f"{MIN_BLOCKS} blocks of {MIN_PERIODS:.0f} periods need {need:.4g} s"
        )
    checks = [
        Check(
            "length",
            "pass",
            have / need,
            f"{have:.4g} s of record for a {we:.4g} rad/s response ({have / need:.3g} x the "
            f"{need:.4g} s that {MIN_BLOCKS} blocks of {MIN_PERIODS:.0f} periods need)",
        ),
        Check(
            "sampling",
            _status("sampling", ratio),
            ratio,
            f"equivalent frequency {we:.4g} rad/s is {ratio:.2f} of the Nyquist frequency "
            f"{wN:.4g} rad/s"
            + ("" if ratio < THRESHOLDS["sampling"][0] else ": sampling too coarse for it"),
        ),
        Check(
            "offset",
            _status("levels", st["levels_z"]),
            st["mean"],
            f"mean {st['mean']:.4g} {unit} ({abs(st['mean']) / sd:.3g} sd) removed before the "
            "fit, or modelled by excitation_mean / quadratic_stiffness"
            + (
                f"; the {record.n_segments} segments' means differ by {st['levels_z']:.2g} "
                "standard errors (rms): different offsets or set-ups?"
                if st["levels_z"] >= THRESHOLDS["levels"][0]
                else ""
            ),
        ),
        Check(
            "trend",
            _status("trend", z),
            z,
            f"linear trend {z:.2g} standard errors from zero"
            + ("" if z < THRESHOLDS["trend"][0] else ": a drifting sensor or a changing load?"),
        ),
        clipping_check(share, st["low"], st["high"], unit),
        quantisation_check(st["grid_step"], q, unit),
    ]
    flat, steady, wand, lines = st["flatness"], st["variation"], st["wander"], st["line_share"]
    why = ""  # the most specific reason: a wandering level dominates any spectrum
    if wand >= THRESHOLDS["wander"][1]:
        why = (
            f"its level wanders like a random walk or a drift (block means hold "
            f"{100 * min(wand, 1.0):.0f} % of the variance)"
        )
    elif steady <= THRESHOLDS["variation"][1] or lines >= THRESHOLDS["line_share"][1]:
        signs = []
        if steady <= THRESHOLDS["variation"][1]:
            signs.append(
                f"its spectral peak is steady from block to block (variation {steady:.2g})"
            )
        if lines >= THRESHOLDS["line_share"][1]:
            signs.append(f"{100 * lines:.0f} % of its variance sits in 5 spectral lines")
        why = "tones, not a random response: " + " and ".join(signs)
    elif flat >= THRESHOLDS["flatness"][1]:
        why = f"its spectrum does not fall off above a resonance (flatness {flat:.2g})"
    closeness = max(
        flat / THRESHOLDS["flatness"][1],
        THRESHOLDS["variation"][1] / max(steady, 1e-12),
        lines / THRESHOLDS["line_share"][1],
        wand / THRESHOLDS["wander"][1],
    )  # 1 at the nearest threshold
    checks.append(
        Check(
            "oscillator",
            "fail" if why else "pass",
            closeness,
            "not a randomly excited oscillator: " + why
            if why
            else f"a resonance at about {we:.4g} rad/s, a broad-band stationary response "
            f"(flatness {flat:.2g}, variation {steady:.2g}, line share {lines:.2g}, "
            f"wander {wand:.2g})",
        )
    )
    return checks


def clipping_check(share: float, low: float, high: float, unit: str) -> Check:
    """The ``clipping`` verdict on the share of samples at the extremes ``low``, ``high``."""
    return Check(
        "clipping",
        _status("clipping", share),
        share,
        f"{100 * share:.3g} % of the samples sit at the extremes {low:.4g} and {high:.4g} "
        f"{unit}" + ("" if share < THRESHOLDS["clipping"][0] else ": a saturated sensor?"),
    )


def quantisation_check(step: float, share: float, unit: str, of: str = "velocity") -> Check:
    """The ``quantisation`` verdict: a grid of ``step`` (0: none), noise ``share`` of ``of``."""
    hint = "; consider the measurement_noise term (--model paper,measurement_noise)"
    msg = f"samples on a grid of {step:.3g} {unit}: its noise is {100 * share:.2g} % of the "
    msg += f"{of}'s variance" + ("" if share < THRESHOLDS["quantisation"][0] else hint)
    status = _status("quantisation", share)
    return Check(
        "quantisation", status, share, msg if step else "no sample grid: continuous values"
    )


def reject_failures(checks: Sequence[Check], *, force: bool = False) -> None:
    """Raise :class:`~hosid.errors.RecordRejected` when a check failed (unless ``force``).

    Raises
    ------
    RecordRejected
        With the failed checks' messages joined.
    """
    failed = sorted(
        (c for c in checks if c.status == "fail"), key=lambda c: c.name != "oscillator"
    )
    if failed and not force:
        raise RecordRejected(
            "; ".join(f"{c.name}: {c.message}" for c in failed) + " (--force fits it anyway)",
            checks,
        )
