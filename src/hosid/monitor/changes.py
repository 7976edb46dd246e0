r"""Named changes in the window-by-window tracks of ``hosid monitor``.

Window :math:`i` covers :math:`[s_i, e_i)` and gives for a parameter a posterior mean
:math:`y_i` and sd :math:`\sigma_i`.  A step of size :math:`\delta` at time
:math:`\tau` is the model

.. math::

    y_i = \mu + \delta\, f_i(\tau) + \varepsilon_i, \qquad
    f_i(\tau) = \operatorname{clip}\Big(\frac{e_i - \tau}{e_i - s_i}, 0, 1\Big), \qquad
    \varepsilon \sim N(0, \Sigma), \quad \Sigma_{ij} = \sigma_i \sigma_j \rho_{ij},

    \rho_{ij} = (1 - \nu)\, \frac{|[s_i, e_i) \cap [s_j, e_j)|}{\sqrt{(e_i - s_i)(e_j - s_j)}}
              + \nu\, [i = j]

(:math:`f_i`: the share of window :math:`i` after the step, so a window straddling it
estimates the mixture; the overlap term: to first order, the correlation of estimates
from overlapping stretches of one stationary record; the nugget :math:`\nu`: see
:func:`scan`).  With :math:`\Sigma = L L^T`, :math:`z = L^{-1} y`, :math:`u = L^{-1}
\mathbf 1` and :math:`g_\tau` the part of :math:`L^{-1} f(\tau)` orthogonal to
:math:`u`, the GLS estimates and the statistic are

.. math::

    \hat\delta(\tau) = \frac{g_\tau^T z}{g_\tau^T g_\tau}, \qquad
    \operatorname{Var}\hat\delta(\tau) = \frac{1}{g_\tau^T g_\tau}, \qquad
    T(\tau) = \frac{\hat\delta^2}{\operatorname{Var}\hat\delta} = (a_\tau^T z)^2,
    \quad a_\tau = \frac{g_\tau}{\lVert g_\tau \rVert},

and :math:`T_{\max} = \max_\tau T(\tau)`.  Without a change :math:`a_\tau^T z =
a_\tau^T w`, :math:`w \sim N(0, I)` (:math:`a_\tau \perp u` removes :math:`\mu`), so
:math:`T` at every :math:`\tau` of many Monte-Carlo tracks is one matrix product
:math:`(W A)^2` (:func:`null_maxima`).

:func:`scan` tests one parameter, :func:`find_changes` all of a fit.  No I/O.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from scipy import linalg, stats

from ..errors import HosidInputError

__all__ = [
    "Change",
    "Profile",
    "Scan",
    "all_changes",
    "find_changes",
    "lr_cut",
    "null_maxima",
    "overlap_correlation",
    "profile",
    "scan",
    "share_after",
    "tau_grid",
]

#: Candidate change times per window step (the grid also holds every window boundary).
GRID_PER_STEP = 20
#: At most this many floats in one block of Monte-Carlo statistics (draws x times).
CHUNK_ELEMENTS = 2_000_000
#: Smaller products bypass BLAS, which took up to 1000 times longer on a busy machine.
BLAS_MIN = 20_000_000
#: Default nugget :math:`\nu` (matters only for overlapping windows; see :func:`scan`).
NUGGET = 0.1


@dataclass(frozen=True)
class Change:
    r"""A named change: ``time`` :math:`\hat\tau` in ``[time_lo, time_hi]``, ``size``
    :math:`\hat\delta` (after minus before) in ``[size_lo, size_hi]`` (intervals at
    ``level``), ``before`` :math:`\hat\mu`, ``statistic`` :math:`T_{\max}` (named iff
    above ``threshold``, iff ``p_value <= alpha``, the per-test level).
    """

    parameter: str
    time: float
    time_lo: float
    time_hi: float
    size: float
    size_lo: float
    size_hi: float
    before: float
    statistic: float
    p_value: float
    threshold: float
    alpha: float
    level: float


@dataclass(frozen=True)
class Scan:
    """One parameter's named changes (by time), or ``reason`` why it was not tested.

    ``dispersion``: whitened residual SS per degree of freedom, the first change fitted;
    about 1 if the sds and correlations hold, well above 1 false alarms are likely.
    """

    parameter: str
    changes: tuple[Change, ...]
    reason: str | None
    windows: int
    alpha: float
    dispersion: float = math.nan


@dataclass(frozen=True)
class Profile:
    """GLS at the candidate times ``tau`` (``rss0``: whitened residual SS, no change)."""

    tau: np.ndarray
    statistic: np.ndarray
    size: np.ndarray
    size_se: np.ndarray
    before: np.ndarray
    directions: np.ndarray
    rss0: float


def share_after(starts, ends, tau) -> np.ndarray:
    r"""The share :math:`f_i(\tau)` of window :math:`i` after :math:`\tau`: (windows, *tau)."""
    s, e, t = (np.asarray(v, dtype=float) for v in (starts, ends, tau))
    shape = s.shape + (1,) * t.ndim
    return np.clip((e.reshape(shape) - t) / (e - s).reshape(shape), 0.0, 1.0)


def overlap_correlation(starts, ends) -> np.ndarray:
    r"""Overlap correlation :math:`|I_i \cap I_j| / \sqrt{|I_i||I_j|}` of window averages.

    Exact for averages of a short-memory stationary sequence; first order for smooth
    functions of them.
    """
    s, e = np.asarray(starts, dtype=float), np.asarray(ends, dtype=float)
    ov = np.clip(np.minimum(e[:, None], e[None, :]) - np.maximum(s[:, None], s[None, :]), 0, None)
    ln = e - s
    return ov / np.sqrt(ln[:, None] * ln[None, :])


def tau_grid(starts, ends, lo: float, hi: float, per_step: int = GRID_PER_STEP) -> np.ndarray:
    """Candidate times in ``[lo, hi]``: ``per_step`` per median step, and window edges."""
    s, e = np.asarray(starts, dtype=float), np.asarray(ends, dtype=float)
    step = float(np.median(np.diff(s))) if s.size > 1 else float(np.median(e - s))
    grid = np.linspace(lo, hi, max(math.ceil((hi - lo) / step * per_step), 0) + 1)
    edges = np.concatenate([s, e])
    return np.unique(np.concatenate([grid, edges[(edges >= lo) & (edges <= hi)]]))


def profile(starts, ends, mean, sd, tau, baseline=None, nugget: float = 0.0) -> Profile:
    r"""GLS :math:`(\hat\mu, \hat\delta)` and :math:`T` at every ``tau``, of all windows given.

    ``baseline=(m, s)`` is one more observation, :math:`f = 0`, uncorrelated with them.
    """
    s, e, y, sig = (np.asarray(v, dtype=float) for v in (starts, ends, mean, sd))
    tau = np.atleast_1d(np.asarray(tau, dtype=float))
    rho = (1.0 - nugget) * overlap_correlation(s, e) + nugget * np.eye(s.size)
    f = share_after(s, e, tau)
    if baseline is not None:
        rho = linalg.block_diag(rho, 1.0)
        y, sig = np.append(y, baseline[0]), np.append(sig, baseline[1])
        f = np.vstack([f, np.zeros((1, tau.size))])
    cov = sig[:, None] * sig[None, :] * rho
    try:  # positive definite: a Gram matrix of distinct windows' indicators
        chol = linalg.cholesky(cov, lower=True)
    except linalg.LinAlgError:  # rounding, at heavy overlap
        chol = linalg.cholesky(cov + 1e-10 * np.diag(sig**2), lower=True)
    wh = _mul(linalg.lapack.dtrtri(chol, lower=1)[0], np.column_stack([y, np.ones_like(y), f]))
    z, u, fw = wh[:, 0], wh[:, 1], wh[:, 2:]
    uu, uf = float(u @ u), u @ fw
    g = fw - np.outer(u, uf / uu)
    gg = np.einsum("ij,ij->j", g, g)
    ok = gg > 1e-12 * max(float(gg.max(initial=0.0)), 1e-300)
    gg = np.where(ok, gg, np.inf)
    gz = z @ g
    size, rss0 = np.where(ok, gz / gg, 0.0), float(z @ z - (u @ z) ** 2 / uu)
    t, se, a = np.where(ok, gz**2 / gg, 0.0), 1.0 / np.sqrt(gg), g / np.sqrt(gg)
    return Profile(tau, t, size, np.where(ok, se, np.inf), (u @ z - uf * size) / uu, a, rss0)


def _mul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``a @ b``, by ``einsum`` below :data:`BLAS_MIN` multiply-adds."""
    return a @ b if a.size * b.shape[1] > BLAS_MIN else np.einsum("ij,jk", a, b)


