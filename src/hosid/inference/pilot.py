r"""A closed-form pilot estimate: where the estimating equations are linearized.

The generator identities of all drift terms are linear in the drift coefficients and in
:math:`D = \pi S_0`: :math:`\bar Q\theta = -\bar c + D(\rho\bar e + \rho_x\bar e_x)`,
so :math:`\theta(D) = \alpha + \beta D`.  The level of the force inferred with
:math:`\theta(D)` on the J2 band must equal :math:`S_0 = D/\pi`,

.. math:: \frac1K\sum_k\frac{\lambda(D)^{\mathsf T}\bar R_k\lambda(D)}{L_k} = \frac{D}{\pi},

a quadratic equation in :math:`D`; its smallest positive root is taken (or, when the
level only touches :math:`D/\pi`, the point of closest approach).  Two rounds
update the velocity restoration and the excitation's shape.
"""

from __future__ import annotations

import math

import numpy as np

from ..components.base import feature_ffts
from ..components.cumulant import ForceKurtosis
from ..components.excitation import Excitation
from ..components.identities import Identities
from ..components.jets import whitened_statistics
from ..components.jumps import kink_constants, read_table
from ..components.spectral import default_band
from ..errors import HosidInputError
from ..model.excitation import Spectrum
from ..model.model import Model
from ..state import RecordState

__all__ = ["initial_theta", "pilot", "whitened_pilots"]


def initial_theta(state: RecordState, model: Model) -> np.ndarray:
    """A start before any estimate: no drift, the rough level, white-ish excitation (or
    the middle of the record's excitation edge).
    """
    s = state.scales
    noise = state.noise["sd"] if state.noise else 0.01 * s.sigma_x
    start = {
        "S0": s.S0,
        "wc": 2.0 * s.omega_nyquist,
        "wb": 0.5 * sum(s.band_edge) if s.band_edge else s.omega_nyquist,
        "noise_sd": max(noise, 1e-3 * s.sigma_x),
        "wf": 2.0 * s.omega_nyquist,
        "zf": 0.7,
        "rate": 100.0 * s.omega_nyquist,
    }
    return np.array([start.get(p, 0.0) for p in model.param_names])


def pilot(state: RecordState, model: Model, theta: np.ndarray | None = None) -> np.ndarray:
    """The pilot estimate (module docstring), starting from ``theta`` if given.

    Raises
    ------
    HosidInputError
        If the identities are singular or no positive excitation level solves them
        (the record does not look like a randomly excited oscillator of this model).
    """
    theta = initial_theta(state, model) if theta is None else np.array(theta, dtype=float)
    if Spectrum(model).whitening:
        return whitened_pilots(state, model, theta)[0]
    nd = model.n_drift
    L = state.layout
    bins = L.bins(*default_band(state), k_min=2)
    omega = bins * L.d_omega
    for _ in range(2):
        Q, const, e, ex, rows, s2 = Identities().statistics(state, model, theta)
        if model.has("rate"):  # the impulses' identities at the current rate
            area = 2.0 * math.pi * theta[model.index("S0")] / theta[model.index("rate")]
            tables = Identities().jump_tables(state, model, rows, s2)
            e = read_table(tables, area, state.scales.sigma_v)
        exc = Excitation(model, theta, state.scales.sigma_v, state.scales.sigma_x)
        rho, rho_x = (float(r) for r in exc.powers(theta, state.dt))
        try:
            alpha = np.linalg.solve(Q.mean(0), -const.mean(0))
            beta = np.linalg.solve(Q.mean(0), rho * e.mean(0) + rho_x * ex.mean(0))
        except np.linalg.LinAlgError:
            raise HosidInputError(
                "the generator identities are singular: the record does not excite the "
                "model's terms"
            ) from None
        Y = feature_ffts(state, model, s2, bins)
        R = np.einsum("ibk,jbk->kij", Y, Y.conj()).real / (
            L.B * 2 * math.pi * L.T * state.window.k2
        )
        Lk = exc.shape(omega, theta)
        l0 = np.concatenate([[1.0], alpha])
        l1 = np.concatenate([[0.0], beta])
        quad = [
            np.mean(np.einsum("kij,i,j->k", R, u, w) / Lk)
            for u, w in ((l1, l1), (l0, l1), (l0, l0))
        ]
        roots = np.roots([quad[0], 2 * quad[1] - 1.0 / math.pi, quad[2]])
        # no real root: the level touches D/pi without crossing; take the closest point
        roots = roots.real if np.iscomplexobj(roots) else roots
        roots = roots[roots > 0]
        if roots.size == 0:
            raise HosidInputError(
                "no positive excitation level explains the record's force spectrum: the "
                "record does not look like a randomly excited oscillator of this model"
            )
        D = float(roots.min())
        theta[:nd] = alpha + beta * D
        theta[model.index("S0")] = D / math.pi
        if model.has("rate"):
            theta[model.index("rate")] = _impulse_rate(state, model, theta)
    if not np.all(np.isfinite(theta)):
        raise HosidInputError("the pilot estimate is not finite")
    return theta


