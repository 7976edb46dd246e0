r"""The step model of ``hosid monitor``'s change test, and its Monte-Carlo primitives
(the test itself: :func:`hosid.monitor.joint.joint_changes`).

Window :math:`i` covers :math:`[s_i, e_i)`; its fit gives the posterior mean vector
:math:`y_i` of the model's :math:`P` parameters and their covariance :math:`C_i = L_i
L_i^T`.  A step :math:`\delta` of parameter :math:`p` (unit vector :math:`e_p`) at time
:math:`\tau` is the model

.. math::

    y_i = \mu + \delta\, e_p\, f_i(\tau) + \varepsilon_i, \qquad
    f_i(\tau) = \operatorname{clip}\Big(\frac{e_i - \tau}{e_i - s_i}, 0, 1\Big), \qquad
    \operatorname{Cov}(\varepsilon_i, \varepsilon_j) = \rho_{ij}\, L_i L_j^T,

    \rho_{ij} = (1 - \nu)\, \frac{|[s_i, e_i) \cap [s_j, e_j)|}{\sqrt{(e_i - s_i)(e_j - s_j)}}
              + \nu\, [i = j],

with :math:`\mu` the unknown vector before the change; :math:`f_i` is the share of
window :math:`i` after the step (:func:`share_after`), so a window straddling it
estimates the mixture; the overlap term (:func:`overlap_correlation`) is, to first
order, the correlation of estimates from overlapping stretches of one stationary
record.  Stacking the windows, whitening by the Cholesky factor :math:`S` of the
stacked covariance (:math:`z = S^{-1} y`) and projecting out the :math:`P` columns of
:math:`\mu` (projector :math:`M`) leaves for each candidate :math:`(p, \tau)` the column
:math:`g = M S^{-1} (f(\tau) \otimes e_p)` and

.. math::

    \hat\delta = \frac{g^T z}{g^T g}, \qquad
    \operatorname{Var}\hat\delta = \frac{1}{g^T g}, \qquad
    T = \frac{\hat\delta^2}{\operatorname{Var}\hat\delta} = (a^T z)^2,
    \quad a = \frac{g}{\lVert g \rVert}.

Without a change :math:`a^T z = a^T w`, :math:`w \sim N(0, I)` (:math:`a` is orthogonal
to :math:`\mu`'s columns), so :math:`T` at every candidate of many Monte-Carlo records
is one matrix product :math:`(W A)^2` (:func:`null_maxima`); records simulated from a
fitted step calibrate the time interval (:func:`lr_cut`).

**Nugget.** The overlap correlation of overlapping windows is nearly singular, and GLS
leans on window differences it takes as nearly noiseless: an independent share of each
window's variance (Monte-Carlo error, edges, nonlinearity) lifts the false alarms of a
5 % test (50 %-overlapping windows, 1000 records each: a true 2 % to 0.066-0.079, a true
10 % to 0.14 over 16 windows and 0.28 over 40).  :data:`NUGGET` :math:`\nu` = 0.1 holds
them at 0.045-0.060 and, with no such share, at 0.049-0.055 (0.052 over 4000 records of
three parameters); it does nothing to windows that do not overlap.  No I/O.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

__all__ = [
    "ALPHA",
    "NUGGET",
    "Change",
    "lr_against",
    "lr_cut",
    "lr_extra",
    "null_maxima",
    "overlap_correlation",
    "share_after",
]

#: Default chance of naming a change in a stationary record (``hosid monitor --alpha``):
#: an operator acts on an alarm, so one false alarm in a hundred records, not twenty.
ALPHA = 0.01
#: At most this many floats in one block of Monte-Carlo statistics (draws x candidates).
CHUNK_ELEMENTS = 2_000_000
#: Smaller products bypass BLAS, which took up to 1000 times longer on a busy machine.
BLAS_MIN = 20_000_000
#: Default nugget :math:`\nu` (matters only for overlapping windows; module docstring).
NUGGET = 0.1


@dataclass(frozen=True)
class Change:
    r"""A named change of ``parameter``: ``time`` :math:`\hat\tau` in ``[time_lo,
    time_hi]``, ``size`` :math:`\hat\delta` (after minus before) in ``[size_lo,
    size_hi]`` (intervals at ``level``), ``before`` :math:`\hat\mu_p`, and the test
    that named it: ``statistic`` above ``threshold``, i.e. ``p_value <= alpha`` (the
    level of that test).  ``role`` is ``first`` (the test's maximum), ``companion`` (it
    stepped too) or ``alternative``: a step of it alone explains the records as well as
    the others' up to chance; then ``statistic`` is the likelihood ratio of the others'
    step against its own, which stayed at or below ``threshold`` (``p_value`` > ``alpha``
    = 1 - level: :func:`lr_against`).
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
    role: str = "first"


