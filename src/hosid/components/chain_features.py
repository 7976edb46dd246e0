r"""What a system's components share: its elements' motion, features and restorations.

For a system of :mod:`hosid.model.system` on the state of its record
(:class:`hosid.chain_state.ChainState`), element :math:`e` sees the relative motion
:math:`r_e = (Bq)_e` and :math:`\dot r_e`, and drift coefficient :math:`c` of element
:math:`e_c` the feature :math:`\varphi_c(r_{e_c})` or :math:`\varphi_c(\dot r_{e_c})`;
the inferred force of dof :math:`d` (eq 45 with indices) is

.. math:: X_d = m_d\ddot q_d + \sum_cB_{e_cd}\,\varphi_c\,\theta_c
    = \lambda_d^{\mathsf T}Y_d, \qquad \lambda_d = (m_d, \theta_{c\in d}),
    \quad Y_d = (\ddot q_d, B_{e_cd}\varphi_c)_{c\in d},

over the coefficients :math:`c \in d` of the elements that touch :math:`d`.

**Restoration.**  What the sampled state lacks is nearly independent of what it holds,
so a statistic :math:`h` of the state is restored as :math:`h + \tfrac12\mathrm{tr}(C\,
\nabla^2h)` with :math:`C` the covariance of the missing part (:class:`Restoration`):

- above the Nyquist frequency, the velocity of a *displacement* channel of a driven dof
  lacks :math:`s_d^2 = \pi^2S_{0,d}/(6m_d^2\omega_N)` (:func:`hosid.state.velocity_deficit`
  of the acceleration's level :math:`S_{0,d}/m_d^2`), independently across dofs (the
  forces are), so the relative velocities lack :math:`S^v = B\,\mathrm{diag}(s^2)B^{\mathsf
  T}`; an acceleration channel holds that power as aliases (:mod:`hosid.chain_state`), an
  undriven dof's velocity is smooth: both lack none;
- an *acceleration* channel's displacement (:mod:`hosid.chain_state`) lacks its part
  below the band's filter and holds the trapezoid rule's random walk:
  :math:`C^q_{dd'} = 2\beta\min(\omega_{L,d}, \omega_{L,d'})S_{qq,dd'}(0) -
  \delta_{dd'}\beta' S_{0,d}\Delta t^2/(6m_d^2\omega_{L,d})` (0 where either channel is a
  displacement; :math:`\beta` and :math:`\beta'` of the filter, :data:`BUTTER` and
  :data:`BUTTER_WALK`), with :math:`S_{qq}(0)` the displacements' spectrum at the bottom
  of the band as the record shows it (:func:`low_spectrum`; the equivalent linear
  system's :math:`K^{-1}\mathrm{diag}(S_0)K^{-1}` was a third of it on the paper
  oscillator), :math:`C^r = BC^qB^{\mathsf T}` for the elements.  The generator
  identities do not use the missing part's restoration: they extrapolate the band edge
  to zero (:meth:`hosid.components.chain_identities.ChainIdentities.extrapolated`).

A velocity feature is restored exactly where its term knows how
(:meth:`hosid.model.base.DriftTerm.smoothed`); generalized functions are regularized at
:math:`\epsilon_e = \max(\sqrt{S^v_{ee}}, 0.05\,\sigma_{\dot r_e})`.  For the one-element
chain all of this is the single oscillator's (:mod:`hosid.components.base`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..chain_state import MARGIN, ChainState
from ..model.system import System
from ..spectra.derivatives import velocity_deficit

__all__ = [
    "BUTTER_NOISE",
    "Restoration",
    "column_blocks",
    "dof_columns",
    "force_ffts",
    "lam",
    "low_spectrum",
    "noise_shares",
    "places",
    "relative",
    "restoration",
    "shape",
    "system_scales",
]


#: The zero-phase high-pass (:func:`hosid.spectra.integrate.integrate_in_time`: a
#: fourth-order Butterworth filter run forwards and backwards) passes the power
#: :math:`g(u)^2`, :math:`g = u^8/(1 + u^8)`, :math:`u = \omega/\omega_L`: the part below
#: the band is :math:`\int_0^\infty(1 - g^2)\,du = \tfrac98\,\pi/(8\sin(\pi/8))` times
#: :math:`\omega_L` times the flat spectrum there (this constant), and a spectrum
#: :math:`\propto\omega^{-2}` keeps :math:`\int_0^\infty g^2u^{-2}\,du = \tfrac78\,\pi/
#: (8\sin(\pi/8))` (:data:`BUTTER_WALK`) over :math:`\omega_L`.  (Taken for
#: :math:`\int(1 - g) = \int g/u^2 = \pi/(8\sin(\pi/8))` before 2026-11-27: the loss
#: 11 % too small, the random walk 14 % too large.)
BUTTER = 9.0 / 8.0 * (math.pi / 8.0) / math.sin(math.pi / 8.0)
#: :math:`\int_0^\infty g^2u^{-2}\,du` (:data:`BUTTER`).
BUTTER_WALK = 7.0 / 8.0 * (math.pi / 8.0) / math.sin(math.pi / 8.0)
#: :math:`\int_0^\infty g^2u^{-4}\,du = \tfrac58\,\pi/(8\sin(3\pi/8))`: a white
#: acceleration noise :math:`N` (two-sided) leaves :math:`2N\cdot` this
#: :math:`/\omega_L^3` in the integrated displacement (and :data:`BUTTER_WALK`
#: :math:`/\omega_L` in the velocity).
BUTTER_NOISE = 5.0 / 8.0 * (math.pi / 8.0) / math.sin(3.0 * math.pi / 8.0)


def _key(system: System) -> bytes:
    return system.incidence.tobytes()


def relative(state: ChainState, system: System, blocks: bool = False):
    r""":math:`(r, \dot r)` of every element, each ``(E, N)`` (or ``(E, B, M)`` with
    ``blocks``), computed once per state.
    """

    def make():
        B = system.incidence
        r, rd = B @ state.q, B @ state.v
        if system.n == 1:  # the single oscillator: the displacement itself
            r, rd = state.q.copy(), state.v.copy()
        return r, rd, state.layout.take(r), state.layout.take(rd)

    got = state.cached(("relative", _key(system)), make)
    return got[2:] if blocks else got[:2]


@dataclass(frozen=True)
class Restoration:
    """The covariances of what the sampled state lacks (module docstring): ``s2`` per
    dof, ``low`` ``(n, n)``, and per element ``Sv``, ``Cr`` ``(E, E)`` and the widths
    ``eps`` and relative velocity sds ``sd`` ``(E,)``.
    """

    s2: np.ndarray
    low: np.ndarray
    Sv: np.ndarray
    Cr: np.ndarray
    eps: np.ndarray
    sd: np.ndarray

    @property
    def velocity_sd(self) -> np.ndarray:
        r"""Restored sd of each element's relative velocity (eq 65's :math:`\sigma`)."""
        return np.sqrt(self.sd**2 + np.diag(self.Sv))


def restoration(
    state: ChainState, system: System, theta: np.ndarray, *, lost: bool = True
) -> Restoration:
    """The restoration at ``theta`` (module docstring); without the displacement's part
    below an acceleration's band unless ``lost`` (the identities extrapolate it away:
    :mod:`hosid.components.chain_identities`).
    """
    th = np.asarray(theta, dtype=float)
    m, S0 = system.mass_vector(th), system.levels(th)
    n = system.n
    s2 = np.zeros(n)
    for d, ch in enumerate(state.channels):
        if ch.kind == "displacement" and S0[d] > 0:
            s2[d] = float(velocity_deficit(float(S0[d] / m[d] ** 2), state.dt))
    low = np.zeros((n, n))
    omega_low = np.array([c.omega_low for c in state.channels])
    if np.any(omega_low > 0):
        if lost:
            edge = np.minimum.outer(omega_low, omega_low)
            low = 2.0 * BUTTER * edge * _static(state, system, th)
        for d in np.flatnonzero(omega_low > 0):  # the trapezoid rule's random walk, in excess
            low[d, d] -= BUTTER_WALK * S0[d] * state.dt**2 / (6.0 * m[d] ** 2 * omega_low[d])
    B = system.incidence
    _, rd = relative(state, system)
    sd = rd.std(axis=1)
    Sv = (B * s2) @ B.T
    eps = np.maximum(np.sqrt(np.maximum(np.diag(Sv), 0.0)), 0.05 * sd)
    return Restoration(s2, low, Sv, B @ low @ B.T, eps, sd)


def noise_shares(state: ChainState, system: System) -> np.ndarray:
    r"""``(elements, 2)``: the share of each element's relative displacement and velocity
    variance that its acceleration channels' noise would make, were each channel's floor
    :math:`F_d` (:func:`hosid.spectra.integrate.acceleration_band`) a white noise:
    :math:`\sum_dB_{ed}^2\,2F_d\,c/\omega_{L,d}^k` over the variance, with
    :math:`(c, k)` = (:data:`BUTTER_NOISE`, 3) and (:data:`BUTTER_WALK`, 1).  The floor,
    the least of many smoothed ordinates, reads a white noise at 0.5-0.6 of its level
    (``tests/test_system_fit.py``), so the shares are lower bounds where the floor is
    noise (a record without noise has its floor at the lowest bins, far below).
    """
    B = system.incidence
    floor = np.array([c.band.floor if c.band is not None else 0.0 for c in state.channels])
    wl = np.array([c.omega_low if c.band is not None else 1.0 for c in state.channels])
    noise = np.stack([2.0 * floor * BUTTER_NOISE / wl**3, 2.0 * floor * BUTTER_WALK / wl])
    var = np.stack([(B @ state.q).var(axis=1), (B @ state.v).var(axis=1)])
    return ((B**2 @ noise.T) / np.maximum(var.T, 1e-300)).astype(float)


def _static(state: ChainState, system: System, th: np.ndarray) -> np.ndarray:
    r""":math:`S_{qq}(0)`, the displacements' spectrum at the bottom of the band, as the
    record shows it (module docstring): the integrated displacements' cross-periodogram
    over :math:`[1.5, 3]\,\omega_L` (:func:`low_spectrum`) less the random walk's
    :math:`S_0\Delta t^2/12m^2\omega^2` of each acceleration channel.
    """
    A, inv_w2 = low_spectrum(state)
    kinds = np.array([c.band is not None for c in state.channels], dtype=float)
    m, S0 = system.mass_vector(th), system.levels(th)
    return A - np.diag(kinds * S0 / m**2) * state.dt**2 / 12.0 * inv_w2


def low_spectrum(state: ChainState) -> tuple[np.ndarray, float]:
    r"""The displacements' two-sided cross-spectrum averaged over
    :math:`1.5\omega_L \le \omega \le 3\omega_L` (:math:`\omega_L` the channels' largest
    band edge), each bin divided by the filters' gains :math:`g(\omega/\omega_{L,d})`
    (:data:`BUTTER`), from every segment's whole transform inside its margins, and the
    mean of :math:`1/\omega^2` over those bins; computed once per state.  The flat
    spectrum there is what the band's filter removed below :math:`\omega_L`.
    Measured on 2000 s of the paper oscillator from its accelerations: 2.8 times
    :math:`S_0/k^2` of the equivalent linear stiffness :math:`k = a_2 + 3n_2E[x^2]`,
    which restored 1/3 of the displacement's missing variance (the identities of the
    cubic stiffness then 1-2 sd off at the truth).
    """

    def make():
        wl = np.array([c.omega_low for c in state.channels])
        top = float(wl.max())
        dt, n = state.dt, state.n
        margin = round(MARGIN * 2.0 * math.pi / top / dt)
        acc = np.zeros((n, n))
        inv, count = 0.0, 0
        for a, b in state.record.bounds:
            a, b = a + margin, b - margin
            if b - a < 16:
                continue
            X = np.fft.rfft(state.q[:, a:b], axis=1)
            w = 2.0 * math.pi * np.fft.rfftfreq(b - a, dt)
            k = np.flatnonzero((w >= 1.5 * top) & (w <= 3.0 * top))
            if k.size == 0:
                continue
            u = w[k][None, :] / np.where(wl > 0, wl, 1.0)[:, None]
            g = np.where(wl[:, None] > 0, u**8 / (1.0 + u**8), 1.0)  # (n, K)
            Y = X[:, k] / g
            cross = np.einsum("dk,ek->de", Y, Y.conj()).real
            acc += cross * dt / (2.0 * math.pi * (b - a))
            inv += float(np.sum(1.0 / w[k] ** 2))
            count += k.size
        if count == 0:
            return np.zeros((n, n)), 0.0
        return acc / count, inv / count

    return state.cached(("low spectrum",), make)


def column_blocks(state: ChainState, system: System, c: int, rest: Restoration) -> np.ndarray:
    r"""Coefficient ``c``'s feature on the blocks, ``(B, M)``, restored (module
    docstring): :math:`E[\varphi(\dot r + s Z)]` for a velocity feature, :math:`\varphi(r)
    + \tfrac12C^r_{ee}\varphi''(r)` for a displacement feature.
    """
    e, t = system.columns[c]
    rb, rdb = relative(state, system, blocks=True)
    if t.variable == "v":
        return t.smoothed(rdb[e], float(rest.Sv[e, e]), float(rest.eps[e]))
    out = t.phi(rb[e])
    if rest.Cr[e, e] > 0 and t.variable == "x":
        out = out + 0.5 * rest.Cr[e, e] * t.phi(rb[e], 2)
    return out


def dof_columns(system: System, d: int) -> tuple[np.ndarray, np.ndarray]:
    """The coefficients in dof ``d``'s equation and their signs :math:`B_{e_cd}`."""
    B = system.incidence
    sign = np.array([B[e, d] for e, _ in system.columns])
    cols = np.flatnonzero(sign != 0)
    return cols, sign[cols]