def _impulse_rate(state: RecordState, model: Model, theta: np.ndarray) -> float:
    r"""The rate of Poisson impulses whose fourth cumulant is the inferred force's at
    ``theta`` (:mod:`hosid.components.jumps`), within the rate's prior support: a
    Gaussian-looking force gets its top (white).
    """
    info = ForceKurtosis().prepare(state, model, theta).info
    excess, m2 = info["excess_kurtosis_at_pilot"], info["sigma"] ** 2
    support = model.default_priors(state.scales, constrained=False)["rate"]
    if not excess > 0:
        return float(support.upper)
    c4 = kink_constants()[1]
    rate = c4 * (2.0 * math.pi * theta[model.index("S0")]) ** 2 / (state.dt**3 * m2**2 * excess)
    return float(np.clip(rate, support.lower, support.upper))


def _level(R: np.ndarray, Lk: np.ndarray, alpha: np.ndarray, beta: np.ndarray) -> float | None:
    r"""The smallest positive :math:`D` with :math:`\frac1K\sum_k\lambda(D)^{\mathsf T}
    R_k\lambda(D)/L_k = D/\pi` (module docstring), or ``None``.
    """
    l0 = np.concatenate([[1.0], alpha])
    l1 = np.concatenate([[0.0], beta])
    quad = [
        np.mean(np.einsum("kij,i,j->k", R, u, w) / Lk) for u, w in ((l1, l1), (l0, l1), (l0, l0))
    ]
    roots = np.roots([quad[0], 2 * quad[1] - 1.0 / math.pi, quad[2]])
    roots = roots.real if np.iscomplexobj(roots) else roots
    roots = roots[roots > 0]
    return float(roots.min()) if roots.size else None


def whitened_pilots(
    state: RecordState, model: Model, theta: np.ndarray, n_best: int = 4, refine: bool = False
) -> list[np.ndarray]:
    r"""Pilots of a model whose force goes through a shaping filter: over a grid of the
    filter's :math:`(\omega_f, \zeta_f)` (:math:`\omega_n/4` to :math:`100\,\omega_N`,
    0.02 to 2, log-spaced), the identities of the augmented state
    (:mod:`hosid.components.jets`, unrestored) give :math:`\theta(D) = \alpha + \beta D`
    and the level equation :math:`D`, as for a white force; the inferred force's
    standardized periodogram :math:`\bar P_k/S_0L_k` should be flat on the J2 band (least
    squares about 1).  The up to ``n_best`` deepest local minima of that
    misfit (lower than their eight neighbours) are returned, best first: a filter near the
    oscillator's resonance can fit the spectrum with the two swapped, and the estimate
    keeps the solution that every start's weight accepts best
    (:func:`hosid.inference.estimate.select_solution`).

    The coarse grid (48 x 16 points) steps :math:`\omega_f` by a factor 1.23; a filter
    peaked at the resonance then has its true and swapped minima between two points, and
    the solver started at the nearer one ended in a third solution.  Measured on a ship-
    roll-like record (40 000 s, filter and oscillator both at 0.6 rad/s): the two coarse
    minima led to solutions with Hansen's :math:`J` 45 and 1000 on 7 df, the true one
    has 4.7.  With ``refine`` the minima of a finer grid over :math:`\omega_n/2` to
    :math:`2\omega_n` (factor 1.04, :math:`\zeta_f` factor 1.2) are returned instead: the
    estimate tries them when no coarse start's solution passes its Hansen test.  Tried
    always, they found swapped solutions the coarse grid had missed and that the data of
    4000 s do not reject (the filter below the ship's resonance: 2 of 10 records kept the
    swapped one, own :math:`J` 2.3 against 5.6, and 4 of 10 sampled both).

    Raises
    ------
    HosidInputError
        If no point of the grid gives a positive level.
    """
    misfit = _PilotMisfit(state, model, theta)
    s = state.scales
    if model.has("wf") and refine:
        grids = [(np.geomspace(0.5 * s.omega_n, 2.0 * s.omega_n, 36), np.geomspace(0.02, 2.0, 26))]
    elif model.has("wf"):
        grids = [
            (
                np.geomspace(0.25 * s.omega_n, 100.0 * s.omega_nyquist, 48),
                np.geomspace(0.02, 2.0, 16),
            )
        ]
    else:  # a measured shape: the filter is fixed
        grids = [(np.array([np.nan]), np.array([np.nan]))]
    ranked: list[tuple[float, np.ndarray]] = []
    for wfs, zfs in grids:
        ranked += misfit.minima(wfs, zfs)
    if not ranked:
        raise HosidInputError(
            "no positive excitation level explains the record's force spectrum through a "
            "shaping filter: the record does not look like a randomly excited oscillator "
            "of this model"
        )
    ranked.sort(key=lambda ct: ct[0])
    out: list[np.ndarray] = []
    for _, th in ranked:
        if all(not np.allclose(th, o, rtol=1e-9) for o in out):
            out.append(th)
    return out[:n_best]


