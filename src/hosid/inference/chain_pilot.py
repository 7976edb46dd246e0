r"""A closed-form pilot of a system's parameters: where its equations are linearized.

With the masses fixed, the generator identities (:mod:`hosid.components.chain_identities`)
are linear in the drift coefficients and in the levels :math:`D_d = \pi S_{0,d}`,
:math:`\bar M(\mu)\theta = -\bar c + \sum_d\mu_d^2D_d\,g_d^2\odot\bar e`, so
:math:`\theta(D) = \alpha + \sum_d\beta_dD_d` (least squares when the rows outnumber the
coefficients).  The level of each driven dof's force inferred with :math:`\theta(D)` on
the J2 band must equal :math:`D_d/\pi`,

.. math:: \frac1K\sum_k\frac{\lambda_d(D)^{\mathsf T}\bar R_{d,k}\lambda_d(D)}{L_{d,k}}
    = \frac{D_d}{\pi},

one quadratic equation per dof, solved in turn for its own :math:`D_d` with the others
held (Gauss-Seidel; the smallest positive root, as the single oscillator's pilot,
:mod:`hosid.inference.pilot`, whose numbers the one-element chain repeats).  Unknown masses
then follow from the identities with the coefficients and the accelerations' levels
:math:`S_{0,d}\mu_d^2` held (linear in :math:`\mu`), and the two steps alternate a few
times: along a chain each dof's mass is fixed by the coefficients of the element below
it, so alternation alone converges slowly; its result starts a joint least-squares solve
of the identities (each scaled by its block scatter) and the level equations, bilinear in
:math:`(\theta, \mu)`.  Two rounds update the velocity restoration.
"""

from __future__ import annotations

import math

import numpy as np

from ..chain_state import ChainState
from ..components.chain_features import force_ffts, restoration, shape
from ..components.chain_identities import ChainIdentities
from ..components.chain_spectral import chain_band
from ..errors import HosidInputError
from ..model.system import System
from ..model.system_priors import MASS_RANGE

__all__ = ["chain_initial", "chain_pilot"]

#: Alternations of the coefficients' and the masses' steps (systems with unknown masses)
#: before the joint least-squares step.
ALTERNATIONS = 10


def chain_initial(state: ChainState, system: System) -> np.ndarray:
    """A start before any estimate: no drift, unit unknown masses, each dof's rough level."""
    th = np.zeros(len(system.param_names))
    k = system.n_drift
    for m in system.masses:
        if m is None:
            th[k] = 1.0
            k += 1
    m = system.mass_vector(th)
    for d in system.driven:
        i = system.dofs.index(d)
        th[system.param_names.index(_s0(system, i))] = state.channels[i].scales.S0 * m[i] ** 2
    return th


def _s0(system: System, d: int) -> str:
    return "S0" if system.single_names else f"S0[{system.dofs[d]}]"


def _solve(M: np.ndarray, b: np.ndarray) -> np.ndarray:
    if M.shape[0] == M.shape[1]:
        return np.linalg.solve(M, b)
    return np.linalg.lstsq(M, b, rcond=None)[0]


def chain_pilot(state: ChainState, system: System, theta: np.ndarray | None = None) -> np.ndarray:
    """The pilot estimate (module docstring), starting from ``theta`` if given.

    Raises
    ------
    HosidInputError
        If the identities are singular or no positive level solves them (the record
        does not look like a randomly excited system of this description).
    """
    th = chain_initial(state, system) if theta is None else np.array(theta, dtype=float)
    driven = [system.dofs.index(d) for d in system.driven]
    i_S0 = [system.param_names.index(_s0(system, d)) for d in driven]
    free = [d for d, m in enumerate(system.masses) if m is None]
    i_m = [system.param_names.index(f"mass[{system.dofs[d]}]") for d in free]
    L = state.layout
    lo, hi = chain_band(state)
    bins = L.bins(lo, hi, k_min=2)
    if bins.size < 3:
        raise HosidInputError(
            f"the J2 band {lo:.3g}-{hi:.3g} rad/s holds fewer than 3 bins (the record's "
            "channels leave no band between their integration edges and the resonances)"
        )
    omega = bins * L.d_omega
    B = system.incidence
    Bcols = np.stack([B[e] for e, _ in system.columns], axis=-1)
    for _ in range(2):
        rest = restoration(state, system, th)
        P, const, e_, rws = ChainIdentities().statistics(state, system, rest)
        Pm, cm, em = P.mean(0), const.mean(0), e_.mean(0)
        g = np.array([w.g for w in rws])
        G2 = np.where(np.array([w.kind == "v" for w in rws])[:, None], g**2, 0.0)  # (A, n)
        T3 = g.T[:, :, None] * Bcols[:, None, :] * Pm[None]  # (n, A, p)
        R, Lk = {}, {}
        for d in driven:
            Y = force_ffts(state, system, d, rest, bins)
            R[d] = np.einsum("ibk,jbk->kij", Y, Y.conj()).real / (
                L.B * 2 * math.pi * L.T * state.window.k2
            )
            Lk[d] = shape(state, d, omega)
            Lk[d] = np.ones(omega.size) if Lk[d] is None else Lk[d]
        for _ in range(ALTERNATIONS if free else 1):
            th = _coefficients(th, system, T3, cm, em, G2, R, Lk, driven, i_S0)
            if free:
                th = _masses(th, system, T3, cm, em, G2, free, i_m, driven, i_S0)
        if free:
            Rbar = {d: np.mean(R[d] / Lk[d][:, None, None], axis=0) for d in driven}
            scale = np.std(const, axis=0) + np.abs(cm) + 1e-300
            th = _joint(th, system, T3, cm, em, G2, Rbar, driven, i_S0, i_m, scale)
    if not np.all(np.isfinite(th)):
        raise HosidInputError("the pilot estimate is not finite")
    return th