def share_after(starts, ends, tau) -> np.ndarray:
    r"""The share :math:`f_i(\tau)` of window :math:`i` after :math:`\tau`.

    Parameters
    ----------
    starts, ends : array_like (windows,)
        The windows :math:`[s_i, e_i)`.
    tau : array_like
        Candidate times, any shape.

    Returns
    -------
    ndarray (windows, \*tau.shape)
    """
    s, e, t = (np.asarray(v, dtype=float) for v in (starts, ends, tau))
    shape = s.shape + (1,) * t.ndim
    return np.clip((e.reshape(shape) - t) / (e - s).reshape(shape), 0.0, 1.0)


def overlap_correlation(starts, ends) -> np.ndarray:
    r"""Overlap correlation :math:`|I_i \cap I_j| / \sqrt{|I_i||I_j|}` of window averages.

    Exact for averages of a short-memory stationary sequence; first order for smooth
    functions of them.  Returns the (windows, windows) matrix.
    """
    s, e = np.asarray(starts, dtype=float), np.asarray(ends, dtype=float)
    ov = np.clip(np.minimum(e[:, None], e[None, :]) - np.maximum(s[:, None], s[None, :]), 0, None)
    ln = e - s
    return ov / np.sqrt(ln[:, None] * ln[None, :])


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
    r""":math:`T_{\max} = \max_c (a_c^T w)^2` of ``draws`` records without a change.

    Parameters
    ----------
    directions : ndarray (N, candidates)
        The unit columns :math:`a_c` (zero columns allowed), whitened and orthogonal to
        :math:`\mu`'s columns.
    draws : int
    rng : numpy.random.Generator

    Returns
    -------
    ndarray (draws,)
    """
    return _simulate(directions, draws, rng, 0.0, lambda t: t.max(axis=1))


def lr_cut(bases: np.ndarray, best: int, fitted: np.ndarray, level: float, draws, rng) -> float:
    r"""The ``level`` quantile of the LR :math:`\max_\tau T^*(\tau) - T^*(\hat\tau)`.

    A step of :math:`k \ge 1` parameters at one time :math:`\tau` spans at each
    candidate time the orthonormal columns :math:`q_{l\tau}` (``bases[l][:, j]``); its
    statistic is :math:`T(\tau) = \sum_l (q_{l\tau}^T z)^2`.  Over ``draws`` records
    simulated from the fitted step :math:`\hat m` (``fitted``, whitened: a parametric
    bootstrap) with :math:`z^* = \hat m + w`, the LR at the fitted time :math:`\hat\tau`
    (index ``best``) plays the LR at the true time, so that :math:`\{\tau : \max T -
    T(\tau) \le c\}` covers it at about ``level``.  The change-point LR is not
    regular: :math:`c = \chi^2_1(0.95)` covered the true time in 0.917 and 0.896 of
    1000 records with steps of 3 and 1.5 sd (one parameter, 40 windows), this cut in
    0.947 and 0.952.

    Parameters
    ----------
    bases : ndarray (k, N, times) or (N, times)
        Orthonormal columns per time (zero where a column vanishes).
    best : int
        Index of :math:`\hat\tau`.
    fitted : ndarray (N,)
        The fitted step, whitened and projected as the columns are.
    level : float
    draws : int
    rng : numpy.random.Generator
    """
    q = np.asarray(bases, dtype=float)
    q = q[None] if q.ndim == 2 else q
    k, n, m = q.shape
    flat = q.transpose(1, 0, 2).reshape(n, k * m)
    shift = np.asarray(fitted, dtype=float) @ flat

    def reduce(t):
        t = t.reshape(t.shape[0], k, m).sum(axis=1)
        return t.max(axis=1) - t[:, best]

    return float(np.quantile(_simulate(flat, draws, rng, shift, reduce), level))


