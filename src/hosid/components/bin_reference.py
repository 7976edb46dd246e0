r"""J4's Gaussian part in bin values (paper eq 36, eq 63 corrected).

For a Gaussian force of spectrum :math:`s(\omega)`, flat over the window's main lobe,
the block trispectrum of the triple :math:`t = (k_1, k_2, k_3)` has the mean

.. math:: G_t = s_1s_3\Delta_T(\omega_1+\omega_2) + s_3s_2\Delta_T(\omega_1+\omega_3)
    + s_1s_2\Delta_T(\omega_2+\omega_3),

with :math:`s = S_0L(\omega)` the model's (J4A, eqs 34, 59) or :math:`s = \hat V^a/k_2`
the record's own (J4B with ``reference="bins"``, eqs 37-38, 62-63).  J4B's default is
exact for the window's leakage instead (:mod:`hosid.components.gaussian_reference`).

Both forms serve :class:`hosid.components.polyspectral.J4` through ``values(theta)``
(:math:`G_t` at the parameters) and ``split(d, q, e, th0, K)``: the jackknife
pseudo-values of the equations, the quartic tensor left for the block products, and the
remainder :math:`\sum_t \bar e_{tj}G_t(\theta)` to subtract from it (``None`` when the
tensor holds it already).
"""

from __future__ import annotations

import math

import numpy as np

from .base import u_pseudovalues

__all__ = ["PAIRS", "BinReference"]

#: (a, b, c): the term :math:`s_as_b\Delta_c` of :math:`G_t`, ``Delta_c`` the window
#: integral at the sum of the two other ordinates (eq 36)
PAIRS = ((0, 2, 0), (2, 1, 1), (0, 1, 2))


class BinReference:
    r""":math:`G_t` from the spectral levels in bin values (module docstring).

    Parameters
    ----------
    kind : str
        ``"A"`` (the model's level) or ``"B"`` (the record's own).
    state : RecordState
        The record's layout and window.
    exc : Excitation
        The model's excitation at the pilot (J4A's level and shape).
    dom : ndarray
        ``(n, 4)`` signed triples of the domain.
    Y : ndarray
        ``(F, B, K + 1)`` block transforms of the force's features on bins ``0..K``.
    nd : int
        The number of drift coefficients.
    """

    def __init__(self, kind: str, state, exc, dom: np.ndarray, Y: np.ndarray, nd: int):
        L, win = state.layout, state.window
        K, B = Y.shape[2] - 1, Y.shape[1]
        self.kind, self.exc, self.nd, self.Y, self.k2 = kind, exc, nd, Y, win.k2
        self.norm = 2 * math.pi * L.T
        self.omega = np.arange(K + 1) * L.d_omega
        self.absk = np.abs(dom[:, :3])
        self.delta = np.stack(
            [win.delta_bins(dom[:, a] + dom[:, b], L.M, L.T) for a, b in ((0, 1), (0, 2), (1, 2))],
            axis=1,
        )
        # the level's quadratic form in the coefficients (J4B's V^a tensors)
        self.R = np.einsum("ibk,jbk->kij", Y, Y.conj()).real / (B * self.norm)

    def _lam(self, theta: np.ndarray) -> np.ndarray:
        return np.concatenate([np.ones((*theta.shape[:-1], 1)), theta[..., : self.nd]], axis=-1)

    def level(self, theta) -> np.ndarray:
        """The spectral level :math:`s` on the bins ``0..K``, ``(..., K + 1)``."""
        th = np.asarray(theta, dtype=float)
        if self.kind == "A":
            return self.exc.S0(th)[..., None] * self.exc.shape(self.omega, th)
        lam = self._lam(th)
        return np.einsum("...i,kij,...j->...k", lam, self.R, lam) / self.k2

    def gauss(self, s: np.ndarray) -> np.ndarray:
        """:math:`G_t` of the levels ``s``."""
        k, dl = self.absk, self.delta
        return sum(s[..., k[:, a]] * s[..., k[:, b]] * dl[:, c] for a, b, c in PAIRS)

    def values(self, theta) -> np.ndarray:
        """:math:`G_t` at the parameters ``theta``."""
        return self.gauss(self.level(theta))

    def split(self, d, q, e, th0, K_all):
        r"""Pseudo-values of the equations with frozen weights ``d`` (``(B, n, J)``) on
        the block products ``q``, their mean weights ``e`` (``(n, J)``), at the pilot
        ``th0``; the tensor ``K_all`` unchanged and the remainder
        :math:`\theta \mapsto s^{\mathsf T}C_js` (:math:`C_j[a, b]` the sum of
        :math:`\bar e_{tj}\Delta` over the triples whose Gaussian term pairs the bins
        :math:`a` and :math:`b`).  J4B's level comes from the blocks too: its influence
        enters by the delta method.
        """
        u = u_pseudovalues(d, q - self.values(th0))
        J = e.shape[1]
        if self.kind == "B":
            sb = np.abs(np.tensordot(self._lam(np.asarray(th0, float)), self.Y, 1)) ** 2
            sb = sb / (self.norm * self.k2)  # per-block level (B, K + 1)
            s0 = sb.mean(axis=0)
            for a in range(J):
                u[:, a] -= (sb - s0) @ self._gauss_grad(s0, np.real(e[:, a]))
        C = np.zeros((J, len(self.omega), len(self.omega)))
        k, dl = self.absk, self.delta
        for a, b, c in PAIRS:
            for j in range(J):
                np.add.at(C[j], (k[:, a], k[:, b]), np.real(e[:, j]) * dl[:, c])

        def rest(theta):
            s = self.level(theta)
            return np.einsum("...a,jab,...b->...j", s, C, s)

        return u, K_all, rest

    def _gauss_grad(self, s: np.ndarray, e: np.ndarray) -> np.ndarray:
        r"""Gradient of :math:`\sum_t e_tG_t(s)` with respect to the levels ``s``."""
        grad = np.zeros_like(s)
        k, dl = self.absk, self.delta
        for a, b, c in PAIRS:
            np.add.at(grad, k[:, a], e * s[k[:, b]] * dl[:, c])
            np.add.at(grad, k[:, b], e * s[k[:, a]] * dl[:, c])
        return grad
