r"""The pilot of a linear system's channels' spectral matrix: Whittle's maximum, searched.

:class:`hosid.components.chain_spectral_matrix.ChainSpectralMatrix` is prepared at a
pilot; its rounds only refine it, so the pilot must sit in the right basin of Whittle's
likelihood, whose narrow resonances make it many-peaked.  :func:`spectral_pilot` maximises
it by L-BFGS-B from a few starts (:func:`uniform_start`, the identities' pilot, and under
a shaped force the white force's maximum with the shape from a grid,
:func:`shape_start`), within the priors' supports and with every damper's coefficient at
least 0 (:func:`damping_floor`), first within :func:`search_box`.  Where a system's
file leaves the forces' shape to the record, :func:`settled_shape` compares the white
force's maximum with the narrow-band shape's.
"""

from __future__ import annotations

import dataclasses

import numpy as np
from scipy import optimize

from ..chain_state import ChainState
from ..components.chain_spectral_matrix import (
    GROUP,
    check_noise_model,
    periodogram,
    spectral_matrix,
)
from ..model.system import System
from ..model.system_priors import MASS_WIDENING

__all__ = [
    "BROAD",
    "CHOICES",
    "SETTLE",
    "SHAPE_GRID",
    "damping_floor",
    "search_box",
    "settled_shape",
    "spectral_pilot",
    "uniform_start",
]


def damping_floor(system: System, lower: np.ndarray) -> np.ndarray:
    r"""``lower`` with every damping coefficient at least 0: eq (65) per element of a
    linear system, which the search keeps because Whittle's likelihood hardly sees the
    damping's sign (:math:`C \to -C` conjugates :math:`H`, so :math:`S \to S^{\mathsf T}`:
    only the cross-spectra's small imaginary parts tell them apart).  Used under a shaped
    force (:mod:`hosid.inference.system_estimate`): on 20 records of
    ``analyses/system_excitation_study.py``, with neither it nor the broad start
    (:data:`BROAD`) 6 ended far from the truth, one with both dampers negative; with both,
    1.  On the white force's noisy two-dof chain of ``tests/test_sensor_noise.py`` it
    led the search to a heavy second mass, so the white force's search goes without it.
    """
    out = np.array(lower, dtype=float)
    for col, (_, t) in enumerate(system.columns):
        if t.name == "linear_damping":
            out[col] = max(out[col], 0.0)
    return out


def spectral_pilot(
    state: ChainState,
    system: System,
    theta,
    lower,
    upper,
    *,
    band=None,
    white=None,
    deviance=False,
):
    r"""Whittle's maximum within ``[lower, upper]`` from a few starts, the best one: ``theta``
    (if given) and a uniform one (:func:`uniform_start`), each with every noise level at
    its channel's acceleration floor; L-BFGS-B in the logarithms of the positive
    parameters, on the periodogram (``band``, default :func:`periodogram`) averaged over
    each group of bins (the rounds then solve on every bin).  Under a shaped force, the
    white force's maximum first (or ``white``, given), and from it as another start, and a
    second uniform start with broad resonances (:data:`BROAD`), each start with the shape at
    :func:`shape_start` (the shape's grid holds nearly white shapes, so the result is at
    least as likely as the white force's: from the two first starts alone the building's
    record gave a worse maximum; :func:`damping_floor` for the rest).  With ``deviance``,
    also the maximum's deviance: :math:`-2\log L` over every bin (:func:`settled_shape`).
    A record without sensor noise leaves every :math:`S(\omega)` of a force at fewer dofs
    than channels nearly singular: the search is then ill-conditioned (a simulated
    two-dof chain under a narrow-band force: the shape's parameters far off, Hansen's J
    in the thousands).
    """
    check_noise_model(system, state)
    P = periodogram(state, system) if band is None else band
    starts = [uniform_start(state, system, z) for z in ((0.02, BROAD) if system.excitation
                                                         else (0.02,))]  # fmt: skip
    starts = starts if theta is None else [np.array(theta, dtype=float), *starts]
    for th in starts:
        for d in system.sensor_noise:
            th[system.index(f"N[{d}]")] = state.channels[system.dofs.index(d)].band.floor
    if system.excitation:
        plain = dataclasses.replace(system, excitation=(), values=())
        keep = [system.index(n) for n in plain.param_names]
        sub = None if theta is None else np.asarray(theta, dtype=float)[keep]
        starts.insert(0, np.zeros(len(system.param_names)))
        starts[0][keep] = (spectral_pilot(state, plain, sub, lower[keep], upper[keep], band=P)
                           if white is None else white)  # fmt: skip
    nll, logs, scale = _grouped_nll(state, system, P)
    box = search_box(system, lower, upper)

    def z_of(th):
        return np.where(logs, np.log(np.maximum(th, 1e-300)), th)

    def fun(z):  # the value and its forward-difference gradient, in one batch
        h = 1e-6 * np.maximum(np.abs(z), 1.0)
        f = nll(np.vstack([z, z + np.diag(h)]))
        return f[0], (f[1:] - f[0]) / h

    def search(z0, lo, hi):
        return optimize.minimize(fun, z0, jac=True, method="L-BFGS-B",
                                 bounds=list(zip(z_of(lo), z_of(hi), strict=True)),
                                 options={"maxiter": 5000, "maxfun": 20000})  # fmt: skip

    best = None
    boxes = [box, (lower, upper)] if np.any(box[0] > lower) or np.any(box[1] < upper) else [box]
    for th in starts:
        for b in boxes:
            got = search(z_of(np.clip(shape_start(state, system, th, *b, nll, logs), *b)), *b)
            if best is None or got.fun < best.fun:
                best = got
    out = np.where(logs, np.exp(best.x), best.x)
    return (out, scale * float(best.fun)) if deviance else out


