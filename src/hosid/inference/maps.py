"""The quasi-log-likelihood over the damping plane: the valley of J2 and the twin minima
of J4 (paper Figures 7-8), for a fit's ``likelihood_map`` group.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:  # pragma: no cover
    from .estimate import Estimate

__all__ = ["likelihood_map"]


def likelihood_map(est: Estimate, draws: np.ndarray, loglike=None, n: int = 61) -> dict | None:
    """The (calibrated, when ``loglike`` is given) quasi-log-likelihood over an
    ``(a1, n1)`` grid around the draws and their mirror images, the other parameters at
    the estimate (or ``None`` when the model lacks either coefficient).
    """
    loglike = est.ql if loglike is None else loglike
    m = est.model
    if not (m.has("a1") and m.has("n1")):
        return None
    i, j = m.index("a1"), m.index("n1")
    qa = np.quantile(np.append(draws[:, i], -draws[:, i]), [0.0, 1.0])
    qn = np.quantile(np.append(draws[:, j], -draws[:, j]), [0.0, 1.0])
    pad_a = 0.25 * (qa[1] - qa[0]) + 1e-9
    pad_n = 0.25 * (qn[1] - qn[0]) + 1e-9
    ga = np.linspace(qa[0] - pad_a, qa[1] + pad_a, n)
    gn = np.linspace(qn[0] - pad_n, qn[1] + pad_n, n)
    A, N = np.meshgrid(ga, gn, indexing="ij")
    th = np.broadcast_to(est.theta, (*A.shape, est.theta.size)).copy()
    th[..., i], th[..., j] = A, N
    return {"a1": ga, "n1": gn, "log_likelihood": loglike(th)}
