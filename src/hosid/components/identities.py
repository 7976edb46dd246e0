r"""Generator identities: the score of the drift, from the displacement alone.

For :math:`\ddot x + g(x,\dot x) = w`, :math:`g = \sum_k\theta_k\phi_k` and white
:math:`w` of intensity :math:`2D`, :math:`D = \pi S_0`, Itô's formula for a function
:math:`G_j(x, \dot x)` with :math:`\partial G_j/\partial\dot x = \phi_j` gives over a
block :math:`[t_b, t_{b+1}]`

.. math::

    \int\phi_j\,\sigma\,dW = \Delta G_j - \int\dot x\,\partial_xG_j\,dt
        + \sum_k\theta_k\int\phi_j\phi_k\,dt - D\int\partial_{\dot x}\phi_j\,dt,

the block's share of the Girsanov score of :math:`\theta_j` (see
:mod:`hosid.model.information`): a martingale increment, so blocks are uncorrelated
whatever their length, and an estimator built on these equations reaches the
Cramer-Rao bound up to the velocity's sampling.  Per drift term:

- velocity feature :math:`\phi(\dot x)`: :math:`G_j = \int_0^{\dot x}\phi`, equation
  :math:`\overline{\phi_j g} - D\,\overline{\phi_j'}`;
- displacement feature :math:`\phi(x)`: :math:`G_j = \phi(x)\dot x`, equation
  :math:`\overline{\phi_j g} - \overline{\phi_j'(x)\dot x^2}`;
- the constant :math:`-1` (mean force): :math:`G_j = -\dot x`, equation :math:`-\bar g`;

plus :math:`\Delta G_j/T_b`.  A term may replace its feature by a smooth test function
:math:`\psi_j` (Coulomb friction: :math:`\tanh(\dot x/w)` for
:math:`\mathrm{sign}\,\dot x`, :meth:`hosid.model.terms.DriftTerm.test`); the identity
stays exact, only its efficiency changes.  For the paper model these are the energy balance
(:math:`a_1\overline{\dot x^2} + n_1\overline{|\dot x|^3} = \pi S_0`), the
velocity-weighted identity that separates :math:`a_1` from :math:`n_1`
(:math:`a_1\overline{|\dot x|^3} + n_1\overline{\dot x^4} = 2\pi S_0\overline{|\dot x|}`)
and the two moment equations of the stiffness (NOTES.md).

Every velocity statistic is restored for the power the sampled record lacks above the
Nyquist frequency (:mod:`hosid.state`): :math:`\overline{h} \to \overline{h + \tfrac12
s^2h''}`, so :math:`\overline{\phi_j\phi_k}` gains
:math:`\tfrac12s^2(\phi_j''\phi_k + 2\phi_j'\phi_k' + \phi_j\phi_k'')` (e.g.
:math:`\overline{\dot x^4} + 6s^2\overline{\dot x^2}`).  Under coloured excitation
:math:`D` becomes :math:`\pi S_0\rho(\omega_c)`
(:class:`hosid.components.excitation.Excitation`), and the restoring identities gain the
force term :math:`\pi S_0\rho_x\overline{\phi_j'(x)}` (zero for white noise).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import partial

import numpy as np

from ..model.model import Model
from ..state import RecordState
from .base import Moments, restoration
from .excitation import Excitation
from .jets import EXTRA, whitened_statistics
from .jumps import GRID, jump_table, read_table

__all__ = ["Identities"]


@dataclass(frozen=True)
class Identities:
    """The generator identities of every drift term (``which="all"``), or of the
    restoring terms only (``which="restoring"``: the paper's moment method).
    """

    which: str = "all"
    name: str = "identities"

    def statistics(self, state: RecordState, model: Model, pilot: np.ndarray):
        """Per-block ``(Q, const, e, ex)`` of the identities, their term indices and
        ``s2``: block ``b``'s equation ``j`` is ``const + Q @ theta_drift - pi S0 (rho e +
        rho_x ex)`` (:class:`hosid.components.excitation.Excitation`).
        """
        rows = self.rows(model)
        s2, eps = restoration(state, model, pilot)
        blk = state.blocks
        x, v = blk["x"], blk["v"]
        terms = model.drift_terms
        L = state.layout
        first, nxt = state.block_edges

        sv = state.scales.sigma_v

        def vder(t, order, fn):  # v-derivatives of a feature or test function (0 for x)
            if order == 0:
                return fn(t)(v if t.variable == "v" else x)
            return fn(t)(v, order, eps) if t.variable == "v" else np.zeros_like(x)

        d = [[vder(t, o, lambda t: t.phi) for o in range(3)] for t in terms]
        q = [
            [vder(t, o, lambda t: partial(t.test, scale=sv)) for o in range(4)]
            if t.variable == "v"
            else d[j]
            for j, t in enumerate(terms)
        ]
        p = len(terms)
        Q = np.empty((L.B, len(rows), p))
        for a, j in enumerate(rows):
            for k in range(p):
                prod = q[j][0] * d[k][0] + 0.5 * s2 * (
                    q[j][2] * d[k][0] + 2 * q[j][1] * d[k][1] + q[j][0] * d[k][2]
                )
                Q[:, a, k] = prod.mean(axis=1)
        const = np.empty((L.B, len(rows)))
        e = np.zeros((L.B, len(rows)))
        ex = np.zeros((L.B, len(rows)))
        for a, j in enumerate(rows):
            t = terms[j]
            if t.variable == "v":
                G = t.test_antiderivative(state.v, scale=sv)
                r = 0.0
                e[:, a] = (q[j][1] + 0.5 * s2 * q[j][3]).mean(axis=1)

            else:
                G = t.phi(state.x) * state.v
                r = (t.phi(x, 1) * (v**2 + s2)).mean(axis=1) if t.variable == "x" else 0.0
                ex[:, a] = t.phi(x, 1).mean(axis=1)
            const[:, a] = (G[nxt] - G[first]) / L.T - r
        return Q, const, e, ex, rows, s2

    def jump_tables(self, state: RecordState, model: Model, rows: list, s2: float):
        r"""Per block, row and area variance, :math:`e(\sigma_A^2)` of the velocity rows
        under Poisson impulses (:mod:`hosid.components.jumps`; zero for the others).
        """
        sv = state.scales.sigma_v
        terms = model.drift_terms
        out = np.zeros((state.layout.B, len(rows), GRID.size))
        for a, j in enumerate(rows):
            if terms[j].variable == "v":
                G = partial(terms[j].test_antiderivative, scale=sv)
                out[:, a] = jump_table(G, state.blocks["v"], s2, sv)
        return out

    def rows(self, model: Model) -> list[int]:
        """The drift terms whose identities are used."""
        if self.which not in ("all", "restoring"):
            raise ValueError(f"unknown identity set {self.which!r}: 'all' or 'restoring'")
        return [j for j, t in enumerate(model.drift_terms) if self.which == "all" or
                t.variable != "v"]  # fmt: skip

    def prepare(self, state: RecordState, model: Model, pilot: np.ndarray) -> Moments:
        """Block statistics of the identities (module docstring)."""
        exc = Excitation(model, pilot, state.scales.sigma_v, state.scales.sigma_x)
        if exc.whitening:
            return self._whitened(state, model, pilot, exc)
        Q, const, e, ex, rows, s2 = self.statistics(state, model, pilot)
        terms = model.drift_terms
        nd = model.n_drift
        Qm, cm, em, exm = Q.mean(0), const.mean(0), e.mean(0), ex.mean(0)
        sv = state.scales.sigma_v
        impulses = model.has("rate")
        if impulses:  # e(sigma_A^2) of the velocity rows (hosid.components.jumps)
            tables = self.jump_tables(state, model, rows, s2)
            tm = tables.mean(axis=0)
            i_S0, i_rate = model.index("S0"), model.index("rate")

            def area(th):
                return 2.0 * np.pi * th[..., i_S0] / th[..., i_rate]

        def mean(theta):
            th = np.asarray(theta, dtype=float)
            D = (np.pi * exc.S0(th))[..., None]
            if impulses:
                return cm + th[..., :nd] @ Qm.T - D * read_table(tm, area(th), sv)
            rho, rho_x = exc.powers(th, state.dt)
            force = D * (rho[..., None] * em + rho_x[..., None] * exm)
            return cm + th[..., :nd] @ Qm.T - force

        th0 = np.asarray(pilot, dtype=float)
        if impulses:
            e = read_table(tables, area(th0), sv)
        D0 = np.pi * float(exc.S0(th0))
        rho0, rho_x0 = (float(r) for r in exc.powers(th0, state.dt))
        force0 = D0 * (rho0 * e + rho_x0 * ex)
        per_block = const + np.einsum("bjk,k->bj", Q, th0[:nd]) - force0
        labels = tuple(f"identity {terms[j].params[0]}" for j in rows)
        return Moments(
            component=self.name,
            labels=labels,
            mean=mean,
            influence=per_block - per_block.mean(axis=0),
            info={"velocity_restoration_s2": s2, "identities": list(labels)},
        )

    def _whitened(
        self, state: RecordState, model: Model, pilot: np.ndarray, exc: Excitation
    ) -> Moments:
        r"""The identities of the augmented state (:mod:`hosid.components.jets`), in the
        scale of their own block covariance at each :math:`\theta`.

        Their block values :math:`u_b(\theta) = \sum p_mp_n(\theta)[\ldots]` are weighted
        by the whitening operator, whose coefficients :math:`2\zeta_f/\omega_f` and
        :math:`1/\omega_f^2` shrink the jet's noisiest products as :math:`\omega_f`
        grows: with the weight frozen at the pilot, a solution gained by shrinking them.
        The mean is therefore returned as :math:`L_0L(\theta)^{-1}\bar u(\theta)`, with
        :math:`L(\theta)` the Cholesky factor of the block covariance of
        :math:`u_b(\theta)` and :math:`L_0` the pilot's: the identities' own term of the
        quasi-likelihood is :math:`\bar u^{\mathsf T}\hat\Sigma(\theta)^{-1}\bar u`
        (continuously updated GMM, Hansen, Heaton & Yaron 1996).  Measured on 4 records
        of the ship-roll-like oscillator under a filter at its resonance: the estimates
        of a2, S0 and wf had been -0.7 to -2.6, -1.4 to -3.2 and +1.4 to +2.5 sd off
        (the ridge of the swap), and were -0.6 to +0.6, -0.1 to -2.5 and -0.4 to +2.0.
        """
        rows = [*self.rows(model), *EXTRA]
        deficit = exc.jet_deficit(pilot, state.dt)
        st = whitened_statistics(state, model, rows, deficit)
        pairs = sorted(st["Q"])
        Q = np.stack([st["Q"][k] for k in pairs])  # (P, B, J, p)
        C = np.stack([st["C"][k] for k in pairs])  # (P, B, J)
        e = st["e"]
        nd = model.n_drift
        spectrum = exc.spectrum

        def weights(th):  # p_m p_n of every pair
            p = spectrum.operator(th)
            return np.stack([p[m] * p[n] for m, n in pairs], axis=-1)

        # the block values are linear in the coefficients (p_m p_n, p_m p_n theta_k, -pi S0):
        # one matrix of the statistics, so that a batch of thetas is one product
        n_b, n_j = e.shape
        X = np.concatenate(
            [C.reshape(len(pairs), -1), np.moveaxis(Q, -1, 1).reshape(-1, n_b * n_j),
             e.reshape(1, -1)]
        )  # fmt: skip

        def blocks(th):  # (..., B, J)
            W = weights(th)
            coef = np.concatenate(
                [W, (W[..., :, None] * th[..., None, :nd]).reshape(*W.shape[:-1], -1),
                 -np.pi * np.asarray(spectrum.S0(th))[..., None]], axis=-1,
            )  # fmt: skip
            return (coef @ X).reshape(*coef.shape[:-1], n_b, n_j)

        def factor(values):  # Cholesky factor of the block covariance, (..., J, J)
            u = values - values.mean(axis=-2, keepdims=True)
            S = np.einsum("...bi,...bj->...ij", u, u) / (u.shape[-2] - 1)
            ridge = 1e-12 * np.trace(S, axis1=-2, axis2=-1)[..., None, None]
            return np.linalg.cholesky(S + ridge * np.eye(S.shape[-1]))

        th0 = np.asarray(pilot, dtype=float)
        per_block = blocks(th0)
        L0 = factor(per_block)

        def mean(theta):
            th = np.asarray(theta, dtype=float)
            values = blocks(th)
            m = values.mean(axis=-2)
            try:  # the equations in the scale of their own covariance at theta
                z = np.linalg.solve(factor(values), m[..., None])
            except np.linalg.LinAlgError:
                return np.full(m.shape, np.nan)
            return (L0 @ z)[..., 0]

        labels = tuple(
            f"identity {j if isinstance(j, str) else model.drift_terms[j].params[0]}" for j in rows
        )
        return Moments(
            component=self.name,
            labels=labels,
            mean=mean,
            influence=per_block - per_block.mean(axis=0),
            info={
                "velocity_restoration_s2": float(deficit[1, 1]),
                "jet_deficit": deficit.tolist(),
                "identities": list(labels),
                "whitening_order": len(spectrum.operator(th0)) - 1,
            },
        )
