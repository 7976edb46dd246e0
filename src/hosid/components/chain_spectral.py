r"""The inferred force vector of a system: its spectral matrix and its levels.

At the true parameters the force inferred on each dof, :math:`X_d = m_d\ddot q_d +
(\Phi\theta)_d = \lambda_d^{\mathsf T}Y_d` (:mod:`hosid.components.chain_features`), is
the dof's own white force: the spectral matrix of :math:`X` is
:math:`\mathrm{diag}(S_{0,d})` on every frequency (eq 21 with its indices,
:math:`\hat V^a_{dd'} = k_2S_{0,d}\delta_{dd'}`), the forces' fourth cumulants vanish, and
an undriven dof's force is zero.  Three components read it, each per driven dof
:math:`d` and, for the one-element chain, exactly the single oscillator's
(:mod:`hosid.components.spectral`, :mod:`hosid.components.level`,
:mod:`hosid.components.cumulant`):

- :class:`ChainJ2`: on the J2 band, the in-band level of each driven dof (J2's
  :math:`S_0` equation, a U-statistic over block pairs with the weight
  :math:`\partial\bar h/\partial S_{0,d}` frozen at the pilot), and for each pair of
  driven dofs the real and imaginary parts of their standardized cross-periodogram,

  .. math:: c_{dd'}(\theta) = \frac1K\sum_k\frac{\overline{X_d(\omega_k)X^*_{d'}
      (\omega_k)}}{2\pi Tk_2\sqrt{S_{0,d}S_{0,d'}L_dL_{d'}}},

  block means with expectation 0 for independent forces (they check the model and
  inform the couplings);
- :class:`ChainLevel`: the level of each driven dof from every boxcar ordinate above
  the J2 band to :math:`0.9\,\omega_N`, :math:`|X_d|^2/(2\pi TS_{0,d}A_d(\omega))`
  with the channel's alias factor (:func:`hosid.components.level.alias_factor` for a
  displacement, :math:`\sum_j(\omega/(\omega + 2j\omega_N))^2` for an acceleration);
- :class:`ChainKurtosis`: the fourth cumulant of each driven dof's force.

:math:`L_d(\omega)` is 1 for a displacement channel and the acceleration's aliases
:math:`\sum_j(\omega/(\omega + 2j\omega_N))^2` for an acceleration channel
(:func:`hosid.components.chain_features.shape`).
The J2 band runs from bin 2 (and from :data:`EDGE_FACTOR` times every acceleration
channel's band edge) to
:math:`\min(6\max_d\omega_{n,d}, \omega_N/2)`, below half of every channel's noise floor
edge and 0.9 of any excitation edge (:func:`chain_band`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..chain_state import ChainState
from ..model.system import System
from .base import Moments, u_pseudovalues
from .chain_features import force_ffts, lam, restoration, shape
from .level import FLOOR, MIN_BINS, MIN_BLOCKS, TOP, alias_factor, end_blocks
from .spectral import BAND_FACTOR

__all__ = ["EDGE_FACTOR", "ChainJ2", "ChainLevel", "chain_band"]

#: The J2 band starts this many times above an acceleration channel's band edge, where the
#: integration's high-pass (:func:`hosid.spectra.integrate.integrate_in_time`, gain
#: :math:`u^8/(1 + u^8)`) passes :math:`1 - 1.5\cdot10^{-5}` of the power (at 1.5 times
#: the edge it passed 0.96, and the in-band levels came out 1-2 standard errors low).
EDGE_FACTOR = 4.0
#: An acceleration channel's displacement carries the trapezoid rule's random walk
#: :math:`\epsilon` (spectrum :math:`S_0\Delta t^2/12m^2\omega^2`,
#: :func:`hosid.spectra.integrate.integrate_in_time`), which the stiffness turns into a
#: share :math:`\omega_n^4\Delta t^2/12\omega^2` of the inferred force's level: the J2 band
#: starts where that share is below this (on 6 records of the 2-dof chain the in-band levels
#: from bin 2 were 1-2 standard errors low).
WALK_SHARE = 1e-3


def chain_band(state: ChainState, *, edges: bool = True) -> tuple[float, float]:
    """``(omega_lo, omega_hi)`` of the J2 band of a system's state (module docstring);
    without ``edges`` the top ignores where the record's excitation seems to stop.
    """
    chans = state.channels
    hi = min(
        BAND_FACTOR * max(c.scales.omega_n for c in chans),
        0.5 * state.omega_nyquist,
        0.5 * min(c.spectrum.floor_edge for c in chans),
    )
    found = [c.spectrum.edge[0] for c in chans if c.spectrum.edge is not None]
    if found and edges:
        hi = min(hi, 0.9 * min(found))
    lo = EDGE_FACTOR * max(c.omega_low for c in chans)
    if any(c.kind == "acceleration" for c in chans):  # the trapezoid's walk: stiffness x it
        w2 = max(c.scales.omega_n for c in chans) ** 2
        lo = max(lo, w2 * state.dt / math.sqrt(12.0 * WALK_SHARE))
    return lo, hi


def _driven(system: System) -> list[int]:
    return [system.dofs.index(d) for d in system.driven]


@dataclass(frozen=True)
class ChainJ2:
    """In-band levels and cross-spectra of the inferred forces (module docstring)."""

    name: str = "J2"
    cross: bool = True

    def prepare(self, state: ChainState, system: System, pilot: np.ndarray) -> Moments:
        """Per-dof U-statistics of the level and block means of the cross-spectra."""
        th0 = np.asarray(pilot, dtype=float)
        L = state.layout
        lo, hi = chain_band(state)
        bins = L.bins(lo, hi, k_min=2)
        if bins.size < 3:
            raise ValueError(f"the J2 band {lo:g}-{hi:g} rad/s holds fewer than 3 bins")
        omega = bins * L.d_omega
        rest = restoration(state, system, th0)
        norm = 2 * math.pi * L.T * state.window.k2
        driven = _driven(system)
        parts, labels, infl, Xs = [], [], [], {}
        for d in driven:
            Y = force_ffts(state, system, d, rest, bins)  # (F, B, K)
            Ld = shape(state, d, omega)
            mean, u, X0 = _level_u(Y, Ld, system, d, th0, norm)
            parts.append(mean)
            infl.append(u)
            Xs[d] = (Y, Ld, X0)
            labels.append(f"J2 d/d{system.param_names[_s0_index(system, d)]}")
        if self.cross:
            for i, d in enumerate(driven):
                for e in driven[i + 1 :]:
                    mean, u = _cross(Xs[d], Xs[e], system, d, e, norm, th0)
                    parts.append(mean)
                    infl.append(u)
                    pair = f"{system.dofs[d]}-{system.dofs[e]}"
                    labels += [f"J2 cross {pair} re", f"J2 cross {pair} im"]

        def mean(theta):
            return np.concatenate([f(theta) for f in parts], axis=-1)

        U = np.concatenate(infl, axis=1)
        return Moments(
            component=self.name,
            labels=tuple(labels),
            mean=mean,
            influence=U - U.mean(axis=0),
            info={
                "band_rad_s": [float(omega[0]), float(omega[-1])],
                "bins": int(bins.size),
                "form": "scaled",
            },
        )


def _s0_index(system: System, d: int) -> int:
    return system.index("S0" if system.single_names else f"S0[{system.dofs[d]}]")


def _level_u(Y, Ld, system: System, d: int, th0, norm):
    """J2's in-band level equation of dof ``d`` (:class:`hosid.components.spectral.J2`
    with ``with_level``), its jackknife pseudo-values and the pilot's force transform.
    """
    i_S0 = _s0_index(system, d)
    R = np.einsum("ibk,jbk->bkij", Y, Y.conj()).real / norm  # (B, K, F, F)
    B, K = R.shape[:2]
    lam0 = lam(system, th0, d)
    S0 = th0[i_S0]
    level0 = S0 * (np.ones(K) if Ld is None else Ld)
    P0 = np.einsum("bkij,i,j->bk", R, lam0, lam0) / level0
    if system.single_names:  # the single oscillator's layout, so that its sums run alike
        nd = system.n_drift
        full = np.empty((B, K, nd + 1))
        full[:, :, nd] = -P0 / S0
        w = full[:, :, nd : nd + 1]
    else:
        w = (-P0 / S0)[:, :, None]  # (B, K, 1): d h / d S0
    wbar = w.mean(axis=0)
    Rbar = R.mean(axis=0)
    A = np.einsum("kj,kxy->kjxy", wbar, Rbar) - np.einsum("bkj,bkxy->kjxy", w, R) / B**2
    c = wbar - w.mean(axis=0) / B
    scale = B / ((B - 1) * K)
    c_sum = c.sum(axis=0)
    A_white = A.sum(axis=0)
    inv = None if Ld is None else 1.0 / Ld

    def mean(theta):
        th = np.asarray(theta, dtype=float)
        lm = lam(system, th, d)
        if inv is None:
            total = np.einsum("...x,jxy,...y->...j", lm, A_white, lm)
        else:
            q = np.einsum("...x,kjxy,...y->...kj", lm, A, lm)
            total = np.einsum("k,...kj->...j", inv, q)
        return scale * (total / th[..., i_S0][..., None] - c_sum)

    u = u_pseudovalues(w / K, P0 - 1.0)
    X0 = np.tensordot(lam0, Y, axes=1)  # (B, K)
    return mean, u, X0


def _cross(first, second, system: System, d: int, e: int, norm, th0):
    """The cross-spectrum equations of dofs ``d`` and ``e`` (module docstring) and their
    block values at the pilot ``th0``.
    """
    (Yd, Ld, Xd), (Ye, Le, Xe) = first, second
    K = Yd.shape[-1]
    shp = np.ones(K) if Ld is None and Le is None else np.sqrt(
        (np.ones(K) if Ld is None else Ld) * (np.ones(K) if Le is None else Le)
    )  # fmt: skip
    C = np.einsum("ibk,jbk,k->bij", Yd, Ye.conj(), 1.0 / shp) / (K * norm)  # (B, Fd, Fe)
    Cbar = C.mean(axis=0)
    i_d, i_e = _s0_index(system, d), _s0_index(system, e)

    def mean(theta):
        th = np.asarray(theta, dtype=float)
        z = np.einsum("...i,ij,...j->...", lam(system, th, d), Cbar, lam(system, th, e))
        z = z / np.sqrt(th[..., i_d] * th[..., i_e])
        return np.stack([z.real, z.imag], axis=-1)

    z = np.sum(Xd * Xe.conj() / shp, axis=-1) / (K * norm * math.sqrt(th0[i_d] * th0[i_e]))
    return mean, np.stack([z.real, z.imag], axis=-1)


@dataclass(frozen=True)
class ChainLevel:
    """The level of each driven dof above the J2 band (module docstring)."""

    name: str = "level"

    def bins(self, state: ChainState, d: int) -> np.ndarray:
        r"""Dof ``d``'s bins: above the J2 band, up to :math:`0.9\omega_N` (below half its
        floor's edge).
        """
        L = state.layout
        lo = chain_band(state)[1]
        hi = min(TOP * state.omega_nyquist, FLOOR * state.channels[d].spectrum.floor_edge)
        bins = L.bins(lo, hi, k_min=2)
        return bins[bins * L.d_omega > lo]

    def skipped(self, state: ChainState, d: int) -> str | None:
        """Why dof ``d``'s equation does not hold (``None``: it does)."""
        if state.channels[d].spectrum.band_limited:
            return "the excitation stops below the Nyquist frequency"
        n = self.bins(state, d).size
        if n < MIN_BINS:
            return f"{n} bins above J2's band"
        inner = int((~end_blocks(state)).sum())
        if inner < MIN_BLOCKS:
            return f"{inner} blocks away from the segments' ends"
        return None

    def prepare(self, state: ChainState, system: System, pilot: np.ndarray) -> Moments:
        """Per-block quadratic forms of each driven dof's band (module docstring)."""
        th0 = np.asarray(pilot, dtype=float)
        L = state.layout
        rest = restoration(state, system, th0)
        keep = ~end_blocks(state)
        parts, labels, infl, info = [], [], [], {}
        for d in _driven(system):
            why = self.skipped(state, d)
            if why is not None:
                info[system.dofs[d]] = {"skipped": why}
                continue
            bins = self.bins(state, d)
            omega = bins * L.d_omega
            Y = force_ffts(state, system, d, rest, bins, window="boxcar")
            A = shape(state, d, omega)
            if A is None:
                A = alias_factor(omega, state.omega_nyquist)
            K = bins.size
            Q = np.einsum("ibk,jbk,k->bij", Y, Y.conj(), 1.0 / (2 * math.pi * L.T * A)).real / K
            Qbar = Q[keep].mean(axis=0)
            i_S0 = _s0_index(system, d)

            def mean(theta, Qbar=Qbar, d=d, i_S0=i_S0):
                th = np.asarray(theta, dtype=float)
                lm = lam(system, th, d)
                q = np.einsum("...i,ij,...j->...", lm, Qbar, lm)
                return (q / th[..., i_S0] - 1.0)[..., None]

            lam0 = lam(system, th0, d)
            u = np.einsum("i,bij,j->b", lam0, Q, lam0) / th0[i_S0]
            u = np.where(keep, (u - u[keep].mean()) * (L.B / keep.sum()), 0.0)
            parts.append(mean)
            infl.append(u[:, None])
            labels.append(f"level {system.param_names[i_S0]}")
            info[system.dofs[d]] = {"band_rad_s": [float(omega[0]), float(omega[-1])],
                                    "bins": int(K)}  # fmt: skip
        if not parts:
            return Moments.empty(self.name, L.B, "; ".join(f"{k}: {v['skipped']}"
                                                           for k, v in info.items()))  # fmt: skip
        if system.single_names:
            info = info[system.dofs[0]] | {"blocks": int(keep.sum())}
        else:
            info["blocks"] = int(keep.sum())

        def mean(theta):
            return np.concatenate([f(theta) for f in parts], axis=-1)

        return Moments(self.name, tuple(labels), mean, np.concatenate(infl, axis=1), info)
