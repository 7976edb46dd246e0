r"""Which parameters changed, when and by how much: ``hosid monitor``'s change test, on
all of a window's parameters at once.

The step model, the whitened columns :math:`g_{p\tau}` and the statistic
:math:`T_p(\tau) = (a_{p\tau}^T z)^2` are those of :mod:`hosid.monitor.changes`.  The
parameters that do not change pin :math:`\mu` down from every window, so a change of one
parameter is measured with its information *given the others* (for the paper
oscillator's stiffness about twice as precise as its marginal posterior, a2 and n2
being strongly correlated), and the step of the wrong parameter fits worse than the
right one's.

**Test.** The candidates are every parameter :math:`p` and :data:`PER_STEP` times
:math:`\tau` per window step (and every window edge) that leave ``min_windows`` windows
on each side, the nearest of them at least half on its side.  The test names
:math:`(\hat p, \hat\tau) = \arg\max T_p(\tau)` when

.. math::

    p = \frac{1 + \#\{T^{null}_{\max} \ge T_{\max}\}}{1 + \mathrm{draws}} \le \alpha,

with :math:`T^{null}_{\max}` the Monte-Carlo null maxima over all parameters' and times'
columns at once (:func:`~hosid.monitor.changes.null_maxima`): one exact level-:math:`\alpha`
test of the family of parameters and times, without Bonferroni.

**Companions.** Other parameters stepping at the same time join one at a time (forward
selection): the one whose joint step with those named already, refitted at a common
time, raises :math:`\max_\tau T` most joins while that likelihood ratio's p-value, from
records simulated from the named step alone (:func:`~hosid.monitor.changes.lr_extra`: the
common time is refitted, so the ratio is not :math:`\chi^2_1`), is at most
:math:`\alpha/2`.  (Tested against the first alone, each parameter correlated with a true
companion would be named as well.)

**Alternatives.** Strongly correlated parameters (the paper oscillator's a2 and n2) can
leave the test unable to tell which of them stepped: a step of another parameter
:math:`q` alone may explain the windows as well as the named set, up to chance.  Each
such :math:`q` is tested against the named set by the likelihood ratio
:math:`\max_\tau T_S - \max_\tau T_q` over records simulated from :math:`q`'s own fitted
step (:func:`~hosid.monitor.changes.lr_against`); where it is not rejected at
:math:`1 -` :data:`ALTERNATIVES` the parameter is named too, with ``role``
``alternative``, refitted with the others at their common time: the named parameters
are then a set that holds the one that stepped, and the report says that the data do
not tell them apart.

**Intervals.** The named parameters' common time :math:`\hat\tau` maximizes their joint
statistic :math:`T_S(\tau)` (the squared norm of :math:`z` projected on their columns at
:math:`\tau`); the time interval is :math:`\{\tau : T_S(\hat\tau) - T_S(\tau) \le c\}`,
its ends interpolated between candidate times, with :math:`c` calibrated on records
simulated from the fitted step (:func:`~hosid.monitor.changes.lr_cut`).  Sizes are the
joint GLS steps at :math:`\hat\tau`; a size interval is the union over the time
interval of the Wald intervals, so the time uncertainty widens it.

**Several changes** (binary segmentation): the windows wholly before the time interval
and those wholly after it are tested again, each at :math:`\alpha/4` with its own
Monte-Carlo null (cutting at the interval rather than at :math:`\hat\tau` keeps the other
regime's windows out of a segment).  With companions, a record with one change gets a
wrong extra name at a rate of at most about :math:`\alpha` (measured over 1000 records
with a 3-sd step: 0.025 for one parameter, 0.041 for three, before alternatives were
named: an alternative is not a wrong name but the set the records allow).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from scipy import linalg, stats

from ..errors import HosidInputError
from .changes import (
    ALPHA,
    NUGGET,
    Change,
    lr_against,
    lr_cut,
    lr_extra,
    null_maxima,
    overlap_correlation,
    share_after,
)

__all__ = ["joint_changes"]

#: Candidate times per window step.
PER_STEP = 10
#: Level of the set of parameters that may have stepped (module docstring, Alternatives).
ALTERNATIVES = 0.95


def _factor(c: np.ndarray) -> np.ndarray:
    c = 0.5 * (c + c.T)
    for jitter in (0.0, 1e-10, 1e-8, 1e-6):
        try:
            return linalg.cholesky(c + jitter * np.diag(np.diag(c)), lower=True)
        except linalg.LinAlgError:
            continue
    return np.diag(np.sqrt(np.clip(np.diag(c), 1e-300, None)))


class _Stack:
    """The whitened stacked windows (and an optional baseline observation)."""

    def __init__(self, starts, ends, Y, C, baseline, nugget):
        n, P = Y.shape
        rho = (1.0 - nugget) * overlap_correlation(starts, ends) + nugget * np.eye(n)
        Ls = [_factor(c) for c in C]
        cov = np.block([[rho[i, j] * Ls[i] @ Ls[j].T for j in range(n)] for i in range(n)])
        y = Y.reshape(-1)
        if baseline is not None:  # one observation wholly before the first window
            cov = linalg.block_diag(cov, np.diag(np.square(baseline[1])))
            y = np.concatenate([y, baseline[0]])
        self.rows, self.P, self.S = n, P, _factor(cov)
        self.z = linalg.solve_triangular(self.S, y, lower=True)
        eye = np.tile(np.eye(P), (y.size // P, 1))
        self.Xmu = linalg.solve_triangular(self.S, eye, lower=True)
        self.Q = np.linalg.qr(self.Xmu)[0]
        self.r = self.z - self.Q @ (self.Q.T @ self.z)

    def _whiten(self, p: int, f: np.ndarray) -> np.ndarray:
        x = np.zeros((self.S.shape[0], *f.shape[1:]))
        x[p : self.rows * self.P : self.P] = f
        return linalg.solve_triangular(self.S, x, lower=True)

    def columns(self, p: int, f: np.ndarray) -> np.ndarray:
        r""":math:`g_{p\tau}` for the shares ``f`` (windows x times)."""
        g = self._whiten(p, f)
        return g - self.Q @ (self.Q.T @ g)

    def before(self, params, f: np.ndarray, sizes) -> np.ndarray:
        r""":math:`\hat\mu` given steps ``sizes`` of ``params`` with the shares ``f``."""
        step = sum(d * self._whiten(p, f) for p, d in zip(params, sizes, strict=True))
        return np.linalg.lstsq(self.Xmu, self.z - step, rcond=None)[0]


def _grid(starts, ends, lo, hi) -> np.ndarray:
    step = float(np.median(np.diff(starts))) if starts.size > 1 else float(ends[0] - starts[0])
    k = max(math.ceil((hi - lo) / step * PER_STEP), 1) + 1
    edges = np.concatenate([starts, ends])
    return np.unique(
        np.concatenate([np.linspace(lo, hi, k), edges[(edges >= lo) & (edges <= hi)]])
    )


def _span(s, e, mw, baseline, floor) -> tuple[float, float]:
    """Candidate times: ``mw`` windows on each side, the nearest at least half."""
    lo = float(s[0]) if baseline else float(e[mw - 1] - (e[mw - 1] - s[mw - 1]) / 2)
    return max(lo, floor), float(s[-mw] + (e[-mw] - s[-mw]) / 2)


def _unit(g: np.ndarray, basis: Sequence[np.ndarray]) -> np.ndarray:
    """The columns ``g`` orthogonalized to ``basis`` per time and normed (0 if none left)."""
    b = g.copy()
    for q in basis:
        b -= q * np.einsum("ij,ij->j", q, b)
    nb, ng = np.einsum("ij,ij->j", b, b), np.einsum("ij,ij->j", g, g)
    ok = nb > 1e-9 * ng + 1e-300
    return np.where(ok, b / np.sqrt(np.where(ok, nb, 1.0)), 0.0)


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


def _segment(s, e, Y, C, names, opts, rng, baseline, floor) -> list[Change]:
    n, P = Y.shape
    mw, alpha, level, draws = opts["min_windows"], opts["alpha"], opts["level"], opts["draws"]
    if n < (mw if baseline is not None else 2 * mw):
        return []
    lo, hi = _span(s, e, mw, baseline is not None, floor)
    if hi <= lo:
        return []
    tau = _grid(s, e, lo, hi)
    st = _Stack(s, e, Y, C, baseline, opts["nugget"])
    f = share_after(s, e, tau)
    G = [st.columns(p, f) for p in range(P)]
    A = [_unit(g, []) for g in G]
    T = (np.hstack(A).T @ st.r) ** 2
    best = int(np.argmax(T))
    t_max = float(T[best])
    null = null_maxima(np.hstack(A), draws, rng)
    p_value = (1 + int(np.sum(null >= t_max))) / (1 + null.size)
    if p_value > alpha:
        return []
    k_max = math.floor(alpha * (draws + 1) - 1 + 1e-9)  # null maxima allowed >= t_max
    threshold = float(-np.partition(-null, k_max)[k_max])
    first = (t_max, p_value, threshold, alpha, "first")
    S, Q, t_S, tests = _companions(st.r, G, A, best // tau.size, first, draws, rng)
    S, Q, t_S, tests = _alternatives(st.r, G, A, (S, Q, t_S, tests), draws, rng)
    named = _estimate(st, G, Q, S, t_S, tau, f, names, tests, level, draws, rng)
    t_lo, t_hi = named[0].time_lo, named[0].time_hi
    # the sides: windows wholly outside the time interval (none from the other regime)
    left, right = e <= t_lo, s >= t_hi
    sub = {**opts, "alpha": alpha / 4}  # further changes: at most alpha / 2 in all
    named += _segment(s[left], e[left], Y[left], C[left], names, sub, rng, baseline, floor)
    named += _segment(s[right], e[right], Y[right], C[right], names, sub, rng, None, -np.inf)
    return named


def _fitted(Q, r, j) -> np.ndarray:
    """The step of the columns ``Q`` at time index ``j`` fitted to ``r`` (whitened)."""
    cols = np.stack([q[:, j] for q in Q], 1)
    return cols @ (cols.T @ r)


def _companions(r, G, A, p, first, draws, rng):
    """Forward selection of the parameters stepping together with ``p`` (module
    docstring): their indices, orthonormal columns, joint statistic, and tests (``first``:
    that of ``p``).
    """
    P, a_q = len(G), first[3] / 2
    S, Q, t_S, tests = [p], [A[p]], (A[p].T @ r) ** 2, [first]
    while len(S) < P:
        cand = {q: _unit(G[q], Q) for q in range(P) if q not in S}
        gain = {q: t_S + (b.T @ r) ** 2 for q, b in cand.items()}
        q = max(gain, key=lambda q: float(gain[q].max()))
        lr = float(gain[q].max() - t_S.max())
        if lr <= 0:
            break
        fitted = _fitted(Q, r, int(np.argmax(t_S)))
        sims = lr_extra(np.stack(Q), np.stack(list(cand.values())), fitted, draws, rng)
        p_value = (1 + int(np.sum(sims >= lr))) / (1 + draws)
        if p_value > a_q:
            break
        S.append(q)
        Q.append(cand[q])
        t_S = gain[q]
        tests.append((lr, p_value, float(np.quantile(sims, 1 - a_q)), a_q, "companion"))
    return S, Q, t_S, tests


def _alternatives(r, G, A, named, draws, rng):
    """The named set with the parameters whose step alone is not rejected against it at
    ``1 -`` :data:`ALTERNATIVES` (module docstring) added, refitted at a common time.
    """
    S, Q, t_S, tests = named
    keep = []
    for q in (q for q in range(len(G)) if q not in S):
        t_q = (A[q].T @ r) ** 2
        lr = float(t_S.max() - t_q.max())
        sims = lr_against(np.stack(Q), A[q], _fitted([A[q]], r, int(np.argmax(t_q))), draws, rng)
        p_value = (1 + int(np.sum(sims >= lr))) / (1 + draws)
        if p_value > 1 - ALTERNATIVES:
            keep.append((q, lr, p_value, float(np.quantile(sims, ALTERNATIVES))))
    for q, lr, p_value, cut in keep:
        b = _unit(G[q], Q)
        S, Q, t_S = [*S, q], [*Q, b], t_S + (b.T @ r) ** 2
        tests = [*tests, (lr, p_value, cut, 1 - ALTERNATIVES, "alternative")]
    return S, Q, t_S, tests


def _estimate(st, G, Q, S, t_S, tau, f, names, tests, level, draws, rng) -> list[Change]:
    """The named parameters' common time, its interval, their joint sizes over it."""
    j = int(np.argmax(t_S))
    fitted = _fitted(Q, st.r, j)
    cut = lr_cut(np.stack(Q), j, fitted, level, draws, rng)
    k0, k1, t_lo, t_hi = _hull(tau, t_S, float(t_S[j]) - cut)
    X = np.stack([G[p][:, k0 : k1 + 1] for p in S], 0)  # (k, N, times)
    H = np.linalg.pinv(np.einsum("anm,bnm->mab", X, X))
    sizes = np.einsum("mab,bm->ma", H, np.einsum("anm,n->am", X, st.r))
    band = stats.norm.ppf(0.5 + level / 2) * np.sqrt(
        np.clip(np.diagonal(H, axis1=1, axis2=2), 0.0, None)
    )
    lo, hi = np.min(sizes - band, axis=0), np.max(sizes + band, axis=0)
    mu = st.before(S, f[:, j], sizes[j - k0])
    return [
        Change(names[p], float(tau[j]), t_lo, t_hi, float(sizes[j - k0, i]), float(lo[i]),
               float(hi[i]), float(mu[p]), *tests[i][:4], level, tests[i][4])
        for i, p in enumerate(S)
    ]  # fmt: skip


