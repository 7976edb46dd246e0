"""Plain-numpy reference for J2 and J4A: a Python loop over parameter sets.

For each parameter set, X_r = sum_j lambda_j Y_jr (eq 45) is formed with numpy and
Va (eq 47) and Vb (eqs 57-58) are block means computed with fancy indexing.  This is
what one would write without numba or batching; the benchmark compares hosid to it.
"""

from __future__ import annotations

import numpy as np


def _force(theta, Ysigned):
    """X = Y_0 + sum_j lambda_j Y_j, shape (N, 2K+1).

    (A plain weighted sum: ``np.tensordot`` of a real vector with a complex array
    takes numpy's slow mixed-type path and would be ~200x slower.)"""
    X = Ysigned[0].copy()
    for lam, Yj in zip(theta[:4], Ysigned[1:], strict=True):
        X += lam * Yj
    return X


def j2_reference(thetas, Ysigned, band_index, T, k2):
    """Eq (50) for each row of ``thetas`` (shape (P, 5))."""
    out = np.empty(len(thetas))
    for p, th in enumerate(thetas):
        X = _force(th, Ysigned)[:, band_index]
        va = np.mean(np.abs(X) ** 2, axis=0) / (2 * np.pi * T)
        out[p] = np.sum((va - k2 * th[4]) ** 2)
    return out


def j4a_reference(thetas, Ysigned, tri_index, gauss, T):
    """Eq (59) for each row of ``thetas`` (shape (P, 5))."""
    i1, i2, i3, i4 = tri_index.T
    out = np.empty(len(thetas))
    for p, th in enumerate(thetas):
        X = _force(th, Ysigned)
        vb = np.mean(X[:, i1] * X[:, i2] * X[:, i3] * np.conj(X[:, i4]), axis=0)
        vb /= 8 * np.pi**3 * T
        out[p] = np.sum(np.abs(vb - th[4] ** 2 * gauss) ** 2)
    return out
