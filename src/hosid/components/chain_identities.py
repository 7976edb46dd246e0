r"""Generator identities of a system: every element's drift, from the response alone.

For :math:`M\ddot q + \Phi(q, \dot q)\theta = F` (:mod:`hosid.model.system`) the state
:math:`(q, v)` has the generator

.. math:: \mathcal LG = \sum_dv_d\partial_{q_d}G + \sum_db_d\partial_{v_d}G
    + \sum_{d\,\mathrm{driven}}\frac{\pi S_{0,d}}{m_d^2}\partial^2_{v_d}G,
    \qquad b = -M^{-1}\Phi\theta,

and every test function :math:`G(q, v)` gives :math:`E[\mathcal LG] = 0`: over a block,
:math:`\Delta G/T_b - \overline{\mathcal LG}` is a martingale increment (blocks
uncorrelated), a moment of the state, affine in :math:`\theta` for known masses and
bilinear with :math:`\mu_d = 1/m_d`.  The test functions (rows):

- a velocity term :math:`\varphi_c(\dot r_e)` of element :math:`e` between :math:`i` and
  :math:`j`: :math:`G = \Psi_c(\dot r_e)`, :math:`\Psi_c' = \psi_c` (the feature, or a
  smooth stand-in: :meth:`hosid.model.base.DriftTerm.test`),

  .. math:: \overline{\psi_c(\dot r_e)\big(\mu_j(\Phi\theta)_j - \mu_i(\Phi\theta)_i\big)}
      = \Big(\frac{\pi S_{0,i}}{m_i^2} + \frac{\pi S_{0,j}}{m_j^2}\Big)\overline{\psi_c'};

- a displacement term :math:`\varphi_c(r_e)` (and the constant of a mean force):
  :math:`G = \varphi_c(r_e)\,v_d`, one row for each end :math:`d` of the element,

  .. math:: \mu_d\,\overline{\varphi_c(r_e)(\Phi\theta)_d} = \overline{\varphi_c'(r_e)\,
      \dot r_e\,v_d}

  (their difference is the element's identity :math:`G = \varphi_c(r_e)\dot r_e`).

**Why these.**  The Girsanov score of :math:`\theta_c` is the Itô integral of
:math:`h = \Sigma^{-1}\partial b/\partial\theta_c`, :math:`h_d = -\kappa_dB_{e_cd}
\varphi_c/2\pi` with :math:`\kappa_d = m_d/S_{0,d}`, and a test function's martingale is
that of :math:`\nabla_vG`: the score is a generator identity where :math:`h` is a
gradient in :math:`v`.  For a displacement term it always is
(:math:`G = \varphi_c(r_e)(\kappa_jv_j - \kappa_iv_i)/2\pi`, spanned by the two end rows);
for a velocity term only where :math:`\kappa_i = \kappa_j`.  Otherwise the row keeps the
gradient part :math:`\bar\kappa\varphi_c(\dot r_e)(e_j - e_i)` and loses the rest: with
the full state and the masses known, the identities' efficient GMM reaches 0.98-0.99 of
the bound's variance for the velocity coefficients of the study's chains
(:math:`\kappa_i/\kappa_j` 0.75-0.8) and 1.00 for the others (``analyses/chain_study.py``,
its ``identity_efficiency``); products of the dofs' velocities (:math:`v_iv_j`,
:math:`v_d^2`) as further rows gained less than 0.005.

For the one-element chain these are the single oscillator's identities
(:mod:`hosid.components.identities`, white force).  Every statistic is restored for what
the sampled state lacks (:mod:`hosid.components.chain_features`):
:math:`\overline{\psi\varphi}` gains :math:`\tfrac12(S_{aa}\psi''\varphi +
2S_{ac}\psi'\varphi' + S_{cc}\psi\varphi'')` with the covariances of the two elements'
missing parts.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..chain_state import ChainState
from ..model.system import System
from .base import Moments
from .chain_features import Restoration, places, relative, restoration

__all__ = ["ChainIdentities", "Row", "combine", "rows"]


@dataclass(frozen=True)
class Row:
    r"""One identity: coefficient ``col`` of element ``element``, of ``kind`` ``"v"``
    (velocity), ``"x"`` (displacement) or ``"1"`` (constant), the direction ``g`` of
    :math:`\partial G/\partial v` and, for a per-end row, its dof ``end``.
    """

    col: int
    element: int
    g: tuple[float, ...]
    end: str | None
    kind: str


def rows(system: System) -> list[Row]:
    """The identities of ``system`` (module docstring), in coefficient order."""
    B = system.incidence
    out = []
    for c, (e, t) in enumerate(system.columns):
        ends = np.flatnonzero(B[e])
        if t.variable == "v" or len(ends) == 1:
            out.append(Row(c, e, tuple(B[e]), None, t.variable))
            continue
        for d in ends:
            g = np.zeros(system.n)
            g[d] = 1.0
            out.append(Row(c, e, tuple(g), system.dofs[d], t.variable))
    return out


@dataclass(frozen=True)
class ChainIdentities:
    """The generator identities of every drift coefficient of a system (module
    docstring).
    """

    name: str = "identities"

    def statistics(self, state: ChainState, system: System, rest: Restoration):
        """Per-block ``P`` ``(B, A, p)`` (restored products of the rows' test functions
        and the features), ``const`` ``(B, A)`` (boundary and displacement terms) and
        ``e`` ``(B, A)`` (the test functions' derivative, velocity rows), and the rows.
        """
        rws = rows(system)
        rb, rdb = relative(state, system, blocks=True)
        r, rd = relative(state, system)
        cols = system.columns
        first, nxt = state.block_edges
        T = state.layout.T
        Bn = state.layout.B

        def col_derivs(c):  # a feature and its v-derivatives (0 for displacement features)
            e, t = cols[c]
            if t.variable == "v":
                eps = float(rest.eps[e])
                return [t.phi(rdb[e])] + [t.phi(rdb[e], k, eps) for k in (1, 2)]
            zero = np.zeros_like(rb[e])
            return [t.phi(rb[e]), zero, zero]

        def row_derivs(w):  # the row's test function and its v-derivatives
            e, t = cols[w.col]
            if w.kind == "v":
                sv, eps = float(rest.sd[e]), float(rest.eps[e])
                return [t.test(rdb[e], scale=sv)] + [t.test(rdb[e], k, eps, scale=sv)
                                                     for k in (1, 2, 3)]  # fmt: skip
            return col_derivs(w.col)

        feats = [col_derivs(c) for c in range(len(cols))]
        P = np.empty((Bn, len(rws), len(cols)))
        const = np.empty((Bn, len(rws)))
        e_ = np.zeros((Bn, len(rws)))
        Sv, Cr = rest.Sv, rest.Cr
        for a, w in enumerate(rws):
            q = row_derivs(w)
            ea = w.element
            for c, d in enumerate(feats):
                ec = cols[c][0]
                saa, sac, scc = Sv[ea, ea], Sv[ea, ec], Sv[ec, ec]
                if saa == sac == scc:
                    prod = q[0] * d[0] + 0.5 * saa * (q[2] * d[0] + 2 * q[1] * d[1] + q[0] * d[2])
                else:
                    prod = q[0] * d[0] + 0.5 * (
                        saa * q[2] * d[0] + 2 * sac * q[1] * d[1] + scc * q[0] * d[2]
                    )
                if Cr[ea, ea] or Cr[ec, ec]:
                    prod = prod + self._low(cols, w, c, rb, Cr, q[0], d[0])
                P[:, a, c] = prod.mean(axis=1)
            t = cols[w.col][1]
            if w.kind == "v":
                G = t.test_antiderivative(rd[ea], scale=float(rest.sd[ea]))
                extra = 0.0
                e_[:, a] = (q[1] + 0.5 * Sv[ea, ea] * q[3]).mean(axis=1)
            else:
                g = np.asarray(w.g)
                gv, gvb = g @ state.v, np.einsum("d,dbm->bm", g, state.blocks["v"])
                if system.n == 1:
                    gv, gvb = state.v[0], state.blocks["v"][0]
                G = t.phi(r[ea]) * gv
                extra = 0.0
                if w.kind == "x":
                    cov = float(np.sum(system.incidence[ea] * g * rest.s2))
                    slope = t.phi(rb[ea], 1)
                    if Cr[ea, ea]:  # restored for the displacement's missing part, as P is
                        slope = slope + 0.5 * Cr[ea, ea] * t.phi(rb[ea], 3)
                    extra = (slope * (rdb[ea] * gvb + cov)).mean(axis=1)
            const[:, a] = (G[nxt] - G[first]) / T - extra
        return P, const, e_, rws

    def extrapolated(self, state: ChainState, system: System, theta: np.ndarray):
        r""":meth:`statistics` of a record with acceleration channels, extrapolated to a
        band edge :math:`\omega_L \to 0` (Richardson): every statistic :math:`s` of the
        state integrated above :math:`\omega_L` and above :math:`2\omega_L`
        (:meth:`hosid.chain_state.ChainState.rebanded`), each restored for the trapezoid
        rule's random walk only, gives :math:`2s(\omega_L) - s(2\omega_L)`, block by
        block.  The displacement missing below the band (variance :math:`\propto
        \omega_L` for a spectrum flat there) moves every statistic in proportion to
        :math:`\omega_L`, whatever its dependence on the rest; the random walk, independent
        of the state, is restored exactly to second order.  Restoring the missing part as
        an independent Gaussian instead (:func:`hosid.components.chain_features.
        restoration`) fits no nonlinear record: on 2000 s of the paper oscillator from
        its accelerations its effect on :math:`E[x^4]` was 1.6 times its effect on
        :math:`E[x^2]` (an independent part: 2.5 times), and the cubic stiffness's
        identity at the truth was 1.7 sd off with the missing variance right and 1 sd
        the other way with it a third as large; extrapolated, the four identities lay
        within 0.6 sd of a displacement record's of the same motion (two 2000 s records
        and one of 600 s, where the restored estimate of :math:`a_2` had been 20 % high).
        """
        one = self.statistics(state, system, restoration(state, system, theta, lost=False))
        wide = state.rebanded(2.0)
        two = self.statistics(wide, system, restoration(wide, system, theta, lost=False))
        return (*(2.0 * a - b for a, b in zip(one[:3], two[:3], strict=True)), one[3])

    @staticmethod
    def _low(cols, w, c, rb, Cr, q0, d0) -> np.ndarray:
        r"""The restoration of :math:`\psi_a\varphi_c` for the displacement missing below
        the band: :math:`\tfrac12(C_{aa}\psi''\varphi + 2C_{ac}\psi'\varphi' +
        C_{cc}\psi\varphi'')` in the displacement factors' derivatives (``q0``, ``d0``:
        the two factors).
        """
        (ea, ta), (ec, tc) = cols[w.col], cols[c]
        xa, xc = ta.variable == "x", tc.variable == "x"
        out = 0.0
        if xa:
            out = out + Cr[ea, ea] * ta.phi(rb[ea], 2) * d0
        if xc:
            out = out + Cr[ec, ec] * q0 * tc.phi(rb[ec], 2)
        if xa and xc:
            out = out + 2 * Cr[ea, ec] * ta.phi(rb[ea], 1) * tc.phi(rb[ec], 1)
        return 0.5 * out

    def prepare(self, state: ChainState, system: System, pilot: np.ndarray) -> Moments:
        """Block statistics of the identities (module docstring)."""
        th0 = np.asarray(pilot, dtype=float)
        rest = restoration(state, system, th0)
        if any(c.band is not None for c in state.channels):
            P, const, e_, rws = self.extrapolated(state, system, th0)
        else:
            P, const, e_, rws = self.statistics(state, system, rest)
        nd = system.n_drift
        mean = combine(system, rws, P.mean(0), const.mean(0), e_.mean(0))
        T3, G2 = _weights(system, rws)
        if system.n == 1:  # the single oscillator's arithmetic, to the last digit
            drift = np.einsum("bjk,k->bj", P, th0[:nd])
            per_block = const + drift - math.pi * float(system.levels(th0)[0]) * e_
        else:
            mu0 = 1.0 / system.mass_vector(th0)
            diff0 = (math.pi * system.levels(th0) * mu0**2) @ G2
            drift = np.einsum("d,dac,bac,c->ba", mu0, T3, P, th0[:nd])
            per_block = const + drift - diff0 * e_
        labels = tuple(_label(system, w) for w in rws)
        s2 = float(rest.s2[0]) if system.n == 1 else dict(zip(system.dofs, rest.s2.tolist(),
                                                              strict=True))  # fmt: skip
        return Moments(
            component=self.name,
            labels=labels,
            mean=mean,
            influence=per_block - per_block.mean(axis=0),
            info={"velocity_restoration_s2": s2, "identities": list(labels)},
        )


def _weights(system: System, rws: list[Row]) -> tuple[np.ndarray, np.ndarray]:
    r""":math:`g_{ad}B_{e_cd}` ``(n, A, p)`` and the diffusion's :math:`g_{ad}^2` of the
    velocity rows ``(n, A)``.
    """
    B = system.incidence
    Bcols = np.stack([B[e] for e, _ in system.columns], axis=-1)  # (n, p)
    g = np.array([w.g for w in rws])  # (A, n)
    T3 = g.T[:, :, None] * Bcols[:, None, :]
    G2 = np.where(np.array([w.kind == "v" for w in rws])[:, None], g**2, 0.0).T
    return T3, G2


def combine(system: System, rws: list[Row], Pm: np.ndarray, cm: np.ndarray, em: np.ndarray):
    r"""The identities' means as a function of :math:`\theta`, ``(..., p) -> (..., A)``.

    From their statistics (:meth:`ChainIdentities.statistics`, block-averaged, or the
    population's),

    .. math:: m_a(\theta) = \bar c_a + \sum_d\mu_d\sum_cg_{ad}B_{e_cd}\bar P_{ac}\theta_c
        - \sum_d\pi S_{0,d}\mu_d^2g_{ad}^2\,\bar e_a.
    """
    nd = system.n_drift
    T3, G2 = _weights(system, rws)
    Z = T3 * Pm[None]  # (n, A, p)
    single = system.n == 1
    pl = places(system)

    def mean(theta):
        th = np.asarray(theta, dtype=float)
        S0 = pl.levels(th)  # (..., n)
        if single:
            return cm + th[..., :nd] @ Pm.T - (math.pi * S0) @ G2 * em
        mu = 1.0 / pl.masses(th)
        U = np.einsum("...c,dac->...da", th[..., :nd], Z)
        diff = (math.pi * S0 * mu**2) @ G2
        return cm + np.einsum("...d,...da->...a", mu, U) - diff * em

    return mean


def _label(system: System, w: Row) -> str:
    name = system.param_names[w.col]
    return f"identity {name}" + (f" at {w.end}" if w.end else "")
