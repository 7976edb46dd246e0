r"""The fourth cumulant of each driven dof's inferred force: a Gaussian force has none.

The force inferred on dof :math:`d` at :math:`\theta`, :math:`X_d = \lambda_d^{\mathsf T}
Y_d` (:mod:`hosid.components.chain_features`, sampled), is Gaussian at the true parameters
when the dof's force is (the paper's :math:`P_{4,dddd} = 0`, eq 34 with indices, at lag
zero).  Per driven dof, with the block moments :math:`m_{2b} = \overline{X_d^2}` and
:math:`m_{4b} = \overline{X_d^4}`,

.. math:: \kappa_d(\theta) = \frac{\frac1B\sum_bm_{4b} - 3C_d(\theta)}{C_d(\theta)}, \qquad
    C_d(\theta) = \frac{1}{B(B-1)}\sum_{b\ne b'}m_{2b}m_{2b'}

(the excess kurtosis in the force's own scale at :math:`\theta`:
:mod:`hosid.components.cumulant` says why)
has mean zero (blocks independent), whatever linear filter the sampling applies to the
force (an acceleration channel's, the derivative of its velocity's samples, included).
Both moments are polynomials in :math:`\lambda_d`, whose coefficient tensors are computed
once.  For the one-element chain this is :class:`hosid.components.cumulant.ForceKurtosis`
(white force).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..chain_state import ChainState
from ..model.system import System
from .base import Moments
from .chain_features import column_blocks, dof_columns, lam, places, restoration
from .cumulant import pilot_force

__all__ = ["ChainKurtosis"]


@dataclass(frozen=True)
class ChainKurtosis:
    """The inferred forces' excess fourth moments, one per driven dof (module docstring)."""

    name: str = "kurtosis"

    def prepare(self, state: ChainState, system: System, pilot: np.ndarray) -> Moments:
        """Block moment tensors and the equations' influences at ``pilot``."""
        th0 = np.asarray(pilot, dtype=float)
        rest = restoration(state, system, th0)
        parts, infl, labels, info = [], [], [], {}
        for d in (system.dofs.index(x) for x in system.driven):
            cols, sign = dof_columns(system, d)
            rows = [state.blocks["a"][d]]
            for c, s in zip(cols, sign, strict=True):
                f = column_blocks(state, system, int(c), rest)
                rows.append(f if s == 1.0 else s * f)
            mean, u, excess, sigma = _kurtosis(np.stack(rows, axis=-1), system, d, th0)
            parts.append(mean)
            infl.append(u)
            name = system.dofs[d]
            labels.append("force kurtosis" if system.single_names else f"force kurtosis {name}")
            info[name] = {"excess_kurtosis_at_pilot": excess, "sigma": sigma}
        if system.single_names:
            info = info[system.dofs[0]]

        def mean(theta):
            return np.concatenate([f(theta) for f in parts], axis=-1)

        return Moments(self.name, tuple(labels), mean, np.concatenate(infl, axis=1), info)


def _kurtosis(Y: np.ndarray, system: System, d: int, th0: np.ndarray):
    """The equation of one dof from its force's rows ``Y`` ``(B, M, F)``: the mean,
    the centred influence ``(B, 1)``, the pilot's excess kurtosis and force sd.
    """
    B, Mb, F = Y.shape
    M2 = np.einsum("bti,btj->bij", Y, Y) / Mb
    pairs = [(i, j) for i in range(F) for j in range(i, F)]
    Z = np.stack([Y[..., i] * Y[..., j] for i, j in pairs], axis=-1).reshape(-1, len(pairs))
    G = Z.T @ Z / Z.shape[0]
    twice = np.array([1.0 if i == j else 2.0 for i, j in pairs])
    first, second = np.array(pairs).T
    lam0 = lam(system, th0, d)
    M2sum = M2.sum(axis=0)

    pl = places(system)
    single = system.single_names  # the single oscillator's arithmetic, to the last digit
    # a block's second moment is w . v_b (v_b: its moments over the pairs), so the blocks'
    # cross term is [(w'm)^2 - w'Hw] / B(B - 1) with H = sum_b v_b v_b' and m = sum_b v_b:
    # an evaluation sums over no blocks
    V = M2[:, first, second]  # (B, P)
    VV = V.T @ V
    msum = V.sum(axis=0)

    def mean(theta):
        th = np.asarray(theta, dtype=float)
        lm = pl.lam(th, d)
        w = lm[..., first] * lm[..., second] * twice
        if single:
            m4 = np.einsum("...p,pq,...q->...", w, G, w)
            per = np.einsum("...i,bij,...j->...b", lm, M2, lm)
            tot = np.einsum("...i,ij,...j->...", lm, M2sum, lm)
            cross = (tot**2 - np.sum(per**2, axis=-1)) / (B * (B - 1))
            return ((m4 - 3.0 * cross) / cross)[..., None]
        square = np.sum((w @ VV) * w, axis=-1)
        cross = ((w @ msum) ** 2 - square) / (B * (B - 1))
        return ((np.sum((w @ G) * w, axis=-1) - 3.0 * cross) / cross)[..., None]

    return (mean, *pilot_force(Y @ lam0))
