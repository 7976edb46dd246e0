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

import dataclasses
import math
from dataclasses import dataclass

import numpy as np
from scipy import optimize, signal

from ..chain_state import ChainState
from ..errors import HosidInputError
from ..model.system import System
from ..spectra.windows import get_window
from .base import Moments
from .chain_spectral import chain_band

__all__ = ["GROUP", "LINEAR", "ChainSpectralMatrix", "check_noise_model", "spectral_pilot"]

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
    g = g * (omega**2)[:, None]  # acceleration per unit force
    g = g * np.sqrt(system.levels(th)[..., driven])[..., :, None, None]
    S = np.einsum("...akn,...akm->...knm", g, g.conj())
    white = system.spectrum.white
    if not white:
        S = S * system.spectrum.shape(omega, th)[..., :, None, None]
    idx = np.arange(n)
    if dt is not None:
        s2 = np.sinc(omega * dt / (2.0 * math.pi)) ** 2
        S = S * s2[:, None, None]
        flat = system.levels(th) * minv**2  # (..., n), 0 off the driven dofs
        alias = 1.0 - s2 if white else (1.0 - s2) * system.spectrum.shape(
            2.0 * math.pi / dt - omega, th)  # the nearest alias's shape  # fmt: skip
        S[..., idx, idx] += alias[..., :, None] * flat[..., None, :]
    S[..., idx, idx] += system.noise_levels(th)[..., None, :]
    return S


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
            S = _hermitian_parts(spectral_matrix(system, th, omega, state.dt))
            return base.sum(axis=1) - S.reshape(*th.shape[:-1], -1) @ Wt / G

        per = base - np.einsum("jkab,kba->jk", W, S0).real @ onehot.T / G  # (p, G)
        per = G * per.T  # the group values whose mean is the equation
        WS = W @ S0
        cov = P.taper * np.einsum("jkab,lkba->jl", WS, WS).real / G  # one group's
        labels = tuple(f"spectral matrix {n}" for n in system.param_names)
        info = {"band_rad_s": [float(omega.min()), float(omega.max())], "bins": int(omega.size),
                "groups": G, "covariance": "Whittle's (model)"}  # fmt: skip
        return Moments(self.name, labels, mean, per - per.mean(axis=0), info, cov)


def spectral_pilot(state: ChainState, system: System, theta, lower, upper, *, band=None):
    r"""Whittle's maximum within ``[lower, upper]`` from two starts, the better one: ``theta``
    (if given) and a uniform one (:func:`uniform_start`), each with every noise level at
    its channel's acceleration floor; L-BFGS-B in the logarithms of the positive
    parameters, on the periodogram (``band``, default :func:`periodogram`) averaged over
    each group of bins (the rounds then solve on every bin).  Under a shaped force, the
    white force's maximum first, and from it with the shape at :func:`shape_start` (the
    shape's grid holds nearly white shapes, so the result is at least as likely as the
    white force's: from the starts directly, the building's record gave a worse maximum).
    A record without sensor noise leaves every :math:`S(\omega)` of a force at fewer dofs
    than channels nearly singular: the search is then ill-conditioned (a simulated
    two-dof chain under a narrow-band force: the shape's parameters far off, Hansen's J
    in the thousands).
    """
    check_noise_model(system, state)
    P = periodogram(state, system) if band is None else band
    starts = [uniform_start(state, system)]
    starts = starts if theta is None else [np.array(theta, dtype=float), *starts]
    for th in starts:
        for d in system.sensor_noise:
            th[system.index(f"N[{d}]")] = state.channels[system.dofs.index(d)].band.floor
    if system.excitation:
        white = dataclasses.replace(system, excitation=(), values=())
        keep = [system.index(n) for n in white.param_names]
        sub = None if theta is None else np.asarray(theta, dtype=float)[keep]
        starts = [np.zeros(len(system.param_names))]
        starts[0][keep] = spectral_pilot(state, white, sub, lower[keep], upper[keep], band=P)
    G = int(P.group.max()) + 1
    count = np.bincount(P.group, minlength=G)
    omega = np.bincount(P.group, P.omega, G) / count
    avg = np.zeros((G, *P.matrix.shape[1:]), dtype=complex)
    np.add.at(avg, P.group, P.matrix)
    avg = avg / count[:, None, None]
    logs = np.zeros(len(system.param_names), dtype=bool)
    logs[system.log_params] = True
    lo = np.where(logs, np.log(np.maximum(lower, 1e-300)), lower)
    hi = np.where(logs, np.log(upper), upper)

    def nll(z):  # (..., p) -> (...)
        S = spectral_matrix(system, np.where(logs, np.exp(np.minimum(z, 700.0)), z), omega,
                            state.dt)  # fmt: skip
        sign, logdet = np.linalg.slogdet(S)
        tr = np.einsum("...kij,kji->...k", np.linalg.inv(S), avg).real
        out = np.sum(logdet.real + tr, axis=-1)
        return np.where(np.all(sign.real > 0, axis=-1) & np.isfinite(out), out, 1e300)

    def minimize(z0, free):  # over the parameters ``free``, the others held
        def fun(u):  # the value and its forward-difference gradient, in one batch
            z = np.repeat(z0[None], u.size + 1, axis=0)
            h = 1e-6 * np.maximum(np.abs(u), 1.0)
            z[:, free] = np.vstack([u, u + np.diag(h)])
            f = nll(z)
            return f[0], (f[1:] - f[0]) / h

        got = optimize.minimize(fun, z0[free], jac=True, method="L-BFGS-B",
                                bounds=list(zip(lo[free], hi[free], strict=True)),
                                options={"maxiter": 5000, "maxfun": 20000})  # fmt: skip
        z = z0.copy()
        z[free] = got.x
        return z, got.fun

    best = None
    for th in starts:
        th = np.clip(shape_start(state, system, th, lower, upper, nll, logs), lower, upper)
        got = minimize(np.where(logs, np.log(np.maximum(th, 1e-300)), th), np.arange(th.size))
        if best is None or got[1] < best[1]:
            best = got
    return np.where(logs, np.exp(best[0]), best[0])


