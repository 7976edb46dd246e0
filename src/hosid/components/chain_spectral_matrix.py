r"""The channels' spectral matrix: Whittle's equations for a linear system with sensor noise.

A record of floor accelerations carries each sensor's own noise.  The generator identities
(:mod:`hosid.components.chain_identities`) are moments of the integrated channels over
their whole band, where that noise, integrated twice, can outweigh a storey's relative
motion: on a simulated five-storey chain with a real building's sensor noise their
stiffnesses came out 3 to 80 times too small, and 5-30 % too small even with the noise's
variance subtracted exactly (``analyses/results/building.md``).  A frequency weighs its
signal over its noise only in the spectral matrix of the channels.

For a system whose terms are all linear (:mod:`hosid.model.linear_chain`: :math:`M, C,
K`), every channel an acceleration :math:`\ddot q_d + \epsilon_d` with a white noise of
two-sided level :math:`N_d` (``N[dof]``, :attr:`hosid.model.system.System.sensor_noise`),
the channels' two-sided spectral matrix is

.. math:: S(\omega;\theta) = \omega^4H\,\mathrm{diag}(S_{0,d})\,H^{\mathsf H}
    + \mathrm{diag}(N_d), \qquad H(\omega) = (K - \omega^2M + i\omega C)^{-1}

(eq 21 with its indices: the inferred forces' matrix :math:`\mathrm{diag}(S_{0,d})`, seen
through the system's transfer, and each sensor's noise); forces of a shared shape
:math:`L(\omega;\theta)` (:attr:`hosid.model.system.System.excitation`, a shaker's or a
sea's) have :math:`\mathrm{diag}(S_{0,d}L(\omega))`, and this is then the system's only
component (the identities assume white forces).  Each segment's periodogram
:math:`I_k = Y_kY_k^{\mathsf H}/(2\pi T k_2)` (Hann taper over the whole segment, linear
trend removed, :math:`Y_k` the channels' transforms) over the band, and the equations
are Whittle's score with its weights frozen at the pilot :math:`\tilde\theta`,

.. math:: m_j(\theta) = \frac1G\sum_g\sum_{k\in g}\mathrm{tr}\big(W_{jk}(I_k -
    S_k(\theta))\big), \qquad W_{jk} = \tilde S_k^{-1}\,\partial_j\tilde S_k\,
    \tilde S_k^{-1},

zero in expectation at the truth whatever the pilot; the rounds re-prepare them at the
estimate, whose root is then the maximum of Whittle's likelihood, efficient for a linear
Gaussian system.  Their covariance is Whittle's, :math:`\mathrm{Cov}(m_j, m_l) = c\sum_k
\mathrm{tr}(W_{jk}\tilde S_kW_{lk}\tilde S_k)/G^2` (a complex Gaussian ordinate has
:math:`\mathrm{Cov}(Y^{\mathsf H}AY, Y^{\mathsf H}BY) = \mathrm{tr}(ASBS)`; the taper
correlates neighbouring ordinates, :math:`c = L\sum h^4/(\sum h^2)^2`, 35/18 for Hann):
the spread of the rows, groups of :data:`GROUP` neighbouring bins, over-weighted the few
groups at a narrow resonance (on 9 records of the building's twin the first frequency's
z had sd 1.8).  The band runs from half the lowest acceleration band edge
(:func:`hosid.spectra.integrate.acceleration_band`: there the noise outweighs the motion
ten-fold and shows its level) to the top of J2's band
(:func:`hosid.components.chain_spectral.chain_band`).  The whole segment's taper resolves
a resonance whose bandwidth :math:`2\zeta\omega` spans several bins; on shorter records
the taper's leakage widens the peaks (no correction).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import signal

from ..chain_state import ChainState
from ..errors import HosidInputError
from ..model.system import System
from ..spectra.windows import get_window
from .base import Moments
from .chain_spectral import chain_band

__all__ = [
    "GROUP",
    "LINEAR",
    "ChainSpectralMatrix",
    "band_periodogram",
    "check_noise_model",
    "periodogram",
    "spectral_matrix",
    "spectral_parts",
]

#: Neighbouring bins in one row of the influence.
GROUP = 4
#: The terms whose system has this component's spectral matrix.
LINEAR = ("linear_damping", "linear_stiffness")


def check_noise_model(system: System, state: ChainState) -> None:
    """Raise unless ``system`` is one this component holds for (module docstring).

    A system whose forces share a shape (:attr:`~hosid.model.system.System.excitation`)
    is fitted by this component only: the generator identities assume white forces.

    Raises
    ------
    HosidInputError
        If a term is not linear, or a channel is not an acceleration with a sensor noise.
    """
    what = "sensor noise is modelled"
    if system.excitation:
        what = f"a system's shaped force ({system.excitation[0].name}) is fitted"
    other = sorted({t.name for _, t in system.columns if t.name not in LINEAR})
    if other:
        raise HosidInputError(
            f"{what} for linear systems only ({', '.join(LINEAR)}); this one has "
            f"{', '.join(other)}"
        )
    bare = [c.name for c in state.channels if c.kind != "acceleration"]
    bare += [d for d in system.dofs if d not in (system.sensor_noise or ()) and d not in bare]
    if bare:
        raise HosidInputError(
            f"{what} when every channel is an acceleration with its own noise "
            f"(sensor_noise = true); not so for {', '.join(bare)}"
        )


@dataclass(frozen=True)
class Periodogram:
    """The bins of the band: ``omega`` ``(K,)``, the periodogram ``matrix`` ``(K, n, n)``,
    each bin's group, and the taper's variance factor (module docstring).
    """

    omega: np.ndarray
    matrix: np.ndarray
    group: np.ndarray
    taper: float


def periodogram(state: ChainState, system: System) -> Periodogram:
    """The state's record's :func:`band_periodogram` over the band (module docstring),
    computed once.  Under a shaped force the band's top is not cut at the record's
    apparent excitation edge (the shape's own fall is modelled).
    """
    shaped = bool(system.excitation)

    def make():
        lo = 0.5 * min(c.omega_low for c in state.channels)
        hi = chain_band(state, edges=not shaped)[1]
        return band_periodogram(state.record, lo, hi)

    return state.cached(("spectral matrix periodogram", shaped), make)


def band_periodogram(record, lo: float, hi: float) -> Periodogram:
    """Every segment's periodogram at its bins in ``[lo, hi]`` rad/s (Hann taper over the
    segment, linear trend removed; two-sided, per rad/s), bins grouped by :data:`GROUP`
    within a segment.
    """
    dt, win = record.dt, get_window("hann")
    omega, cross, group, first, taper = [], [], [], 0, []
    for a, b in record.bounds:
        y = signal.detrend(record.x[a:b].T, axis=-1, type="linear")
        L = b - a
        w = 2.0 * math.pi * np.fft.rfftfreq(L, dt)
        keep = np.flatnonzero((w >= lo) & (w <= hi))
        h = win.samples(L)
        Y = np.fft.rfft(y * h, axis=-1)[:, keep] * dt
        cross.append(np.einsum("ik,jk->kij", Y, Y.conj()) / (2.0 * math.pi * L * dt * win.k2))
        omega.append(w[keep])
        taper.append(np.full(keep.size, L * np.sum(h**4) / np.sum(h**2) ** 2))
        group.append(first + np.arange(keep.size) // GROUP)
        first = group[-1][-1] + 1 if keep.size else first
    return Periodogram(np.concatenate(omega), np.concatenate(cross), np.concatenate(group),
                       float(np.mean(np.concatenate(taper))))  # fmt: skip


def spectral_matrix(
    system: System, theta: np.ndarray, omega: np.ndarray, dt: float | None = None
) -> np.ndarray:
    r""":math:`S(\omega;\theta)`, ``(..., K, n, n)``, for ``theta`` ``(..., p)`` (module
    docstring), :math:`H` by the modes of the state matrix :math:`A`
    (:mod:`hosid.model.linear_chain`): :math:`H(\omega) = \sum_rL_rR_r^{\mathsf T}/(i\omega
    - \lambda_r)`, :math:`A = V\Lambda V^{-1}`, :math:`L = [I\;0]V`, :math:`R =
    V^{-1}[0;\,M^{-1}E]` with :math:`E` the driven dofs' columns.

    With ``dt``, the channels are interval averages of the acceleration
    (:mod:`hosid.chain_state`): the motion's part is seen through
    :math:`s^2 = \mathrm{sinc}^2(\omega\Delta t/2)`, and its aliases add
    :math:`(1 - s^2)\,\mathrm{diag}(S_{0,d}/m_d^2)` (a driven dof's acceleration is flat
    far above the modes, and a flat spectrum's aliases through the average sum to 1).
    A shaped force (:attr:`~hosid.model.system.System.excitation`) multiplies the levels
    by :math:`L(\omega)`, and the aliases by :math:`L(2\pi/\Delta t - \omega)`, that of
    the nearest alias (a shape that falls off above the modes leaves them negligible).
    """
    g, diag = _columns(system, theta, omega, dt)
    S = np.einsum("...akn,...akm->...knm", g, g.conj())
    idx = np.arange(g.shape[-1])
    S[..., idx, idx] += diag
    return S


def spectral_parts(
    system: System, theta: np.ndarray, omega: np.ndarray, dt: float | None = None
) -> np.ndarray:
    """:func:`spectral_matrix`'s Hermitian parts (:func:`_hermitian_parts`), ``(..., K,
    n^2)``, from the transfer's columns without the whole matrix (the sampler's
    likelihood; for 46 walkers of the building's chain on 1492 bins, 17 ms against 44 ms
    for the matrix and then its parts: ``benchmarks/test_bench.py``).
    """
    g, diag = _columns(system, theta, omega, dt)
    n = g.shape[-1]
    i, j = np.triu_indices(n, 1)
    d = np.sum(g.real**2 + g.imag**2, axis=-3) + diag
    up = math.sqrt(2.0) * np.sum(g[..., i] * g[..., j].conj(), axis=-3)
    return np.concatenate([d, up.real, up.imag], axis=-1)


def _columns(system: System, theta, omega: np.ndarray, dt: float | None):
    r"""The columns :math:`g_a(\omega)`, ``(..., a, K, n)``, with :math:`S = \sum_a g_a
    g_a^{\mathsf H} + \mathrm{diag}(\cdot)`, and that diagonal, ``(..., K, n)``
    (:func:`spectral_matrix`): each driven dof's acceleration per unit force times the
    square root of its level, the force's shape and the interval average's gain.
    """
    th = np.asarray(theta, dtype=float)
    B, n = system.incidence, system.n
    k = np.zeros((*th.shape[:-1], len(system.elements)))
    c = np.zeros_like(k)
    for col, (e, t) in enumerate(system.columns):
        (k if t.name == "linear_stiffness" else c)[..., e] += th[..., col]
    minv = 1.0 / system.mass_vector(th)
    A = np.zeros((*th.shape[:-1], 2 * n, 2 * n))
    A[..., :n, n:] = np.eye(n)
    A[..., n:, :n] = -minv[..., :, None] * np.einsum("ed,...e,ef->...df", B, k, B)
    A[..., n:, n:] = -minv[..., :, None] * np.einsum("ed,...e,ef->...df", B, c, B)
    lam, V = np.linalg.eig(A)
    driven = [system.dofs.index(d) for d in system.driven]
    U = np.zeros((*th.shape[:-1], 2 * n, len(driven)))
    U[..., n + np.array(driven), np.arange(len(driven))] = minv[..., driven]
    R = np.linalg.solve(V, U.astype(complex))  # (..., 2n, a)
    poles = 1.0 / (1j * omega[:, None] - lam[..., None, :])  # (..., K, 2n)
    g = (poles[..., None, :, :] @ (V[..., None, :n, :] * np.swapaxes(R, -1, -2)[..., :, None, :]
                                   ).swapaxes(-1, -2))  # (..., a, K, n)  # fmt: skip
    gain = omega**4 * np.ones((*th.shape[:-1], 1))  # acceleration per unit force, squared
    white = system.spectrum.white
    if not white:
        gain = gain * system.spectrum.shape(omega, th)
    if dt is not None:
        s2 = np.sinc(omega * dt / (2.0 * math.pi)) ** 2
        gain = gain * s2
    g = g * np.sqrt(system.levels(th)[..., driven, None, None] * gain[..., None, :, None])
    diag = np.broadcast_to(system.noise_levels(th)[..., None, :], (*g.shape[:-3], *g.shape[-2:]))
    if dt is not None:
        flat = system.levels(th) * minv**2  # (..., n), 0 off the driven dofs
        alias = 1.0 - s2 if white else (1.0 - s2) * system.spectrum.shape(
            2.0 * math.pi / dt - omega, th)  # the nearest alias's shape  # fmt: skip
        diag = diag + alias[..., :, None] * flat[..., None, :]
    return g, diag


def _hermitian_parts(S: np.ndarray) -> np.ndarray:
    r"""``(..., n, n)`` Hermitian to ``(..., n^2)`` real: the diagonal, and :math:`\sqrt2`
    times the real and imaginary parts above it, so that :math:`\mathrm{tr}(WS)` of two
    Hermitian matrices is the dot product of their parts.
    """
    n = S.shape[-1]
    i, j = np.triu_indices(n, 1)
    d = np.einsum("...ii->...i", S).real
    up = math.sqrt(2.0) * S[..., i, j]
    return np.concatenate([d, up.real, up.imag], axis=-1)


@dataclass(frozen=True)
class ChainSpectralMatrix:
    """Whittle's equations of the channels' spectral matrix (module docstring)."""

    name: str = "spectral matrix"

    def prepare(self, state: ChainState, system: System, pilot: np.ndarray) -> Moments:
        """The frozen-weight score, per group of bins, at ``pilot``."""
        check_noise_model(system, state)
        th0 = np.asarray(pilot, dtype=float)
        P = periodogram(state, system)
        p = th0.size
        S0 = spectral_matrix(system, th0, P.omega, state.dt)
        inv = np.linalg.inv(S0)
        logs = np.zeros(p, dtype=bool)
        logs[system.log_params] = True
        floor = 1e-3 * np.max(np.abs(th0[: system.n_drift]))  # a coefficient near 0
        step = np.where(logs, 1e-6 * th0, 1e-6 * np.maximum(np.abs(th0), floor))
        E = np.diag(step)
        both = spectral_matrix(system, np.concatenate([th0 + E, th0 - E]), P.omega, state.dt)
        dS = (both[:p] - both[p:]) / (2.0 * step[:, None, None, None])
        W = inv @ dS @ inv  # (p, K, n, n)
        G = int(P.group.max()) + 1
        onehot = np.zeros((G, P.omega.size))
        onehot[P.group, np.arange(P.omega.size)] = 1.0
        Wt = _hermitian_parts(W).reshape(p, -1).T  # tr(W S) as a real dot product
        data = np.einsum("jkab,kba->jk", W, P.matrix).real  # (p, K)
        base = data @ onehot.T / G  # per group, data part
        omega = P.omega

        def mean(theta):
            th = np.asarray(theta, dtype=float)
            S = spectral_parts(system, th, omega, state.dt)
            return base.sum(axis=1) - S.reshape(*th.shape[:-1], -1) @ Wt / G

        per = base - np.einsum("jkab,kba->jk", W, S0).real @ onehot.T / G  # (p, G)
        per = G * per.T  # the group values whose mean is the equation
        WS = W @ S0
        cov = P.taper * np.einsum("jkab,lkba->jl", WS, WS).real / G  # one group's
        labels = tuple(f"spectral matrix {n}" for n in system.param_names)
        info = {"band_rad_s": [float(omega.min()), float(omega.max())], "bins": int(omega.size),
                "groups": G, "covariance": "Whittle's (model)"}  # fmt: skip
        return Moments(self.name, labels, mean, per - per.mean(axis=0), info, cov)