def _stack(bases, more) -> tuple[np.ndarray, int, int]:
    """The columns ``bases`` (k, N, times) and ``more`` (c, N, times) side by side."""
    q = np.asarray(bases, dtype=float)
    q = q[None] if q.ndim == 2 else q
    k, n, m = q.shape
    more = np.asarray(more, dtype=float).reshape(-1, n, m)
    flat = np.concatenate([q, more]).transpose(1, 0, 2).reshape(n, -1)
    return flat, k, m


def lr_against(bases, single, fitted, draws: int, rng: np.random.Generator) -> np.ndarray:
    r"""The LR :math:`\max_\tau T^*_S(\tau) - \max_\tau T^*_q(\tau)` of ``draws`` records
    simulated from a step of parameter :math:`q` alone (a parametric bootstrap).

    :math:`T_S(\tau) = \sum_l (q_{l\tau}^T z)^2` is the statistic of the named step
    (orthonormal ``bases`` as in :func:`lr_cut`), :math:`T_q(\tau) = (a_{q\tau}^T z)^2`
    that of :math:`q` alone (unit columns ``single``), and :math:`z^* = \hat m_q + w` with
    ``fitted`` :math:`\hat m_q` the step of :math:`q` fitted at its own best time.  The
    observed LR beyond the ``level`` quantile of these rejects :math:`q` alone at
    :math:`1 -` ``level``.

    Parameters
    ----------
    bases : ndarray (k, N, times) or (N, times)
    single : ndarray (N, times)
    fitted : ndarray (N,)
    draws : int
    rng : numpy.random.Generator

    Returns
    -------
    ndarray (draws,)
    """
    flat, k, m = _stack(bases, single)
    shift = np.asarray(fitted, dtype=float) @ flat

    def reduce(t):
        joint = t[:, : k * m].reshape(t.shape[0], k, m).sum(axis=1).max(axis=1)
        return joint - t[:, k * m :].max(axis=1)

    return _simulate(flat, draws, rng, shift, reduce)


def lr_extra(bases, extra, fitted, draws: int, rng: np.random.Generator) -> np.ndarray:
    r"""The LR :math:`\max_{c,\tau} [T^*_S(\tau) + (b_{c\tau}^T z^*)^2] - \max_\tau
    T^*_S(\tau)` of the best extra parameter :math:`c` stepping with the named ones, over
    ``draws`` records simulated from the named step alone (``fitted``, whitened):
    :math:`z^* = \hat m_S + w`.

    The time is refitted with the extra parameter, so the LR is not :math:`\chi^2_1`: a
    companion can move the common time to where its own noise is largest, more so when
    the named step's time is poorly known (a late change).

    Parameters
    ----------
    bases : ndarray (k, N, times) or (N, times)
        The named parameters' orthonormal columns (as in :func:`lr_cut`).
    extra : ndarray (c, N, times)
        Each candidate's unit columns orthogonalized to ``bases`` at each time.
    fitted : ndarray (N,)
    draws : int
    rng : numpy.random.Generator

    Returns
    -------
    ndarray (draws,)
    """
    flat, k, m = _stack(bases, extra)
    shift = np.asarray(fitted, dtype=float) @ flat

    def reduce(t):
        t = t.reshape(t.shape[0], -1, m)
        t_S = t[:, :k].sum(axis=1)
        return (t_S[:, None, :] + t[:, k:]).max(axis=(1, 2)) - t_S.max(axis=1)

    return _simulate(flat, draws, rng, shift, reduce)
