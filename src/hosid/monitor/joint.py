r"""Which parameter changed, when and by how much: the change test on all of a window's
parameters at once.

Window :math:`i` gives a posterior mean vector :math:`y_i` of the model's :math:`P`
parameters with covariance :math:`C_i`.  A step of parameter :math:`p` alone at time
:math:`\tau` is the model

.. math::

    y_i = \mu + \delta\, e_p\, f_i(\tau) + \varepsilon_i, \qquad
    \operatorname{Cov}(\varepsilon_i, \varepsilon_j) = \rho_{ij}\, L_i L_j^T,
    \quad C_i = L_i L_i^T,

with :math:`\mu` the unknown vector before the change, :math:`f_i(\tau)` the share of
window :math:`i` after it and :math:`\rho_{ij}` the windows' overlap correlation
(:mod:`hosid.monitor.changes`, whose nugget it shares).  Stacking the windows,
whitening by the Cholesky factor :math:`S` of the stacked covariance and projecting out
the :math:`P` columns of :math:`\mu` (:math:`M = I - QQ^T`) leaves, for every candidate
:math:`(p, \tau)`, the column :math:`g_{p\tau} = M S^{-1}(f(\tau) \otimes e_p)` and

.. math::

    \hat\delta_p(\tau) = \frac{g_{p\tau}^T z}{g_{p\tau}^T g_{p\tau}}, \qquad
    T_p(\tau) = \frac{(g_{p\tau}^T z)^2}{g_{p\tau}^T g_{p\tau}}, \qquad z = S^{-1} y.

The parameters that do not change pin :math:`\mu` down from every window, so a change
of one parameter is measured with its information *given the others* (for the paper
oscillator's stiffness about twice as precise as its marginal posterior, a2 and n2
being strongly correlated), and the step of the wrong parameter fits worse than the
right one's.  The test names :math:`(\hat p, \hat\tau) = \arg\max T_p(\tau)` when
:math:`T_{\max}` exceeds the :math:`1 - \alpha` quantile of its Monte-Carlo null
(:func:`hosid.monitor.changes.null_maxima` over all parameters' columns at once: the
family of parameters and times, at level :math:`\alpha` without Bonferroni); another
parameter changing at about the same time is added when its likelihood ratio given the
first passes :math:`\chi^2_1` at :math:`\alpha/(2(P-1))`; changes at other times are
sought on either side (binary segmentation, each side at :math:`\alpha/4`), so that a
record with one change gets a wrong extra name at a rate of about :math:`\alpha`.  The
time interval inverts the likelihood ratio with its parametric-bootstrap cut
(:func:`hosid.monitor.changes.lr_cut`); the size interval is the union of the Wald
intervals over it.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from scipy import linalg, stats

from .changes import NUGGET, Change, lr_cut, null_maxima, overlap_correlation, share_after

__all__ = ["joint_changes"]

#: Candidate times per window step.
PER_STEP = 10


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
        blocks = [[rho[i, j] * Ls[i] @ Ls[j].T for j in range(n)] for i in range(n)]
        cov = np.block(blocks)
        y = Y.reshape(-1)
        self.rows = n
        if baseline is not None:  # one observation wholly before the first window
            cov = linalg.block_diag(cov, np.diag(np.square(baseline[1])))
            y = np.concatenate([y, baseline[0]])
        self.S = _factor(cov)
        self.P = P
        N = y.size
        self.z = linalg.solve_triangular(self.S, y, lower=True)
        Xmu = linalg.solve_triangular(self.S, np.tile(np.eye(P), (N // P, 1)), lower=True)
        self.Xmu = Xmu
        self.Q, _ = np.linalg.qr(Xmu)
        self.r = self.z - self.Q @ (self.Q.T @ self.z)

    def columns(self, p: int, f: np.ndarray) -> np.ndarray:
        r""":math:`g_{p\tau}` for the shares ``f`` (windows x times)."""
        N = self.S.shape[0]
        x = np.zeros((N, f.shape[1]))
        x[p : self.rows * self.P : self.P] = f
        g = linalg.solve_triangular(self.S, x, lower=True)
        return g - self.Q @ (self.Q.T @ g)

    def before(self, p: int, f: np.ndarray, size: float) -> np.ndarray:
        r""":math:`\hat\mu` given a step ``size`` of parameter ``p`` with shares ``f``."""
        x = np.zeros(self.S.shape[0])
        x[p : self.rows * self.P : self.P] = f
        xw = linalg.solve_triangular(self.S, x, lower=True)
        return np.linalg.lstsq(self.Xmu, self.z - size * xw, rcond=None)[0]


def _grid(starts, ends, lo, hi) -> np.ndarray:
    step = float(np.median(np.diff(starts))) if starts.size > 1 else float(ends[0] - starts[0])
    k = max(math.ceil((hi - lo) / step * PER_STEP), 1) + 1
    edges = np.concatenate([starts, ends])
    return np.unique(
        np.concatenate([np.linspace(lo, hi, k), edges[(edges >= lo) & (edges <= hi)]])
    )


def _segment(s, e, Y, C, names, opts, rng, baseline, lo_floor) -> list[Change]:
    n, P = Y.shape
    mw = opts["min_windows"]
    if n < 2 * mw and baseline is None:
        return []
    # a candidate time leaves min_windows windows on each side, up to half of the nearest
    # (a change in the last window's first half is still seen, by that window alone)
    lo = float(s[0]) if baseline is not None else float(e[mw - 1] - (e[mw - 1] - s[mw - 1]) / 2)
    lo = max(lo, lo_floor)
    hi = float(s[n - mw] + (e[n - mw] - s[n - mw]) / 2)
    if hi <= lo:
        return []
    tau = _grid(s, e, lo, hi)
    st = _Stack(s, e, Y, C, baseline, opts["nugget"])
    f = share_after(s, e, tau)
    G = [st.columns(p, f) for p in range(P)]
    norms = [np.sqrt(np.einsum("ij,ij->j", g, g)) for g in G]
    A = np.hstack([g / np.where(nm > 0, nm, np.inf) for g, nm in zip(G, norms, strict=True)])
    T = (A.T @ st.r) ** 2
    best = int(np.argmax(T))
    t_max = float(T[best])
    null = null_maxima(A, opts["draws"], rng)
    p_value = (1 + int(np.sum(null >= t_max))) / (1 + null.size)
    threshold = float(np.quantile(null, 1 - opts["alpha"]))
    if p_value > opts["alpha"]:
        return []
    m = tau.size
    p, k = divmod(best, m)
    a_p = A[:, p * m : (p + 1) * m]
    Tp = T[p * m : (p + 1) * m]
    cut = lr_cut(a_p, k, t_max, opts["level"], opts["draws"], rng)
    inside = Tp >= t_max - cut
    idx = np.flatnonzero(inside)
    gz = G[p].T @ st.r
    sizes = gz / np.square(norms[p])
    se = 1.0 / norms[p]
    z = stats.norm.ppf(0.5 + opts["level"] / 2)
    mu = st.before(p, f[:, k], float(sizes[k]))
    named = [
        Change(
            parameter=names[p],
            time=float(tau[k]),
            time_lo=float(tau[idx[0]]),
            time_hi=float(tau[idx[-1]]),
            size=float(sizes[k]),
            size_lo=float(np.min(sizes[idx] - z * se[idx])),
            size_hi=float(np.max(sizes[idx] + z * se[idx])),
            before=float(mu[p]),
            statistic=t_max,
            p_value=p_value,
            threshold=threshold,
            alpha=opts["alpha"],
            level=opts["level"],
        )
    ]
    named += _companions(st, G, norms, p, k, tau, f, names, opts, z)
    # the sides: windows wholly outside the time interval (none from the other regime)
    left, right = e <= float(tau[idx[0]]), s >= float(tau[idx[-1]])
    sub = {**opts, "alpha": opts["alpha"] / 4}  # further changes: at most alpha / 2 in all
    for side, base in ((left, baseline), (right, None)):
        if side.sum() >= 2 * mw or (base is not None and side.sum() >= mw):
            named += _segment(s[side], e[side], Y[side], C[side], names, sub, rng, base, -np.inf)
    return named


def _companions(st, G, norms, p, k, tau, f, names, opts, z) -> list[Change]:
    r"""Other parameters that change together with the first: for each ``q``, the
    likelihood ratio of a joint step of ``p`` and ``q`` at a common time (refitted)
    over the step of ``p`` alone, against :math:`\chi^2_1` at :math:`\alpha/(2(P-1))`.
    """
    P = len(G)
    if P < 2:
        return []
    a = G[p] / np.where(norms[p] > 0, norms[p], np.inf)
    ar = a.T @ st.r
    t_p = float(np.max(ar**2))
    crit = stats.chi2.ppf(1 - opts["alpha"] / 2 / (P - 1), 1)
    out = []
    for q in range(P):
        if q == p:
            continue
        b = G[q] - a * np.einsum("ij,ij->j", a, G[q])
        bb = np.einsum("ij,ij->j", b, b)
        ok = bb > 1e-9 * np.einsum("ij,ij->j", G[q], G[q]) + 1e-300
        br = b.T @ st.r
        t_pq = ar**2 + np.where(ok, br**2 / np.where(ok, bb, 1.0), 0.0)
        j = int(np.argmax(t_pq))
        lr = float(t_pq[j]) - t_p
        if lr <= crit:
            continue
        # the two steps at tau_j: solve the 2 x 2 normal equations in the whitened space
        X = np.stack([G[p][:, j], G[q][:, j]], 1)
        coef, cov = np.linalg.lstsq(X, st.r, rcond=None)[0], np.linalg.inv(X.T @ X)
        size, se = float(coef[1]), math.sqrt(float(cov[1, 1]))
        mu = st.before(q, f[:, j], size)
        out.append(
            Change(
                parameter=names[q],
                time=float(tau[j]),
                time_lo=float(tau[j]),
                time_hi=float(tau[j]),
                size=size,
                size_lo=size - z * se,
                size_hi=size + z * se,
                before=float(mu[q]),
                statistic=lr,
                p_value=float(stats.chi2.sf(lr, 1)),
                threshold=float(crit),
                alpha=opts["alpha"],
                level=opts["level"],
            )
        )
    return out


def joint_changes(
    starts: Sequence[float],
    ends: Sequence[float],
    mean: np.ndarray,
    cov: np.ndarray,
    names: Sequence[str],
    *,
    rng: np.random.Generator,
    alpha: float = 0.05,
    level: float = 0.95,
    min_windows: int = 1,
    baseline: tuple[np.ndarray, np.ndarray] | None = None,
    baseline_windows: int = 0,
    nugget: float = NUGGET,
    draws: int = 4000,
) -> tuple[list[Change], str | None]:
    """Named changes of the parameters ``names`` (module docstring), sorted by time, and
    why nothing was tested (``None`` when it was).

    Parameters
    ----------
    starts, ends : array_like
        The windows (s), increasing.
    mean : ndarray (windows, P)
        Posterior means; a row with a NaN is a failed window, left out.
    cov : ndarray (windows, P, P)
        Posterior covariances.
    names : sequence of str
        The ``P`` parameters.
    rng : numpy.random.Generator
        Source of the Monte-Carlo null and of the interval's bootstrap.
    alpha : float
        Chance of naming any change in a record without one.
    level : float
        Of the time and size intervals.
    min_windows : int
        Windows on each side of a candidate time, the nearest one at least half on
        that side (default 1: a change late in a record is still looked for).
    baseline : (mean, sd), optional
        A reference fit's means and sds of ``names``: an observation before every window.
    baseline_windows : int
        Changes are sought only after the first ``baseline_windows`` windows.
    nugget : float
        As in :func:`hosid.monitor.changes.scan`.
    draws : int
        Monte-Carlo tracks of the null.
    """
    s, e = np.asarray(starts, dtype=float), np.asarray(ends, dtype=float)
    Y, C = np.asarray(mean, dtype=float), np.asarray(cov, dtype=float)
    ok = np.all(np.isfinite(Y), axis=1) & np.all(np.isfinite(C), axis=(1, 2))
    ok &= np.all(np.diagonal(C, axis1=1, axis2=2) > 0, axis=1)
    s, e, Y, C = s[ok], e[ok], Y[ok], C[ok]
    if s.size < 2 * min_windows and baseline is None:
        return [], f"{s.size} windows with a posterior; the test needs {2 * min_windows}"
    if baseline is not None and s.size < min_windows:
        return [], f"{s.size} windows with a posterior; the test needs {min_windows}"
    opts = {"alpha": alpha, "level": level, "min_windows": min_windows, "nugget": nugget}
    opts["draws"] = draws
    floor = float(e[baseline_windows - 1]) if 0 < baseline_windows <= e.size else -np.inf
    if baseline_windows > e.size - min_windows:
        return [], f"no window after the {baseline_windows} baseline windows"
    if baseline is not None:
        baseline = (np.asarray(baseline[0], dtype=float), np.asarray(baseline[1], dtype=float))
    found = _segment(s, e, Y, C, list(names), opts, rng, baseline, floor)
    return sorted(found, key=lambda c: (c.time, c.parameter)), None