def _coefficients(th, system, T3, cm, em, G2, R, Lk, driven, i_S0):
    """The drift coefficients and levels at the current masses (module docstring)."""
    nd = system.n_drift
    mu = 1.0 / system.mass_vector(th)
    Mmat = np.einsum("d,dac->ac", mu, T3) if system.n > 1 else T3[0]
    try:
        alpha = _solve(Mmat, -cm)
        beta = np.stack([_solve(Mmat, mu[d] ** 2 * G2[:, d] * em) for d in driven], axis=-1)
    except np.linalg.LinAlgError:
        raise HosidInputError(
            "the generator identities are singular: the record does not excite the system's terms"
        ) from None
    D = math.pi * th[i_S0]
    cols = {d: np.flatnonzero(system.incidence[[e for e, _ in system.columns], d]) for d in driven}
    m = system.mass_vector(th)
    for _ in range(50 if len(driven) > 1 else 1):
        before = D.copy()
        for k, d in enumerate(driven):
            c = cols[d]
            others = [j for j in range(len(driven)) if j != k]
            held = alpha + beta[:, others] @ D[others] if others else alpha
            l0 = np.concatenate([[m[d]], held[c]])
            l1 = np.concatenate([[0.0], beta[c, k]])
            root = _level_root(R[d], Lk[d], l0, l1)
            if root is None:
                raise HosidInputError(
                    "no positive excitation level explains the record's force spectrum: the "
                    f"record does not look like a randomly excited system of this description "
                    f"(dof {system.dofs[d]})"
                )
            D[k] = root
        if np.allclose(D, before, rtol=1e-10, atol=0.0):
            break
    th = th.copy()
    th[:nd] = alpha + beta @ D
    th[i_S0] = D / math.pi
    return th


def _level_root(R, Lk, l0, l1) -> float | None:
    r"""The smallest positive :math:`D` with the dof's level equation (module docstring)."""
    quad = [
        np.mean(np.einsum("kij,i,j->k", R, u, w) / Lk) for u, w in ((l1, l1), (l0, l1), (l0, l0))
    ]
    roots = np.roots([quad[0], 2 * quad[1] - 1.0 / math.pi, quad[2]])
    roots = roots.real if np.iscomplexobj(roots) else roots
    roots = roots[roots > 0]
    return float(roots.min()) if roots.size else None


def _masses(th, system, T3, cm, em, G2, free, i_m, driven, i_S0):
    r"""The unknown masses with the coefficients and the accelerations' levels
    :math:`S_{0,d}\mu_d^2` held: the identities are then linear in :math:`\mu`.
    """
    nd = system.n_drift
    mu = 1.0 / system.mass_vector(th)
    acc = np.zeros(system.n)  # S0_d mu_d^2
    acc[driven] = th[i_S0] * mu[driven] ** 2
    U = np.einsum("dac,c->ad", T3, th[:nd])  # (A, n): the identities' mu_d coefficients
    rhs = -cm + math.pi * (G2 * acc[None, :]).sum(axis=1) * em
    fixed = [d for d in range(system.n) if d not in free]
    rhs = rhs - U[:, fixed] @ mu[fixed]
    got = np.linalg.lstsq(U[:, free], rhs, rcond=None)[0]
    if not np.all(np.isfinite(got) & (got > 0)):
        return th  # keep the masses: the coefficients are not yet informative
    th = th.copy()
    mu[free] = got
    th[i_m] = 1.0 / got
    th[i_S0] = acc[driven] / mu[driven] ** 2
    return th


def _joint(th, system, T3, cm, em, G2, Rbar, driven, i_S0, i_m, scale):
    r"""The identities and the J2-band level equations solved jointly in the drift
    coefficients, the logarithms of the unknown masses and of the levels (module
    docstring).
    """
    from scipy.optimize import least_squares

    nd = system.n_drift
    cols = {d: np.flatnonzero(system.incidence[[e for e, _ in system.columns], d]) for d in driven}

    def full(z):
        t = th.copy()
        t[:nd] = z[:nd]
        t[i_m] = np.exp(z[nd : nd + len(i_m)])
        t[i_S0] = np.exp(z[nd + len(i_m) :])
        return t

    def residual(z):
        t = full(z)
        mu = 1.0 / system.mass_vector(t)
        ident = np.einsum("d,dac,c->a", mu, T3, t[:nd]) + cm
        ident = ident - (math.pi * system.levels(t) * mu**2) @ G2.T * em
        m = system.mass_vector(t)
        lev = [
            np.concatenate([[m[d]], t[cols[d]]])
            @ Rbar[d]
            @ np.concatenate([[m[d]], t[cols[d]]])
            / t[i]
            - 1.0
            for d, i in zip(driven, i_S0, strict=True)
        ]
        return np.concatenate([ident / scale, lev])

    z0 = np.concatenate([th[:nd], np.log(th[i_m]), np.log(th[i_S0])])
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        got = least_squares(residual, z0, method="lm", xtol=1e-12, ftol=1e-12, max_nfev=2000)
        out = full(got.x)
        better = np.sum(residual(got.x) ** 2) <= np.sum(residual(z0) ** 2)
    lo, hi = MASS_RANGE
    masses = out[i_m]
    if not (np.all(np.isfinite(out)) and better and np.all((masses >= lo) & (masses <= hi))):
        return th  # a collapse (masses out of their range, coefficients to 0): keep th
    return out