def force_ffts(
    state: ChainState, system: System, d: int, rest: Restoration, bins: np.ndarray, window=None
) -> np.ndarray:
    r"""Block transforms of :math:`Y_d` (module docstring), ``(1 + |c \in d|, B, K)``,
    with the state's window or ``window``; cached per feature and restoration.
    """
    cols, sign = dof_columns(system, d)
    rows = [state.block_fft(("a", d), lambda b: b["a"][d], bins, window)]
    for c, s in zip(cols, sign, strict=True):
        e, t = system.columns[c]
        spread = rest.Sv[e, e] if t.variable == "v" else rest.Cr[e, e]
        # by element and term, not by column: systems of one topology share a state
        # (hosid.check.locate) and number their columns differently
        key = ("column", _key(system), int(e), t.name, round(float(spread), 12), state.centred)
        Y = state.block_fft(key, lambda b, c=c: column_blocks(state, system, c, rest), bins,
                            window)  # fmt: skip
        rows.append(Y if s == 1.0 else s * Y)
    return np.stack(rows)


@dataclass(frozen=True)
class Places:
    """Where a system's masses, levels and each dof's force coefficients sit in
    ``theta`` (:func:`places`): what the components' means read at every evaluation.
    """

    fixed: np.ndarray  # (n,) the known masses (1 where unknown)
    free: np.ndarray  # dofs with an unknown mass
    i_mass: np.ndarray  # their positions in theta
    driven: np.ndarray  # driven dofs
    i_S0: np.ndarray  # their levels' positions
    cols: tuple[np.ndarray, ...]  # per dof, its equation's coefficients
    where: tuple[int, ...]  # per dof, the position of its mass in theta (-1: known)

    def masses(self, th: np.ndarray) -> np.ndarray:
        """:math:`m`, ``(..., n)``."""
        m = np.broadcast_to(self.fixed, (*th.shape[:-1], self.fixed.size)).copy()
        m[..., self.free] = th[..., self.i_mass]
        return m

    def levels(self, th: np.ndarray) -> np.ndarray:
        r""":math:`S_{0,d}`, ``(..., n)`` (0 undriven)."""
        out = np.zeros((*th.shape[:-1], self.fixed.size))
        out[..., self.driven] = th[..., self.i_S0]
        return out

    def mass(self, th: np.ndarray, d: int) -> np.ndarray:
        """:math:`m_d`, ``(..., 1)``."""
        i = self.where[d]
        if i >= 0:
            return th[..., i : i + 1]
        return np.full((*th.shape[:-1], 1), self.fixed[d])

    def lam(self, th: np.ndarray, d: int) -> np.ndarray:
        r""":math:`\lambda_d(\theta) = (m_d, \theta_{c\in d})`, ``(..., 1 + |c \in d|)``."""
        return np.concatenate([self.mass(th, d), th[..., self.cols[d]]], axis=-1)


