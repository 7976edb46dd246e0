r"""Compiled kernels of the higher-order spectral components (J3, J4A, J4B).

Written by hand because no library forms block products of four Fourier ordinates on an
arbitrary triple domain: one pass over blocks and triples, no temporaries of size
(blocks x triples x features^2), blocks in parallel (numba threads).

``Ys`` holds the features' block transforms on signed bins, shape ``(F, B, 2K + 1)``;
``idx`` the domain's four bin positions per triple, ``(n, 4)``.
"""

from __future__ import annotations

import numpy as np

from .._jit import njit, prange

__all__ = ["contract", "contract3", "products", "products3"]


@njit(cache=True, parallel=True)
def products(Ys, idx, lam, c8):  # pragma: no cover - compiled
    r"""Per block and triple: :math:`q = X_1X_2X_3X_4^*/c_8` with
    :math:`X = \sum_f\lambda_fY_f`, and :math:`\partial q/\partial\lambda_f` for
    :math:`f \ge 1`.  Returns ``q (B, n)`` and ``dq (B, n, F - 1)``.
    """
    F, B = Ys.shape[0], Ys.shape[1]
    n = idx.shape[0]
    q = np.empty((B, n), dtype=np.complex128)
    dq = np.empty((B, n, F - 1), dtype=np.complex128)
    for b in prange(B):
        x = np.zeros(4, dtype=np.complex128)
        for t in range(n):
            x[:] = 0.0
            for f in range(F):
                for p in range(4):
                    x[p] += lam[f] * Ys[f, b, idx[t, p]]
            x[3] = np.conj(x[3])
            q[b, t] = x[0] * x[1] * x[2] * x[3] / c8
            for f in range(1, F):
                y0 = Ys[f, b, idx[t, 0]]
                y1 = Ys[f, b, idx[t, 1]]
                y2 = Ys[f, b, idx[t, 2]]
                y3 = np.conj(Ys[f, b, idx[t, 3]])
                dq[b, t, f - 1] = (
                    y0 * x[1] * x[2] * x[3]
                    + x[0] * y1 * x[2] * x[3]
                    + x[0] * x[1] * y2 * x[3]
                    + x[0] * x[1] * x[2] * y3
                ) / c8
    return q, dq


@njit(cache=True, parallel=True)
def contract(Ys, idx, w, c8):  # pragma: no cover - compiled
    r""":math:`K_{j,abcd} = \frac{1}{Bc_8}\sum_{b,t}\mathrm{Re}\,w_{btj}Y_a(k_1)Y_b(k_2)
    Y_c(k_3)Y_d^*(k_4)`, shape ``(J, F, F, F, F)``; ``w`` is ``(B, n, J)``.
    """
    F, B = Ys.shape[0], Ys.shape[1]
    n = idx.shape[0]
    J = w.shape[2]
    parts = np.zeros((B, J, F, F, F, F))  # one partial sum per block (parallel)
    for b in prange(B):
        K = parts[b]
        p1 = np.empty((F, F), dtype=np.complex128)
        p2 = np.empty((F, F), dtype=np.complex128)
        for t in range(n):
            for a in range(F):
                ya = Ys[a, b, idx[t, 0]]
                for d in range(F):
                    p1[a, d] = ya * np.conj(Ys[d, b, idx[t, 3]])
            for bb in range(F):
                yb = Ys[bb, b, idx[t, 1]]
                for c in range(F):
                    p2[bb, c] = yb * Ys[c, b, idx[t, 2]]
            for j in range(J):
                wj = w[b, t, j]
                for a in range(F):
                    for d in range(F):
                        u = wj * p1[a, d]
                        for bb in range(F):
                            for c in range(F):
                                K[j, a, bb, c, d] += (u * p2[bb, c]).real
    return parts.sum(axis=0) / (B * c8)


@njit(cache=True, parallel=True)
def products3(Ys, idx, lam, c3):  # pragma: no cover - compiled
    r"""Per block and pair: :math:`q = X_1X_2X_3^*/c_3` and
    :math:`\partial q/\partial\lambda_f` for :math:`f \ge 1` (``idx`` is ``(n, 3)``).
    """
    F, B = Ys.shape[0], Ys.shape[1]
    n = idx.shape[0]
    q = np.empty((B, n), dtype=np.complex128)
    dq = np.empty((B, n, F - 1), dtype=np.complex128)
    for b in prange(B):
        x = np.zeros(3, dtype=np.complex128)
        for t in range(n):
            x[:] = 0.0
            for f in range(F):
                for p in range(3):
                    x[p] += lam[f] * Ys[f, b, idx[t, p]]
            x[2] = np.conj(x[2])
            q[b, t] = x[0] * x[1] * x[2] / c3
            for f in range(1, F):
                y0 = Ys[f, b, idx[t, 0]]
                y1 = Ys[f, b, idx[t, 1]]
                y2 = np.conj(Ys[f, b, idx[t, 2]])
                dq[b, t, f - 1] = (y0 * x[1] * x[2] + x[0] * y1 * x[2] + x[0] * x[1] * y2) / c3
    return q, dq


@njit(cache=True, parallel=True)
def contract3(Ys, idx, w, c3):  # pragma: no cover - compiled
    r""":math:`K_{j,abc} = \frac{1}{Bc_3}\sum_{b,t}\mathrm{Re}\,w_{btj}Y_a(k_1)Y_b(k_2)
    Y_c^*(k_3)`, shape ``(J, F, F, F)``.
    """
    F, B = Ys.shape[0], Ys.shape[1]
    n = idx.shape[0]
    J = w.shape[2]
    parts = np.zeros((B, J, F, F, F))
    for b in prange(B):
        K = parts[b]
        for t in range(n):
            for a in range(F):
                ya = Ys[a, b, idx[t, 0]]
                for bb in range(F):
                    yab = ya * Ys[bb, b, idx[t, 1]]
                    for c in range(F):
                        p = yab * np.conj(Ys[c, b, idx[t, 2]])
                        for j in range(J):
                            K[j, a, bb, c] += (w[b, t, j] * p).real
    return parts.sum(axis=0) / (B * c3)
