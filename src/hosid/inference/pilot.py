r"""A closed-form pilot estimate: where the estimating equations are linearized.

The generator identities of all drift terms are linear in the drift coefficients and in
:math:`D = \pi S_0`: :math:`\bar Q\theta = -\bar c + D(\rho\bar e + \rho_x\bar e_x)`,
so :math:`\theta(D) = \alpha + \beta D`.  The level of the force inferred with
:math:`\theta(D)` on the J2 band must equal :math:`S_0 = D/\pi`,

.. math:: \frac1K\sum_k\frac{\lambda(D)^{\mathsf T}\bar R_k\lambda(D)}{L_k} = \frac{D}{\pi},

a quadratic equation in :math:`D`; its smallest positive root is taken (or, when the
level only touches :math:`D/\pi`, the point of closest approach).  Two rounds
update the velocity restoration and the excitation's shape.
"""

from __future__ import annotations

import math

import numpy as np

from ..components.base import feature_ffts
from ..components.excitation import Excitation
from ..components.identities import Identities
from ..components.spectral import default_band
from ..errors import HosidInputError
from ..model.model import Model
from ..state import RecordState

__all__ = ["initial_theta", "pilot"]


def initial_theta(state: RecordState, model: Model) -> np.ndarray:
    """A start before any estimate: no drift, the rough level, white-ish excitation (or
    the middle of the record's excitation edge).
    """
    s = state.scales
    noise = state.noise["sd"] if state.noise else 0.01 * s.sigma_x
    start = {
        "S0": s.S0,
        "wc": 2.0 * s.omega_nyquist,
        "wb": 0.5 * sum(s.band_edge) if s.band_edge else s.omega_nyquist,
        "noise_sd": max(noise, 1e-3 * s.sigma_x),
    }
    return np.array([start.get(p, 0.0) for p in model.param_names])


def pilot(state: RecordState, model: Model, theta: np.ndarray | None = None) -> np.ndarray:
    """The pilot estimate (module docstring), starting from ``theta`` if given.

    Raises
    ------
    HosidInputError
        If the identities are singular or no positive excitation level solves them
        (the record does not look like a randomly excited oscillator of this model).
    """
    theta = initial_theta(state, model) if theta is None else np.array(theta, dtype=float)
    nd = model.n_drift
    L = state.layout
    bins = L.bins(*default_band(state), k_min=2)
    omega = bins * L.d_omega
    for _ in range(2):
        Q, const, e, ex, _, s2 = Identities().statistics(state, model, theta)
        exc = Excitation(model, theta, state.scales.sigma_v, state.scales.sigma_x)
        rho, rho_x = (float(r) for r in exc.powers(theta, state.dt))
        try:
            alpha = np.linalg.solve(Q.mean(0), -const.mean(0))
            beta = np.linalg.solve(Q.mean(0), rho * e.mean(0) + rho_x * ex.mean(0))
        except np.linalg.LinAlgError:
            raise HosidInputError(
                "the generator identities are singular: the record does not excite the "
                "model's terms"
            ) from None
        Y = feature_ffts(state, model, s2, bins)
        R = np.einsum("ibk,jbk->kij", Y, Y.conj()).real / (
            L.B * 2 * math.pi * L.T * state.window.k2
        )
        Lk = exc.shape(omega, theta)
        l0 = np.concatenate([[1.0], alpha])
        l1 = np.concatenate([[0.0], beta])
        quad = [
            np.mean(np.einsum("kij,i,j->k", R, u, w) / Lk)
            for u, w in ((l1, l1), (l0, l1), (l0, l0))
        ]
        roots = np.roots([quad[0], 2 * quad[1] - 1.0 / math.pi, quad[2]])
        # no real root: the level touches D/pi without crossing; take the closest point
        roots = roots.real if np.iscomplexobj(roots) else roots
        roots = roots[roots > 0]
        if roots.size == 0:
            raise HosidInputError(
                "no positive excitation level explains the record's force spectrum: the "
                "record does not look like a randomly excited oscillator of this model"
            )
        D = float(roots.min())
        theta[:nd] = alpha + beta * D
        theta[model.index("S0")] = D / math.pi
    if not np.all(np.isfinite(theta)):
        raise HosidInputError("the pilot estimate is not finite")
    return theta