def places(system: System) -> Places:
    """The :class:`Places` of ``system`` (made once per system, kept on it: a system's
    hash walks all its terms, too slow for every evaluation of the equations).
    """
    got = system.__dict__.get("_places")
    if got is None:
        got = system.__dict__["_places"] = _places(system)
    return got


def _places(system: System) -> Places:
    names = system.param_names
    free = [d for d, m in enumerate(system.masses) if m is None]
    driven = [system.dofs.index(x) for x in system.driven]
    s0 = ["S0" if system.single_names else f"S0[{system.dofs[d]}]" for d in driven]
    i_mass = [names.index(f"mass[{system.dofs[d]}]") for d in free]
    where = [-1] * system.n
    for d, i in zip(free, i_mass, strict=True):
        where[d] = i
    return Places(
        fixed=np.array([1.0 if m is None else m for m in system.masses]),
        free=np.array(free, dtype=int),
        i_mass=np.array(i_mass, dtype=int),
        driven=np.array(driven, dtype=int),
        i_S0=np.array([names.index(n) for n in s0], dtype=int),
        cols=tuple(dof_columns(system, d)[0] for d in range(system.n)),
        where=tuple(where),
    )


def lam(system: System, theta: np.ndarray, d: int) -> np.ndarray:
    r""":math:`\lambda_d(\theta) = (m_d, \theta_{c\in d})`, ``(..., 1 + |c \in d|)``."""
    return places(system).lam(np.asarray(theta, dtype=float), d)