class _PilotMisfit:
    """The pilot's misfit of :func:`whitened_pilots` at any filter ``(wf, zf)``: the
    record's statistics computed once.
    """

    def __init__(self, state: RecordState, model: Model, theta: np.ndarray):
        self.model, self.theta = model, theta
        self.spectrum = Spectrum(model)
        M = self.spectrum.order
        st = whitened_statistics(
            state, model, list(range(model.n_drift)), np.zeros((M + 2, M + 2))
        )
        self.pairs = sorted(st["Q"])
        self.Qm = np.stack([st["Q"][k].mean(axis=0) for k in self.pairs])
        self.Cm = np.stack([st["C"][k].mean(axis=0) for k in self.pairs])
        self.em = st["e"].mean(axis=0)
        L = state.layout
        bins = L.bins(*default_band(state), k_min=2)
        self.omega = bins * L.d_omega
        Y = feature_ffts(state, model, 0.0, bins)
        self.R = np.einsum("ibk,jbk->kij", Y, Y.conj()).real / (
            L.B * 2 * math.pi * L.T * state.window.k2
        )

    def at(self, wf: float, zf: float) -> tuple[float, np.ndarray] | None:
        """The misfit and the pilot with the filter at ``(wf, zf)`` (NaN: the model's
        fixed shape), or ``None`` where no positive level exists.
        """
        model, nd = self.model, self.model.n_drift
        th = self.theta.copy()
        if not math.isnan(wf):
            th[model.index("wf")], th[model.index("zf")] = wf, zf
        p = [float(c) for c in self.spectrum.operator(th)]
        Wp = np.array([p[m] * p[n] for m, n in self.pairs])
        try:
            A = np.einsum("q,qjk->jk", Wp, self.Qm)
            alpha = np.linalg.solve(A, -(Wp @ self.Cm))
            beta = np.linalg.solve(A, self.em)
        except np.linalg.LinAlgError:
            return None
        Lk = self.spectrum.shape(self.omega, th)
        D = _level(self.R, Lk, alpha, beta)
        if D is None:
            return None
        lam = np.concatenate([[1.0], alpha + beta * D])
        h = np.einsum("kij,i,j->k", self.R, lam, lam) / (D / math.pi * Lk) - 1.0
        th[:nd], th[model.index("S0")] = lam[1:], D / math.pi
        return float(np.sum(h**2)), th

    def minima(self, wfs: np.ndarray, zfs: np.ndarray) -> list[tuple[float, np.ndarray]]:
        """The grid's local minima (each at most its eight neighbours): (misfit, pilot)."""
        cost = np.full((wfs.size, zfs.size), np.inf)
        found = {}
        for a, wf in enumerate(wfs):
            for b, zf in enumerate(zfs):
                r = self.at(float(wf), float(zf))
                if r is not None:
                    cost[a, b], found[a, b] = r
        padded = np.pad(cost, 1, constant_values=np.inf)
        near = np.stack(
            [np.roll(np.roll(padded, i, 0), j, 1)[1:-1, 1:-1]
             for i in (-1, 0, 1) for j in (-1, 0, 1) if (i, j) != (0, 0)]
        )  # fmt: skip
        minima = np.argwhere(np.isfinite(cost) & np.all(cost <= near, axis=0))
        return [(float(cost[tuple(ab)]), found[tuple(ab)]) for ab in minima]