def _simulate(directions, draws, rng, shift, reduce: Callable) -> np.ndarray:
    """``reduce((shift + W A)^2)`` per draw, ``W`` standard normal, in memory-bound blocks."""
    n, m = directions.shape
    chunk = max(1, CHUNK_ELEMENTS // max(m, 1))
    out = np.empty(draws)
    for i in range(0, draws, chunk):
        w = rng.standard_normal((min(chunk, draws - i), n))
        out[i : i + w.shape[0]] = reduce((shift + _mul(w, directions)) ** 2)
    return out


def null_maxima(directions: np.ndarray, draws: int, rng: np.random.Generator) -> np.ndarray:
    r""":math:`T_{\max} = \max_\tau (a_\tau^T w)^2` of ``draws`` tracks with no change."""
    return _simulate(directions, draws, rng, 0.0, lambda t: t.max(axis=1))


def lr_cut(directions: np.ndarray, best: int, t_max: float, level: float, draws, rng) -> float:
    r"""The ``level`` quantile of the LR :math:`\max T^* - T^*(\hat\tau)` at the true time.

    Over ``draws`` tracks simulated from the fitted step (parametric bootstrap),
    :math:`T^*(\tau) = (\sqrt{T_{\max}}\, a_{\hat\tau}^T a_\tau + a_\tau^T w)^2`.
    """
    shift = math.sqrt(t_max) * (directions[:, best] @ directions)
    lr = _simulate(directions, draws, rng, shift, lambda t: t.max(axis=1) - t[:, best])
    return float(np.quantile(lr, level))


def _hull(tau: np.ndarray, t: np.ndarray, cut: float) -> tuple[int, int, float, float]:
    """First and last index with ``t >= cut``; the ends interpolated to the crossings."""
    idx = np.flatnonzero(t >= cut)
    k0, k1 = int(idx[0]), int(idx[-1])
    lo, hi = float(tau[k0]), float(tau[k1])
    if k0 > 0:
        lo = float(np.interp(cut, t[k0 - 1 : k0 + 1], tau[k0 - 1 : k0 + 1]))
    if k1 < tau.size - 1:
        hi = float(np.interp(-cut, -t[k1 : k1 + 2], tau[k1 : k1 + 2]))
    return k0, k1, lo, hi


def _check(starts, ends, mean, sd, alpha, family, level, min_windows, nugget, draws):
    s, e, y, sig = (np.asarray(v, dtype=float) for v in (starts, ends, mean, sd))
    if not (s.ndim == 1 and s.shape == e.shape == y.shape == sig.shape):
        raise HosidInputError("starts, ends, mean and sd must be 1-d and of one length")
    if not (np.all(np.isfinite(s) & np.isfinite(e) & (e > s)) and np.all(np.diff(s) > 0)):
        raise HosidInputError("windows need finite start < end, and increasing starts")
    if np.any(sig <= 0):
        raise HosidInputError("a window sd must be positive (NaN marks a failed window)")
    if not (0 < alpha < 1 and 0 < level < 1 and 0 <= nugget < 1 <= min(family, min_windows)):
        raise HosidInputError("need 0<alpha,level<1, 0<=nugget<1, family>=1, min_windows>=1")
    if draws + 1 < math.ceil(family / alpha):
        raise HosidInputError(f"draws={draws} cannot reach the level {alpha}/{family}")
    return s, e, y, sig


def scan(
    starts,
    ends,
    mean,
    sd,
    *,
    rng: np.random.Generator,
    parameter: str = "",
    alpha: float = 0.05,
    family: int = 1,
    level: float = 0.95,
    min_windows: int = 2,
    baseline: tuple[float, float] | None = None,
    baseline_windows: int = 0,
    nugget: float = NUGGET,
    draws: int = 4000,
) -> Scan:
    r"""Named step changes of one parameter's track, each test at level ``alpha / family``.

    **Test.** :math:`T_{\max}` over :data:`GRID_PER_STEP` candidate times per window
    step, from the end of the first ``min_windows`` windows to the start of the last
    ``min_windows``.  With ``draws`` Monte-Carlo null maxima (:func:`null_maxima`),
    :math:`p = (1 + \#\{T^{null}_{\max} \ge T_{\max}\}) / (1 + \mathrm{draws})`; a
    change is named iff :math:`p \le \alpha/P`, an exact level-:math:`\alpha/P` test
    under the model (``threshold`` is the order statistic this amounts to).

    **Named change.** :math:`\hat\tau = \arg\max T`; time interval the hull of
    :math:`\{\tau : T_{\max} - T(\tau) \le c\}` (the profile LR inverted).  The
    change-point LR is not regular: :math:`c = \chi^2_1(\mathrm{level})` under-covers
    (0.89-0.94 at 0.95 for 1.5-3 sigma steps, 400 tracks each), so :math:`c` is
    calibrated on tracks simulated from the fitted step (:func:`lr_cut`; measured
    0.93-0.95, 1000 tracks each).  Size :math:`\hat\delta(\hat\tau)`, its interval the
    union over the time interval of :math:`\hat\delta(\tau) \pm z_{(1+\mathrm{level})/2}\,
    \mathrm{sd}\,\hat\delta(\tau)`, so the time uncertainty widens it.

    **Several changes** (binary segmentation): the windows wholly before the time
    interval (:math:`e_i \le` ``time_lo``) and wholly after it (:math:`s_i \ge`
    ``time_hi``) are scanned again, each with its own Monte-Carlo null at the same
    level, while a segment has ``2 * min_windows`` windows.  (Cutting at the interval
    rather than at :math:`\hat\tau` keeps the other regime's windows out of a segment
    when :math:`\hat\tau` misses by a window.)  The family-wise level holds for a
    parameter's first change; a spurious second change follows a real one with
    probability about :math:`2\alpha/P`.

    **Nugget.** The overlap correlation of overlapping windows is nearly singular, and
    GLS leans on window differences it takes as nearly noiseless: an independent 2 % of
    each window's variance (Monte-Carlo error, edges, nonlinearity) lifts a 5 % test's
    false alarms to 15 % (10 %: to 49 %).  ``nugget`` :math:`\nu` = 0.1 holds 5 % up to a
    true 0.1, is slightly conservative when the overlap model is exact, and costs no
    measurable power; it does nothing to windows that do not overlap.

    Parameters
    ----------
    starts, ends : array_like
        Windows :math:`[s_i, e_i)`, s; starts increasing; windows may overlap.
    mean, sd : array_like
        The parameter's posterior mean and sd per window; NaN marks a failed window.
    rng, parameter : numpy.random.Generator, str
        Source of the Monte-Carlo tracks; the name carried into each :class:`Change`.
    alpha, family, level : float, int, float
        Test level ``alpha / family`` (Bonferroni); level of the intervals.
    min_windows : int
        Windows needed wholly on each side of a candidate time.
    baseline : (mean, sd), optional
        A reference fit: one more observation wholly before the first window,
        uncorrelated with them; :math:`\tau` may then lie anywhere from the first start.
    baseline_windows : int
        The first K windows are the reference: :math:`\tau` after the end of window K.
    nugget, draws : float, int
        :math:`\nu` in [0, 1); Monte-Carlo tracks per test and per time interval.

    Returns
    -------
    Scan
        The named changes (possibly none), or ``reason`` when no test was possible.
    """
    s, e, y, sig = _check(starts, ends, mean, sd, alpha, family, level, min_windows, nugget, draws)
    if baseline is not None and not (np.all(np.isfinite(baseline)) and baseline[1] > 0):
        raise HosidInputError("a baseline needs a finite mean and a positive finite sd")
    a = alpha / family
    usable = np.flatnonzero(np.isfinite(y) & np.isfinite(sig))
    if usable.size < 2 * min_windows:
        why = f"{usable.size} usable windows of {y.size}; a scan needs {2 * min_windows}"
        return Scan(parameter, (), why, int(usable.size), a)
    z = float(stats.norm.ppf(0.5 + level / 2))
    k_max = math.floor(a * (draws + 1) - 1 + 1e-9)  # null maxima allowed >= T_max
    changes: list[Change] = []
    reason, dispersion = None, math.nan
    stack = [(usable, baseline, baseline_windows, True)]
    while stack:
        idx, base, k_ref, first = stack.pop()
        if idx.size < 2 * min_windows:
            continue
        k_eff = k_ref if base is not None else max(k_ref, min_windows)
        lo = float(s[idx[0]]) if k_eff == 0 else float(np.max(e[idx[:k_eff]]))
        hi = float(s[idx[-min_windows]])
        if lo > hi:
            if first:
                reason = f"no admissible change time in {idx.size} usable windows"
            continue
        tau = tau_grid(s[idx], e[idx], lo, hi)
        prof = profile(s[idx], e[idx], y[idx], sig[idx], tau, base, nugget)
        null = null_maxima(prof.directions, draws, rng)
        best = int(np.argmax(prof.statistic))
        t_max = float(prof.statistic[best])
        threshold = float(-np.partition(-null, k_max)[k_max])
        named = t_max > threshold
        if first:  # residual SS per degree of freedom
            dispersion = (prof.rss0 - named * t_max) / (idx.size + (base is not None) - 1 - named)
        if not named:
            continue
        cut = lr_cut(prof.directions, best, t_max, level, draws, rng)
        k0, k1, t_lo, t_hi = _hull(tau, prof.statistic, t_max - cut)
        sz, band = prof.size[k0 : k1 + 1], z * prof.size_se[k0 : k1 + 1]
        d_lo, d_hi = float(np.min(sz - band)), float(np.max(sz + band))
        p = (1 + int(np.count_nonzero(null >= t_max))) / (1 + draws)
        t_hat, d_hat, mu = float(tau[best]), float(prof.size[best]), float(prof.before[best])
        est = (t_hat, t_lo, t_hi, d_hat, d_lo, d_hi, mu, t_max, p, threshold, a, level)
        changes.append(Change(parameter, *est))
        stack.append((idx[e[idx] <= t_lo], base, k_ref, False))
        stack.append((idx[s[idx] >= t_hi], None, 0, False))
    changes.sort(key=lambda c: c.time)
    return Scan(parameter, tuple(changes), reason, int(usable.size), a, float(dispersion))


def find_changes(
    tracks: Mapping[str, tuple[Sequence[float], Sequence[float]]],
    starts,
    ends,
    *,
    rng: np.random.Generator,
    alpha: float = 0.05,
    family: int | None = None,
    baselines: Mapping[str, tuple[float, float]] | None = None,
    **options,
) -> dict[str, Scan]:
    """:func:`scan` every parameter at ``alpha / P`` (Bonferroni): ``{parameter: Scan}``.

    ``tracks`` is ``{parameter: (mean, sd)}`` over the shared windows ``starts, ends``;
    with :math:`P` = ``family`` (default: the number of tracks) the chance of any change
    named in a record without one is at most ``alpha``, however the tracks depend.
    ``baselines``: ``{parameter: (mean, sd)}`` of reference fits; ``options`` go to
    :func:`scan`; :func:`all_changes` lists the named changes.
    """
    p = max(len(tracks) if family is None else family, 1)
    baselines = baselines or {}
    common = dict(rng=rng, alpha=alpha, family=p, **options)
    return {
        name: scan(starts, ends, m, sd, baseline=baselines.get(name), **common, parameter=name)
        for name, (m, sd) in tracks.items()
    }


def all_changes(scans: Mapping[str, Scan]) -> list[Change]:
    """The named changes of all parameters (:func:`find_changes`), sorted by time."""
    return sorted((c for sc in scans.values() for c in sc.changes), key=lambda c: c.time)