def search_box(system: System, lower, upper) -> tuple[np.ndarray, np.ndarray]:
    r"""Where :func:`spectral_pilot`'s starts search first: the bounds, with every
    element's coefficients in their range before
    :data:`~hosid.model.system_priors.MASS_WIDENING` widened it for unknown masses (each
    start is searched from in the box and within the whole bounds).  Whittle's likelihood
    is many-peaked: with the widened range as the first search's bounds, one record of
    the two-dof chain of ``tests/test_system_excitation.py`` ended in another peak.
    """
    lo, hi = np.array(lower, dtype=float), np.array(upper, dtype=float)
    if None in system.masses:
        lo[: system.n_drift] /= MASS_WIDENING
        hi[: system.n_drift] /= MASS_WIDENING
    return lo, hi


def _grouped_nll(state: ChainState, system: System, P):
    r"""Whittle's :math:`-\log L` on the periodogram ``P``'s group averages, as a function
    of the parameters with the log-scaled ones (the second value) in their logarithms, and
    the factor that makes twice it the deviance of every bin (:func:`settled_shape`): each
    group average counts for its bins, whose variance the taper inflates by ``P.taper``.
    """
    G = int(P.group.max()) + 1
    count = np.bincount(P.group, minlength=G)
    omega = np.bincount(P.group, P.omega, G) / count
    avg = np.zeros((G, *P.matrix.shape[1:]), dtype=complex)
    np.add.at(avg, P.group, P.matrix)
    avg = avg / count[:, None, None]
    logs = np.zeros(len(system.param_names), dtype=bool)
    logs[system.log_params] = True

    def nll(z):  # (..., p) -> (...)
        S = spectral_matrix(system, np.where(logs, np.exp(np.minimum(z, 700.0)), z), omega,
                            state.dt)  # fmt: skip
        sign, logdet = np.linalg.slogdet(S)
        tr = np.einsum("...kij,kji->...k", np.linalg.inv(S), avg).real
        out = np.sum(logdet.real + tr, axis=-1)
        return np.where(np.all(sign.real > 0, axis=-1) & np.isfinite(out), out, 1e300)

    return nll, logs, 2.0 * P.omega.size / G / P.taper


#: The uniform start's damping ratio under a shaped force: broad resonances smooth
#: Whittle's likelihood, whose narrow peaks trap the search (:func:`spectral_pilot`).
BROAD = 0.2
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


#: The fall of Whittle's deviance by which a record rejects the white force for the
#: narrow-band shape: the 99.9 % point of a chi-square of 2 degrees of freedom (``wf``,
#: ``zf``; white is the shape's limit, so the test is conservative).
SETTLE = 13.8


#: The shapes a record may choose for a system whose file leaves it open (two parameters
#: each, ``wf`` and ``zf``): a low-pass shaping filter and a band-pass one.
CHOICES = ("narrowband_excitation", "bandpass_excitation")


def settled_shape(state: ChainState, system: System, theta, bounds_of):
    r"""The shape of ``system``'s forces when its file leaves it to the record
    (``excitation`` not given), a linear system of accelerations with sensor noise: the
    white force's Whittle maximum (:func:`spectral_pilot` from ``theta``) and each shape's
    of :data:`CHOICES` (a shaker's or a sea's force, 2 parameters more) from it, on the
    same band (the shapes': not cut at the record's apparent excitation edge); the shape
    of the lowest deviance when it lowers the white force's by more than
    :data:`SETTLE`.  ``bounds_of(system)`` gives a system's search bounds.  Returns the
    chosen system, its maximum (the pilot) and a note of what the record said.

    A white force modelled where it is coloured costs the frequencies: on the building's
    twin driven by a narrow-band roof force 2-4 % (``analyses/results/building.md``).
    """
    white = dataclasses.replace(system, excitation=())
    shapes = [dataclasses.replace(system, excitation=(name,)) for name in CHOICES]
    P = periodogram(state, shapes[0])  # one band for all: the shapes', not cut at an edge
    lw, uw = bounds_of(white)
    th_w, d_w = spectral_pilot(state, white, theta, lw, uw, band=P, deviance=True)
    best = None
    for shaped in shapes:
        ls, us = bounds_of(shaped)
        th, d = spectral_pilot(state, shaped, None, damping_floor(shaped, ls), us, band=P,
                               white=th_w, deviance=True)  # fmt: skip
        if best is None or d < best[2]:
            best = (shaped, th, d)
    shaped, th_s, d_s = best
    if d_s < d_w - SETTLE:  # the white search may have missed: again from the shaped one
        keep = [shaped.index(n) for n in white.param_names]
        again, d_again = spectral_pilot(state, white, th_s[keep], lw, uw, band=P, deviance=True)
        th_w, d_w = (again, d_again) if d_again < d_w else (th_w, d_w)
    drop = d_w - d_s
    if drop > SETTLE:
        name = shaped.excitation[0].name
        return (
            shaped,
            th_s,
            (
                f"the record rejects a white force (Whittle's deviance {drop:.4g} lower with "
                f"{name}, wf = {th_s[shaped.index('wf')]:.4g} rad/s, zf = "
                f"{th_s[shaped.index('zf')]:.3g}): the forces share that shape"
            ),
        )
    return white, th_w, f"white force kept (a shaped force lowers the deviance by {drop:.3g})"
