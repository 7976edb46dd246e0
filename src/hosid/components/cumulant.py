r"""The fourth cumulant of the inferred force: a Gaussian force has none.

The force inferred at :math:`\theta`, :math:`g_\theta = \ddot x + \sum_l\theta_l\phi_l`
(eq 45, sampled), is Gaussian at the true parameters when the excitation is (the
paper's :math:`P_4 = 0`, eq 34, here at lag zero: the trispectrum integrated over all
frequencies).  With the block moments :math:`m_{2b} = \overline{g_\theta^2}` and
:math:`m_{4b} = \overline{g_\theta^4}` the equation

.. math:: \kappa(\theta) = \frac{\frac1B\sum_bm_{4b} - 3C(\theta)}{C(\theta)}, \qquad
    C(\theta) = \frac{1}{B(B-1)}\sum_{b\ne b'}m_{2b}m_{2b'},

the force's excess kurtosis (its fourth cumulant in the scale of its own variance at
:math:`\theta`), has mean zero (blocks independent; the ratio's first-order bias
:math:`-\mathrm{Cov}(m_4 - 3C, C)/C^2` vanishes for a Gaussian force), for any filter of
the force, white or shaped, and whatever the sampling (a band-limited Gaussian process is
Gaussian).  Under Poisson impulses (``impulsive_excitation``) the numerator's mean is the
impulses' fourth cumulant :math:`3(2\pi S_0)^2c_4/(r\Delta t^3)`
(:mod:`hosid.components.jumps`).  Both moments are polynomials in :math:`\lambda = (1,
\theta_{drift})` whose coefficients (the blocks' second and fourth moment tensors of
:math:`(\ddot x, \phi_1, \dots)`) are computed once.

*Its own scale.*  The equation's weight is its block variance at the pilot (the
quasi-likelihood's frozen covariance).  In the pilot's fixed scale (the numerator over
the pilot's :math:`\overline{g^2}^2`, as before) the equation at another :math:`\theta`
grows with the fourth power of the force's sd there, and so does its variance, which the
frozen weight does not follow: a :math:`\theta` whose inferred force is larger was
penalized as if its kurtosis were measured more precisely than it is.  On a record of the
ship-roll-like oscillator under a filter at its resonance (``ship_at`` record 0 of
``analyses/excitation_study.py``) the true :math:`(a_2, \omega_f)`, the other
parameters profiled, lay 9.9 below the estimate in quasi-log-likelihood, the kurtosis
standardized 4.5 sd off there; in its own scale 3.3 and 2.5.  The excess kurtosis is
scale free, and its variance (:math:`24/n` for :math:`n` independent Gaussian samples)
depends on :math:`\theta` only through the force's correlation time.

It is what tells a shaping filter from the oscillator it drives when the two could swap:
a filter at twice the paper oscillator's resonance was fitted, on one of 8 records, by
a stiff, nearly linear oscillator (a2 = 162 for 25) under a filter at the resonance,
whose inferred force is the non-Gaussian displacement scaled (Hansen's J 2.3 against
7.0 at the true parameters without this equation).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..model.model import Model
from ..state import RecordState
from .base import Moments, restoration
from .jumps import kink_constants

__all__ = ["ForceKurtosis", "pilot_force"]


@dataclass(frozen=True)
class ForceKurtosis:
    """The inferred force's excess fourth moment (module docstring)."""

    name: str = "kurtosis"

    def prepare(self, state: RecordState, model: Model, pilot: np.ndarray) -> Moments:
        """Block moment tensors and the equation's influence at ``pilot``."""
        s2, eps = restoration(state, model, pilot)
        blk = state.blocks
        rows = [blk["a"]]
        for t in model.drift_terms:
            rows.append(t.smoothed(blk["v"], s2, eps) if t.variable == "v" else t.phi(blk["x"]))
        Y = np.stack(rows, axis=-1)  # (B, M, F)
        B, Mb, F = Y.shape
        M2 = np.einsum("bti,btj->bij", Y, Y) / Mb
        pairs = [(i, j) for i in range(F) for j in range(i, F)]
        Z = np.stack([Y[..., i] * Y[..., j] for i, j in pairs], axis=-1).reshape(-1, len(pairs))
        G = Z.T @ Z / Z.shape[0]  # the fourth moments, over pairs of pairs
        twice = np.array([1.0 if i == j else 2.0 for i, j in pairs])
        first, second = np.array(pairs).T
        nd = model.n_drift
        lam0 = np.concatenate([[1.0], np.asarray(pilot, dtype=float)[:nd]])
        influence, excess, sigma = pilot_force(Y @ lam0)
        M2sum = M2.sum(axis=0)
        if model.has("rate"):  # Poisson impulses: 3 (2 pi S0)^2 c4 / (r dt^3) (.jumps)
            i_S0, i_rate = model.index("S0"), model.index("rate")
            k4 = 3.0 * kink_constants()[1] / state.dt**3

            def impulses(th):
                return k4 * (2.0 * math.pi * th[..., i_S0]) ** 2 / th[..., i_rate]
        else:

            def impulses(th):
                return 0.0

        def mean(theta):
            th = np.asarray(theta, dtype=float)
            lam = np.concatenate([np.ones((*th.shape[:-1], 1)), th[..., :nd]], axis=-1)
            w = lam[..., first] * lam[..., second] * twice
            m4 = np.einsum("...p,pq,...q->...", w, G, w)
            per = np.einsum("...i,bij,...j->...b", lam, M2, lam)
            tot = np.einsum("...i,ij,...j->...", lam, M2sum, lam)
            cross = (tot**2 - np.sum(per**2, axis=-1)) / (B * (B - 1))
            return ((m4 - 3.0 * cross - impulses(th)) / cross)[..., None]

        return Moments(
            component=self.name,
            labels=("force kurtosis",),
            mean=mean,
            influence=influence,
            info={"excess_kurtosis_at_pilot": excess, "sigma": sigma},
        )


def pilot_force(g0: np.ndarray) -> tuple[np.ndarray, float, float]:
    """The equation's centred influence ``(B, 1)`` (the projection of the ratio's
    U-statistics on the blocks, in the pilot's scale), the pilot's excess kurtosis and
    force sd, from the pilot's inferred force on the blocks ``g0`` ``(B, M)``.
    """
    m2b = (g0**2).mean(axis=1)
    sigma4 = float(m2b.mean()) ** 2
    m4b = (g0**4).mean(axis=1)
    u = (m4b - 2.0 * m4b.mean() / m2b.mean() * m2b) / sigma4
    excess = float((g0**4).mean() / (3.0 * m2b.mean() ** 2) - 1.0)
    return (u - u.mean())[:, None], excess, math.sqrt(math.sqrt(sigma4))
