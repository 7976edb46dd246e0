r"""The paper's own estimators on today's engine, and its cost maps (Figures 1-8).

Every estimator below is a choice of model and likelihood components of
:func:`hosid.estimate`, with the paper's settings (Hann window, blocks of 20.48 s,
:math:`\omega \le 8` rad/s unless stated); none is a second engine:

=====================  ==========================================================
``moments``            the moment method (paper's ref 12; NOTES.md): the two
                       stationary moment identities with the damping force's
                       small terms dropped, velocity by hosid's spectral derivative,
                       :math:`E\dot x^2 = a_2Ex^2 + n_2Ex^4`,
                       :math:`3E x^2\dot x^2 = a_2Ex^4 + n_2Ex^6`
``J2 free``            J2 as printed (eq 50) with linear equivalent damping and the
                       stiffness free: the spectral stiffness of Figures 1-2
``J2+J4A free``        J2 and J4A as printed (eqs 50, 59), every parameter free
                       ("all the unknown parameters were simultaneously estimated")
``J2``                 the paper's protocol for :math:`a_{1eq}` and :math:`S_0`:
                       linear equivalent damping, stiffness by the moment identities
                       and J2 as printed (Figures 4-5)
``J2 split``           the same on the paper's model: J2 alone splits
                       :math:`a_1` from :math:`n_1` (Figure 6's second order)
``J4A line``           J4A as printed minimized along the line of eq (65) at J2's
                       :math:`a_{1eq}` (:math:`a_1, n_1 \ge 0`), stiffness and
                       :math:`S_0` from ``J2``: Figure 6's fourth order
``hosid``              the default estimate (generator identities + scaled J2)
=====================  ==========================================================

:func:`cost_maps` evaluates the printed costs themselves over an :math:`(a_1, n_1)` grid
with the other parameters fixed (Figures 7-8):

.. math:: J_2 = \sum_k\big(\hat V^a_k(\lambda) - k_2S_0\big)^2, \qquad
    J_{4A} = \sum_t\big|\hat V^b_t(\lambda) - S_0^2(\Delta_T(\omega_1+\omega_2)
    + \Delta_T(\omega_1+\omega_3) + \Delta_T(\omega_2+\omega_3))\big|^2,

with :math:`\hat V^a_k = \overline{|X_k|^2}/2\pi T` and :math:`\hat V^b_t` the block mean
of :math:`X_1X_2X_3X_4^*/8\pi^3T` on the principal domain (eqs 39, 57-59).  Both are
polynomials in :math:`(a_1, n_1)` (degree 2 and 4 per ordinate): :math:`\hat V^b_t` is
interpolated exactly from 25 evaluations of the compiled block products and then
evaluated on the whole grid (no library forms these; the kernels are hosid's own).
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np

import hosid
from hosid.components._kernels import products
from hosid.components.base import feature_ffts, restoration
from hosid.components.identities import Identities
from hosid.components.polyspectral import J4
from hosid.components.spectral import J2
from hosid.errors import HosidInputError
from hosid.inference.estimate import prepare_state
from hosid.model import Model
from hosid.spectra.domains import trispectral_domain
from hosid.state import RecordState

SQRT_8_PI = math.sqrt(8.0 / math.pi)
PARAMS = ("a1", "n1", "a2", "n2", "S0")
BLOCK_SECONDS = 20.48
OMEGA_MAX = 8.0
LINEAR_DAMPING = "linear_damping,linear_stiffness,cubic_stiffness"
ESTIMATORS = ("moments", "J2 free", "J2+J4A free", "J2", "J2 split", "J4A line", "hosid")
LINE_POINTS = 401


def _components(name: str, omega_max: float) -> tuple[str, list]:
    band = (0.0, omega_max)
    j2 = J2(band=band, form="printed")
    j4 = J4(kind="A", form="printed", omega_max=omega_max)
    return {
        "J2 free": (LINEAR_DAMPING, [j2]),
        "J2+J4A free": ("paper", [j2, j4]),
        "J2": (LINEAR_DAMPING, [Identities("restoring"), j2]),
        "J2 split": ("paper", [Identities("restoring"), j2]),
        "hosid": ("paper", None),
    }[name]


def moments(state) -> dict[str, float]:
    """The moment method (module table) on a prepared state."""
    x, v = state.x, state.v
    A = np.array([[np.mean(x**2), np.mean(x**4)], [np.mean(x**4), np.mean(x**6)]])
    b = np.array([np.mean(v**2), 3.0 * np.mean(x**2 * v**2)])
    a2, n2 = np.linalg.solve(A, b)
    return {"a2": float(a2), "n2": float(n2)}


def record_state(record, block_seconds: float | None = BLOCK_SECONDS) -> RecordState:
    """``record``'s state with the paper's block (a state passes through): every model
    here is white, centred and noise-free, so one state serves them all.
    """
    if isinstance(record, RecordState):
        return record
    return prepare_state(record, Model.from_spec("paper"), block_seconds=block_seconds)


def point_estimates(
    record,
    names=ESTIMATORS,
    *,
    omega_max: float = OMEGA_MAX,
    block_seconds: float = BLOCK_SECONDS,
) -> dict[str, dict[str, float]]:
    """``{estimator: {a1, n1, a2, n2, S0, a1eq}}`` of one record (module table; NaN
    where an estimator does not give a parameter or its equations have no solution).
    ``a1eq`` is eq (65) at the record's velocity sd (the linear-damping estimators'
    ``a1`` is their :math:`a_{1eq}`).  ``omega_max`` and ``block_seconds``: the
    paper's band and block (another oscillator takes them in units of its own natural
    frequency).
    """
    out: dict[str, dict[str, float]] = {}
    state = record_state(record, block_seconds)  # the same for every estimator's model
    sigma_v = state.scales.sigma_v
    for name in names:
        row = dict.fromkeys((*PARAMS, "a1eq"), math.nan)
        if name == "moments":
            row.update(moments(state))
        elif name == "J4A line":
            j2 = out.get("J2") or point_estimates(state, ("J2",), omega_max=omega_max)["J2"]
            row.update(j4a_line(state, j2, sigma_v, omega_max=omega_max))
        else:
            spec, comps = _components(name, omega_max)
            model = Model.from_spec(spec)
            try:
                values = hosid.estimate(state, model, comps, settle=False).values
            except HosidInputError:
                values = None
            if values is not None and spec == LINEAR_DAMPING:
                row.update({k: values[k] for k in ("a2", "n2", "S0")}, a1eq=values["a1"])
            elif values is not None:
                row.update({k: values[k] for k in PARAMS})
                row["a1eq"] = values["a1"] + values["n1"] * SQRT_8_PI * sigma_v
        out[name] = row
    return out


def j4a_line(
    record,
    j2: Mapping[str, float],
    sigma_v: float,
    *,
    omega_max: float = OMEGA_MAX,
    block_seconds: float = BLOCK_SECONDS,
) -> dict[str, float]:
    r"""Figure 6's fourth order: the printed J4A along :math:`a_1 + n_1\sqrt{8/\pi}
    \sigma_v = a_{1eq}` (``j2``'s), :math:`a_1, n_1 \ge 0`, on ``LINE_POINTS`` points."""
    a1eq = j2["a1eq"]
    if not (math.isfinite(a1eq) and a1eq > 0):
        return {}
    n1 = np.linspace(0.0, a1eq / (SQRT_8_PI * sigma_v), LINE_POINTS)
    a1 = a1eq - n1 * SQRT_8_PI * sigma_v
    theta = {**j2, "a1": a1eq, "n1": 0.0}
    costs = PrintedCosts(record_state(record, block_seconds), theta, omega_max=omega_max)
    i = int(np.argmin(costs.j4a(a1, n1)))
    return {
        **{k: j2[k] for k in ("a2", "n2", "S0")},
        "a1": float(a1[i]),
        "n1": float(n1[i]),
        "a1eq": a1eq,
    }


def _monomials(a, n):
    return np.stack([a**i * n**j for i in range(5) for j in range(5 - i)], axis=-1)


class PrintedCosts:
    """The printed J2 and J4A (module docstring) as functions of :math:`(a_1, n_1)` with
    ``a2, n2, S0`` at ``theta``; the velocity restoration at ``theta``.
    """

    def __init__(
        self,
        record,
        theta: Mapping[str, float],
        *,
        omega_max: float = OMEGA_MAX,
        block_seconds: float = BLOCK_SECONDS,
    ):
        model = Model.from_spec("paper")
        state = record_state(record, block_seconds)
        L, win = state.layout, state.window
        self.k2, self.S0 = win.k2, float(theta["S0"])
        th = np.array([theta[p] for p in model.param_names], dtype=float)
        s2, _ = restoration(state, model, th)
        a2, n2, T = theta["a2"], theta["n2"], L.T

        def features(bins):  # (Z, v, v|v|) with Z = a + a2 x + n2 x^3 fixed
            Y = feature_ffts(state, model, s2, bins)
            return np.stack([Y[0] + a2 * Y[3] + n2 * Y[4], Y[1], Y[2]])

        F = features(L.bins(0.0, omega_max, k_min=1))
        self.R = np.einsum("ibk,jbk->kij", F, F.conj()).real / (F.shape[1] * 2 * math.pi * T)
        k_max = math.floor(omega_max / L.d_omega + 1e-9)
        dom = trispectral_domain(k_max, "principal")
        Ft = features(np.arange(k_max + 1))
        self._Ys = np.ascontiguousarray(np.concatenate([np.conj(Ft[:, :, :0:-1]), Ft], axis=2))
        self._idx = np.ascontiguousarray(dom + k_max, dtype=np.int64)
        self._c8 = 8 * math.pi**3 * T
        self.W = self.S0**2 * sum(
            win.delta_bins(dom[:, i] + dom[:, j], L.M, T) for i, j in ((0, 1), (0, 2), (1, 2))
        )
        self._coef = None

    def j2(self, a1, n1) -> np.ndarray:
        r""":math:`J_2` at the points ``(a1, n1)`` (broadcast)."""
        a1, n1 = np.broadcast_arrays(np.asarray(a1, float), np.asarray(n1, float))
        lam = np.stack([np.ones_like(a1), a1, n1], axis=-1)
        Va = np.einsum("...i,kij,...j->...k", lam, self.R, lam)
        return np.sum((Va - self.k2 * self.S0) ** 2, axis=-1)

    def vb(self, a1: float, n1: float) -> np.ndarray:
        r""":math:`\hat V^b_t` at one point, straight from the block products."""
        lam = np.array([1.0, a1, n1])
        return products(self._Ys, self._idx, lam, self._c8)[0].mean(axis=0)

    def j4a(self, a1, n1) -> np.ndarray:
        r""":math:`J_{4A}` at the points ``(a1, n1)`` (broadcast): each ordinate a quartic
        in :math:`(a_1, n_1)`, interpolated exactly from 25 points of a 5 x 5 grid."""
        a1, n1 = np.broadcast_arrays(np.asarray(a1, float), np.asarray(n1, float))
        sa, sn = max(np.abs(a1).max(), 1.0), max(np.abs(n1).max(), 1e-3)
        nodes = np.linspace(-1.0, 1.0, 5)
        pa, pn = (g.ravel() for g in np.meshgrid(nodes, nodes, indexing="ij"))
        Vb = np.stack([self.vb(a * sa, n * sn) for a, n in zip(pa, pn, strict=True)])
        coef, *_ = np.linalg.lstsq(_monomials(pa, pn), Vb, rcond=None)
        mono = _monomials(a1 / sa, n1 / sn).reshape(-1, coef.shape[0])
        out = np.empty(mono.shape[0])
        for s in range(0, mono.shape[0], 256):  # (256, n_t) complex at a time
            out[s : s + 256] = np.sum(np.abs(mono[s : s + 256] @ coef - self.W) ** 2, axis=-1)
        return out.reshape(a1.shape)

    def direct_j4a(self, a1: float, n1: float) -> float:
        r""":math:`J_{4A}` at one point from the block products (the oracle of
        :meth:`j4a`'s interpolation)."""
        return float(np.sum(np.abs(self.vb(a1, n1) - self.W) ** 2))


def cost_maps(
    record,
    theta: Mapping[str, float],
    a1: np.ndarray,
    n1: np.ndarray,
    *,
    omega_max: float = OMEGA_MAX,
) -> dict[str, np.ndarray]:
    """The printed J2 and J4A over the grid ``a1 x n1``, ``(a1.size, n1.size)`` each."""
    costs = PrintedCosts(record, theta, omega_max=omega_max)
    A, N = np.meshgrid(np.asarray(a1, float), np.asarray(n1, float), indexing="ij")
    return {"a1": A[:, 0], "n1": N[0], "J2": costs.j2(A, N), "J4A": costs.j4a(A, N)}