def _check(s, e, Y, C, names, alpha, level, min_windows, baseline_windows, nugget, draws):
    n = s.size
    if s.ndim != 1 or e.shape != s.shape:
        raise HosidInputError("starts and ends must be 1-d and of one length")
    P = len(names)
    if P < 1 or Y.shape != (n, P) or C.shape != (n, P, P):
        raise HosidInputError(f"need mean (windows, P) and cov (windows, P, P) with P={P} names")
    if not (np.all(np.isfinite(s) & np.isfinite(e) & (e > s)) and np.all(np.diff(s) > 0)):
        raise HosidInputError("windows need finite start < end, and increasing starts")
    d = np.diagonal(C, axis1=1, axis2=2)
    if np.any(np.isfinite(d) & (d <= 0)):
        raise HosidInputError("a posterior sd must be positive (NaN marks a failed window)")
    if not (0 < alpha < 1 and 0 < level < 1 and 0 <= nugget < 1):
        raise HosidInputError("need 0 < alpha < 1, 0 < level < 1 and 0 <= nugget < 1")
    if min_windows < 1 or baseline_windows < 0:
        raise HosidInputError("need min_windows >= 1 and baseline_windows >= 0")
    if alpha * (draws + 1) < 1:
        raise HosidInputError(
            f"draws={draws} cannot reach alpha={alpha}: need {math.ceil(1 / alpha) - 1}"
        )