#: Grid points per parameter of a shaped force's start (:func:`shape_start`).
SHAPE_GRID = 9


def shape_start(state, system: System, theta, lower, upper, nll, logs) -> np.ndarray:
    """``theta`` with the forces' shape parameters (if any) at the best of a grid over
    their supports (:data:`SHAPE_GRID` points each, log-spaced for a log parameter), the
    levels rescaled at each so that the force's level at the channels' largest peak stays
    ``theta``'s; ``nll`` is Whittle's on the groups' averages (:func:`spectral_pilot`).
    """
    th = np.array(theta, dtype=float)
    idx = [i for _, ix in system.spectrum.terms for i in ix]
    if not idx:
        return th
    axes = [np.exp(np.linspace(np.log(lower[i]), np.log(upper[i]), SHAPE_GRID)) if logs[i]
            else np.linspace(lower[i], upper[i], SHAPE_GRID) for i in idx]  # fmt: skip
    grid = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, len(idx))
    cand = np.repeat(th[None], grid.shape[0], axis=0)
    cand[:, idx] = grid
    levels = [system.index(f"S0[{d}]") for d in system.driven]
    cand[:, levels] /= system.spectrum.shape(np.array([peak_frequency(state, system)]), cand)
    z = np.where(logs, np.log(np.maximum(cand, 1e-300)), cand)
    return cand[int(np.argmin(nll(z)))]


def peak_frequency(state: ChainState, system: System) -> float:
    """The largest peak of the channels' summed periodogram over the band (rad/s)."""
    P = periodogram(state, system)
    power = np.einsum("kii->k", P.matrix).real
    return float(P.omega[np.argmax(np.convolve(power, np.ones(2 * GROUP + 1), "same"))])


def uniform_start(state: ChainState, system: System, zeta: float = 0.02) -> np.ndarray:
    r"""Every element's stiffness :math:`k` and damping :math:`c` alike, unknown masses 1,
    each driven level its channel's rough level times its mass squared: the slowest mode
    of :math:`M\ddot q + cL\dot q + kL q` (:math:`L = B^{\mathsf T}B`, eigenvalue
    :math:`\mu_1` of :math:`M^{-1}L`) at the largest peak of the channels' summed
    periodogram over the band, damping ratio ``zeta``: :math:`k = \omega^2/\mu_1`,
    :math:`c = 2\zeta\omega/\mu_1`.
    """
    peak = peak_frequency(state, system)
    th = np.zeros(len(system.param_names))
    for name in system.param_names:
        if name.startswith("mass["):
            th[system.index(name)] = 1.0
    m = system.mass_vector(th)
    B = system.incidence
    mu = float(np.min(np.linalg.eigvals((B.T @ B) / m[:, None]).real))
    for col, (_, t) in enumerate(system.columns):
        th[col] = peak**2 / mu if t.name == "linear_stiffness" else 2 * zeta * peak / mu
    for d in system.driven:
        i = system.dofs.index(d)
        th[system.index(f"S0[{d}]")] = state.channels[i].scales.S0 * m[i] ** 2
    return th
