r"""Estimators: moments, energy balance, J2, J4 (along the eq-65 line and jointly).

The paper's protocol (section 7): stiffness by moments, the equivalent linear
damping and :math:`S_0` by J2, then the split of :math:`a_1` and :math:`n_1` by
J4 along the line of constant equivalent damping (eq 65)

.. math:: a_{1eq} = a_1 + n_1\sqrt{8/\pi}\,\sigma_{\dot x}.

Moment method (stationary Ito identities, NOTES.md): multiplying the equation of
motion by :math:`x` and :math:`x^3` and taking expectations,

.. math::

    E[\dot x^2] = a_2 E[x^2] + n_2 E[x^4] + E[x h(\dot x)], \qquad
    3E[x^2\dot x^2] = a_2 E[x^4] + n_2 E[x^6] + E[x^3 h(\dot x)],

where the damping terms vanish for a stationary density even in :math:`\dot x`
and are neglected.  Energy balance (exact for white noise):
:math:`a_1 E[\dot x^2] + n_1 E|\dot x|^3 = \pi S_0`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import optimize

from . import costs as C
from .errors import HosidInputError
from .records import Record
from .spectra import block_spectra, derivatives

__all__ = [
    "METHODS",
    "SQRT_8_PI",
    "Settings",
    "energy_balance_S0",
    "estimate",
    "fit_J2",
    "fit_J4_joint",
    "fit_J4_line",
    "moments",
]

SQRT_8_PI = math.sqrt(8.0 / math.pi)  # eq (65), misprinted as 8/pi
METHODS = ("moments", "J2", "J4A", "J4B", "paper")


@dataclass(frozen=True)
class Settings:
    """Spectral settings shared by the estimators."""

    window: str = "hann"
    block_seconds: float = 20.48
    omega_max: float = 8.0
    domain: str = "principal"
    form: str = "scaled"  # "scaled" (well-scaled, bias-corrected) or "literal" (as printed)
    derivative: str = "spectral"

    def as_dict(self) -> dict:
        """Settings as a plain dict (for JSON)."""
        return dict(self.__dict__)


def velocity_tail(record: Record, derivative: str = "spectral") -> float:
    r"""Velocity variance lost above the Nyquist frequency :math:`\omega_N`.

    Far above resonance the velocity spectrum is :math:`S_0/\omega^2`, so the
    sampled record misses :math:`2\int_{\omega_N}^\infty S_0\omega^{-2}d\omega =
    2 S_0/\omega_N`.  :math:`S_0` is read from the displacement spectrum on
    :math:`[0.2, 0.5]\,\omega_N` as :math:`\omega^4 S_x (1 - \omega_e^2/\omega^2)^2`
    (median over bins, divided by ln 2), :math:`\omega_e^2 = E[\dot x^2]/E[x^2]`.
    Measurement noise inflates it; pass ``tail_correction=False`` then.
    """
    x = record.x - np.mean(record.x)
    n = x.size
    w = np.hanning(n)
    F = np.fft.rfft(x * w)
    om = 2 * np.pi * np.fft.rfftfreq(n, record.dt)
    Sx = np.abs(F) ** 2 * record.dt / (2 * np.pi * n * np.mean(w**2))
    wN = np.pi / record.dt
    sel = (om > 0.2 * wN) & (om < 0.5 * wN)
    v, _ = derivatives(x, record.dt, derivative)
    we2 = np.mean(v**2) / np.mean(x**2)
    S0_hf = np.median(om[sel] ** 4 * Sx[sel] * (1 - we2 / om[sel] ** 2) ** 2) / math.log(2)
    return float(2.0 * S0_hf / wN)


def moments(
    record: Record,
    *,
    damping: tuple[float, float] | None = None,
    derivative: str = "spectral",
    tail_correction: bool = True,
    velocity: np.ndarray | None = None,
    tail: float | None = None,
) -> dict:
    """Stiffness (a2, n2) from the two stationary moment identities (module doc).

    Parameters
    ----------
    damping : (a1, n1), optional
        When given, the damping terms :math:`E[x h]` and :math:`E[x^3 h]` are kept
        (measured from the record); they are not zero (the stationary density is
        not even in the velocity) and bias a2 by about -5 % at S0 = 100 if dropped.
    tail_correction : bool
        Add the velocity variance lost above Nyquist (:func:`velocity_tail`).
    velocity, tail : optional
        The record's velocity and tail variance when already computed (the
        protocol calls this function repeatedly on the same record).
    """
    x = record.x - np.mean(record.x)
    v = derivatives(x, record.dt, derivative)[0] if velocity is None else velocity
    if tail is None:
        tail = velocity_tail(record, derivative) if tail_correction else 0.0
    v2 = v**2 + tail
    m2, m4, m6 = (np.mean(x**p) for p in (2, 4, 6))
    A = np.array([[m2, m4], [m4, m6]])
    b = np.array([np.mean(v2), 3.0 * np.mean(x**2 * v2)])
    if damping is not None:
        a1, n1 = damping
        h = a1 * v + n1 * v * np.abs(v)
        b -= np.array([np.mean(x * h), np.mean(x**3 * h)])
    a2, n2 = np.linalg.solve(A, b)
    return {
        "a2": float(a2),
        "n2": float(n2),
        "sigma_v": float(np.sqrt(np.mean(v2))),
        "Ev2": float(np.mean(v2)),
        "Ev3": float(np.mean(np.abs(v) ** 3)),
    }


def energy_balance_S0(a1: float, n1: float, Ev2: float, Ev3: float) -> float:
    """S0 from a1 E[v^2] + n1 E|v|^3 = pi S0."""
    return (a1 * Ev2 + n1 * Ev3) / math.pi


def _cost_names(form: str) -> tuple[str, str, str]:
    if form == "scaled":
        return "J2W", "J4AW", "J4BW"
    if form == "literal":
        return "J2", "J4A", "J4B"
    raise HosidInputError(f"unknown cost form {form!r}: use 'scaled' or 'literal'")


def fit_J2(
    data: C.CostData,
    *,
    sigma_v: float,
    stiffness: tuple[float, float] | None = None,
    form: str = "scaled",
    x0: dict | None = None,
) -> dict:
    """Equivalent linear damping and S0 (and the stiffness unless given) by J2.

    J2 cannot split a1 from n1 (its valley runs along constant a1eq, eq 65), so the
    search is a global grid over a1eq with linear damping, then a bounded local
    polish over (a1, n1 >= 0, S0[, a2, n2]); ``a1eq = a1 + n1 sqrt(8/pi) sigma_v``
    is the reported, well-determined combination.
    """
    j2 = C.COSTS[_cost_names(form)[0]]
    x0 = x0 or {}
    c = SQRT_8_PI * sigma_v
    free_k = stiffness is None
    k0 = (x0.get("a2", 25.0), x0.get("n2", 0.0)) if free_k else stiffness

    def theta(p):
        p = np.atleast_2d(p)
        a2 = p[:, 3] if free_k else np.full(p.shape[0], k0[0])
        n2 = p[:, 4] if free_k else np.full(p.shape[0], k0[1])
        return np.stack([p[:, 0], p[:, 1], a2, n2, np.exp(p[:, 2])], -1)

    # global: a1eq grid with n1 = 0, S0 from the mean inferred-force level
    grid = np.linspace(0.05, 40.0, 160)
    th = np.stack(
        [grid, 0 * grid, np.full_like(grid, k0[0]), np.full_like(grid, k0[1]), np.ones_like(grid)],
        -1,
    )
    S0g = np.mean(data.second_order(th), axis=-1) / data.k2
    P = np.column_stack(
        [grid, 0 * grid, np.log(S0g)]
        + ([np.full_like(grid, k0[0]), np.full_like(grid, k0[1])] if free_k else [])
    )
    best = P[np.argmin(j2(theta(P), data))]
    a1eq0 = best[0]
    bounds = [(0.0, a1eq0 * 2), (0.0, 2 * a1eq0 / c), (best[2] - 2, best[2] + 2)]
    if free_k:
        bounds += [(None, None), (None, None)]
    res = optimize.minimize(
        lambda p: float(j2(theta(p), data)[0]),
        best,
        method="Powell",
        bounds=bounds,
        options={"xtol": 1e-6, "ftol": 1e-10, "maxfev": 20000},
    )
    t = theta(res.x)[0]
    return {
        "a1": float(t[0]),
        "n1": float(t[1]),
        "a1eq": float(t[0] + t[1] * c),
        "a2": float(t[2]),
        "n2": float(t[3]),
        "S0": float(t[4]),
        "cost": float(res.fun),
    }


def fit_J4_line(
    data: C.CostData,
    *,
    a1eq: float,
    sigma_v: float,
    a2: float,
    n2: float,
    S0: float,
    cost: str = "J4AW",
    n_grid: int = 81,
) -> dict:
    """The paper's J4 step: minimize J4 along a1 + n1 sqrt(8/pi) sigma_v = a1eq, n1 >= 0, a1 >= 0.

    A grid over the whole admissible segment (global: J4 has valleys and twin
    minima) is followed by a bounded scalar refinement around the best point.
    """
    f = C.COSTS[cost]
    c = SQRT_8_PI * sigma_v
    n1_max = a1eq / c

    def theta(n1):
        n1 = np.atleast_1d(n1)
        a1 = a1eq - n1 * c
        return np.stack(
            [a1, n1, np.full_like(n1, a2), np.full_like(n1, n2), np.full_like(n1, S0)], -1
        )

    grid = np.linspace(0.0, n1_max, n_grid)
    vals = f(theta(grid), data)
    i = int(np.argmin(vals))
    lo, hi = grid[max(i - 1, 0)], grid[min(i + 1, n_grid - 1)]
    res = optimize.minimize_scalar(
        lambda n: float(f(theta(n), data)[0]),
        bounds=(lo, hi),
        method="bounded",
        options={"xatol": 1e-5},
    )
    n1 = float(res.x)
    return {"a1": float(a1eq - n1 * c), "n1": n1, "cost": float(res.fun), "profile": (grid, vals)}


def fit_J4_joint(
    data: C.CostData,
    start: dict,
    *,
    sigma_v: float,
    cost: str = "J4AW",
    with_J2: str | None = "J2W",
    fix_S0: bool = False,
    n_starts: int = 7,
) -> dict:
    """Joint fit of the damping (and S0) by J4, plus J2 when ``with_J2`` (eq 15).

    The stiffness is held at ``start`` (moments are far more accurate for it than
    either spectral cost; a free stiffness trades off against the damping).  The
    search is global along the eq-65 line (``n_starts`` starts from a1 = a1eq to
    n1 = a1eq / (sqrt(8/pi) sigma_v)) with a bounded Powell polish from each, in the
    admissible region a1, n1 >= 0 (which keeps a1eq > 0, the physical twin).
    """
    f4 = C.COSTS[cost]
    f2 = C.COSTS[with_J2] if with_J2 else None
    c = SQRT_8_PI * sigma_v
    a1eq = start["a1"] + start["n1"] * c
    logS0 = math.log(start["S0"])

    def theta(p):
        p = np.atleast_2d(p)
        s0 = np.full(p.shape[0], start["S0"]) if fix_S0 else np.exp(p[:, 2])
        return np.column_stack(
            [
                p[:, 0],
                p[:, 1],
                np.full(p.shape[0], start["a2"]),
                np.full(p.shape[0], start["n2"]),
                s0,
            ]
        )

    def J(p):
        th = theta(p)
        val = f4(th, data)
        if f2 is not None:
            val = val + f2(th, data)
        return float(val[0])

    bounds = [(0.0, 2 * a1eq), (0.0, 2 * a1eq / c)] + ([] if fix_S0 else [(logS0 - 1, logS0 + 1)])
    best = None
    for n1 in np.linspace(0.0, a1eq / c, n_starts):
        p0 = [max(a1eq - n1 * c, 0.0), n1] + ([] if fix_S0 else [logS0])
        res = optimize.minimize(
            J,
            p0,
            method="Powell",
            bounds=bounds,
            options={"xtol": 1e-4, "ftol": 1e-8, "maxfev": 2000},
        )
        if best is None or res.fun < best.fun:
            best = res
    th = theta(best.x)[0]
    return dict(zip(C.PARAM_NAMES, map(float, th), strict=False), cost=float(best.fun))


def estimate(
    record: Record,
    *,
    method: str = "paper",
    window: str = "hann",
    block_seconds: float = 20.48,
    omega_max: float = 8.0,
    domain: str = "principal",
    form: str = "scaled",
    derivative: str = "spectral",
    refine: bool = True,
) -> dict:
    """Estimate the oscillator's parameters from a displacement record.

    Parameters
    ----------
    record : Record
    method : {"moments", "J2", "J4A", "J4B", "paper"}
        ``moments``: stiffness only (damping terms neglected).  ``J2``: equivalent
        damping, stiffness and S0 jointly by J2.  ``paper``: moments, then J2
        (a1eq, S0) with that stiffness, then J4 along the a1eq line; with
        ``refine`` the moments are redone with the damping terms kept and J2/J4
        repeated once.  ``J4B``: the protocol with J4B on the line (J4B is blind
        to the level, so it cannot leave the line).  ``J4A``: the protocol followed
        by a joint fit of (a1, n1, S0) by J4A together with J2 (eq 15), stiffness
        held at the refined moment estimate.
    window, block_seconds, omega_max, domain, form, derivative
        Spectral settings; ``form="literal"`` uses the costs exactly as printed.

    Returns
    -------
    dict
        ``{"method", "estimates": {a1, n1, a2, n2, S0, a1eq}, "settings"}``;
        parameters a method does not estimate are NaN.
    """
    if method not in METHODS:
        raise HosidInputError(f"unknown method {method!r}: choose from {', '.join(METHODS)}")
    settings = Settings(window, float(block_seconds), float(omega_max), domain, form, derivative)
    nan = float("nan")
    est = dict.fromkeys(("a1", "n1", "a2", "n2", "S0", "a1eq"), nan)
    v = derivatives(record.x - np.mean(record.x), record.dt, derivative)[0]
    tail = velocity_tail(record, derivative)
    mom = moments(record, derivative=derivative, velocity=v, tail=tail)
    out = {"method": method, "estimates": est, "settings": settings.as_dict()}
    if method == "moments":
        est.update(a2=mom["a2"], n2=mom["n2"])
        return out
    sp = block_spectra(
        record,
        window=window,
        block_seconds=block_seconds,
        omega_max=omega_max,
        derivative=derivative,
    )
    data = C.prepare(sp, domain)
    j2name, j4a, j4b = _cost_names(form)
    sv = mom["sigma_v"]
    if method == "J2":
        r2 = fit_J2(data, sigma_v=sv, form=form, x0={"a2": mom["a2"], "n2": mom["n2"]})
        est.update(a1eq=r2["a1eq"], a2=r2["a2"], n2=r2["n2"], S0=r2["S0"])
        return out
    j4 = j4b if method == "J4B" else j4a
    for _ in range(2 if refine else 1):
        r2 = fit_J2(data, sigma_v=sv, stiffness=(mom["a2"], mom["n2"]), form=form)
        line = fit_J4_line(
            data, a1eq=r2["a1eq"], sigma_v=sv, a2=mom["a2"], n2=mom["n2"], S0=r2["S0"], cost=j4
        )
        est.update(
            a1=line["a1"], n1=line["n1"], a2=mom["a2"], n2=mom["n2"], S0=r2["S0"], a1eq=r2["a1eq"]
        )
        mom = moments(record, damping=(line["a1"], line["n1"]), velocity=v, tail=tail)
    if method == "paper":
        return out
    if method == "J4B":
        # J4B is blind to the force level and to a1eq: the eq-65 line supplies both
        return out
    start = {k: est[k] for k in C.PARAM_NAMES}
    j = fit_J4_joint(data, start, sigma_v=sv, cost=j4a, with_J2=j2name)
    est.update({k: j[k] for k in C.PARAM_NAMES})
    est["a1eq"] = est["a1"] + est["n1"] * SQRT_8_PI * sv
    return out