def joint_changes(
    starts: Sequence[float],
    ends: Sequence[float],
    mean: np.ndarray,
    cov: np.ndarray,
    names: Sequence[str],
    *,
    rng: np.random.Generator,
    alpha: float = ALPHA,
    level: float = 0.95,
    min_windows: int = 1,
    baseline: tuple[np.ndarray, np.ndarray] | None = None,
    baseline_windows: int = 0,
    nugget: float = NUGGET,
    draws: int = 4000,
) -> tuple[list[Change], str | None]:
    r"""Named changes of the parameters ``names`` (module docstring), and why nothing was
    tested.

    Parameters
    ----------
    starts, ends : array_like (windows,)
        The windows (s); starts increasing; windows may overlap.
    mean : ndarray (windows, P)
        Posterior means; a window with a NaN in its mean or covariance failed and is left
        out.
    cov : ndarray (windows, P, P)
        Posterior covariances.
    names : sequence of str
        The ``P`` parameters.
    rng : numpy.random.Generator
        Source of the Monte-Carlo null and of the time interval's bootstrap.
    alpha : float
        Chance of naming any change in a record without one; ``draws`` must reach it.
    level : float
        Of the time and size intervals.
    min_windows : int
        Windows on each side of a candidate time, the nearest one at least half on that
        side (default 1: a change late in a record is still looked for).
    baseline : (mean, sd), optional
        A reference fit's means and sds of ``names`` (each (P,)): an observation before
        every window, uncorrelated with them; a change may then lie anywhere from the
        first start.
    baseline_windows : int
        The first ``baseline_windows`` windows (failed ones included) are the reference:
        changes are sought only after their end.
    nugget : float
        :math:`\nu` in [0, 1) (:mod:`hosid.monitor.changes`).
    draws : int
        Monte-Carlo records of the null and of each time interval's bootstrap.

    Returns
    -------
    changes : list of Change
        Sorted by time, then parameter; empty if none was named.
    reason : str or None
        Why no test was possible (``None`` when one was made).
    """
    s, e = np.asarray(starts, dtype=float), np.asarray(ends, dtype=float)
    Y, C = np.asarray(mean, dtype=float), np.asarray(cov, dtype=float)
    _check(s, e, Y, C, names, alpha, level, min_windows, baseline_windows, nugget, draws)
    if baseline is not None:
        baseline = tuple(np.asarray(b, dtype=float).reshape(-1) for b in baseline)
        if not all(b.shape == (len(names),) and np.all(np.isfinite(b)) for b in baseline):
            raise HosidInputError("a baseline needs a finite mean and sd of every parameter")
        if np.any(baseline[1] <= 0):
            raise HosidInputError("a baseline sd must be positive")
    floor = float(e[baseline_windows - 1]) if 0 < baseline_windows <= e.size else -np.inf
    if baseline_windows >= e.size > 0:
        return [], f"no window after the {baseline_windows} baseline windows"
    ok = np.all(np.isfinite(Y), axis=1) & np.all(np.isfinite(C), axis=(1, 2))
    s, e, Y, C = s[ok], e[ok], Y[ok], C[ok]
    need = min_windows if baseline is not None else 2 * min_windows
    if s.size < need:
        return [], f"{s.size} of {ok.size} windows have a posterior; the test needs {need}"
    lo, hi = _span(s, e, min_windows, baseline is not None, floor)
    if hi <= lo:
        return [], f"no candidate time with {min_windows} windows on each side" + (
            f" after the {baseline_windows} baseline windows" if baseline_windows else ""
        )
    opts = dict(alpha=alpha, level=level, min_windows=min_windows, nugget=nugget, draws=draws)
    found = _segment(s, e, Y, C, list(names), opts, rng, baseline, floor)
    return sorted(found, key=lambda c: (c.time, c.parameter)), None