def shape(state: ChainState, d: int, omega: np.ndarray) -> np.ndarray | None:
    r"""How the force of dof ``d`` is seen on ``omega``: ``None`` (flat) for a
    displacement channel, :math:`\sum_j(\omega/(\omega + 2j\omega_N))^2` for an
    acceleration channel, whose acceleration is the spectral derivative of the velocity's
    samples: the force's white part, :math:`S_0/m^2\omega^2` in the velocity, folds into
    the band and is multiplied by :math:`\omega^2` there.
    """
    if state.channels[d].kind == "displacement":
        return None
    j = np.arange(-64, 65)
    w = np.asarray(omega, dtype=float)[..., None]
    return np.sum((w / (w + 2.0 * j * state.omega_nyquist)) ** 2, axis=-1)


def system_scales(state: ChainState, system: System, sigma_v=None):
    """The record's :class:`~hosid.model.system_priors.SystemScales`: per element its
    relative motion's sds (``sigma_v``, the elements' restored velocity sds, replaces the
    sampled ones when given), per dof its acceleration's rough level.
    """
    from dataclasses import replace

    from ..model.system_priors import SystemScales
    from ..model.terms import Scales

    r, rd = relative(state, system)
    out = []
    for e, el in enumerate(system.elements):
        ch = state.channels[system.dofs.index(el.between[1])]
        s = ch.scales
        if system.n > 1:
            s = Scales(float(np.std(r[e])), float(np.std(rd[e])), s.S0, s.dt, s.band_edge)
        if sigma_v is not None:
            s = replace(s, sigma_v=float(np.asarray(sigma_v)[e]))
        out.append(s)
    return SystemScales(tuple(out), tuple(c.scales.S0 for c in state.channels))
