r"""Simulation of the randomly excited oscillator (paper section 7.4).

The equation of motion is assembled from a fixed library of drift terms,

.. math::

    \ddot x + a_1 \dot x + n_1 \dot x|\dot x| + a_2 x + n_2 x^3
    + b_2 x^2 + \mu\,\mathrm{sign}(\dot x) = g(t) + m,

driven by a force ``g`` that is Gaussian white noise of two-sided level
:math:`S_0` (:math:`R_f(\tau) = 2\pi S_0\,\delta(\tau)`, eq 42-43) or, with a
corner frequency :math:`\omega_c > 0`, white noise passed through the first-order
low-pass :math:`\dot g = \omega_c (w - g)`.  Terms whose coefficient is zero cost
nothing, so adding an effect is setting its coefficient.  A user drift (a
``numba.njit`` function ``drift(x, v, coeffs) -> float`` returning the extra
restoring/damping force) can be plugged in through ``extra_drift``.

The scheme is the paper's: fourth-order Runge-Kutta with the noise held constant
over each (sub)step, as in Roberts and Spanos.  A sub-step :math:`h = dt/m` draws
:math:`w_k \sim N(0, 2\pi S_0 / h)`.  Records start at rest and are recorded after
a burn-in.  Measurement noise (white, standard deviation ``noise_sd``) is added to
the sampled displacement only.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping

import numba
import numpy as np

from .records import Record

__all__ = ["PAPER_PARAMS", "TERM_ORDER", "simulate", "simulate_ensemble"]

#: Paper parameter values (section 7.4) with the Figure 6-8 excitation level.
PAPER_PARAMS: dict[str, float] = {"a1": 0.5, "n1": 0.5, "a2": 25.0, "n2": 5.0, "S0": 100.0}

#: Order of the drift coefficients passed to the compiled kernel.
TERM_ORDER = ("a1", "n1", "a2", "n2", "b2", "mu", "m")


@numba.njit(cache=True, inline="always")
def _accel(x, v, g, c):
    a = g + c[6]
    a -= c[0] * v + c[1] * v * abs(v) + c[2] * x + c[3] * x * x * x
    if c[4] != 0.0:
        a -= c[4] * x * x
    if c[5] != 0.0:
        a -= c[5] * np.sign(v)
    return a


@numba.njit(cache=True)
def _no_drift(x, v, c):  # pragma: no cover - compiled
    return 0.0


@numba.njit(inline="always")
def _rk4(x, v, g, wk, h, c, wc, extra):  # pragma: no cover - compiled
    """One RK4 sub-step with the forcing held at ``wk``; returns the new (x, v, g)."""
    if wc > 0.0:
        # state (x, v, g): g' = wc (w - g)
        k1x = v
        k1v = _accel(x, v, g, c) - extra(x, v, c)
        k1g = wc * (wk - g)
        x2, v2, g2 = x + 0.5 * h * k1x, v + 0.5 * h * k1v, g + 0.5 * h * k1g
        k2x = v2
        k2v = _accel(x2, v2, g2, c) - extra(x2, v2, c)
        k2g = wc * (wk - g2)
        x3, v3, g3 = x + 0.5 * h * k2x, v + 0.5 * h * k2v, g + 0.5 * h * k2g
        k3x = v3
        k3v = _accel(x3, v3, g3, c) - extra(x3, v3, c)
        k3g = wc * (wk - g3)
        x4, v4, g4 = x + h * k3x, v + h * k3v, g + h * k3g
        k4x = v4
        k4v = _accel(x4, v4, g4, c) - extra(x4, v4, c)
        k4g = wc * (wk - g4)
        g += h / 6.0 * (k1g + 2.0 * k2g + 2.0 * k3g + k4g)
    else:
        k1x = v
        k1v = _accel(x, v, wk, c) - extra(x, v, c)
        x2, v2 = x + 0.5 * h * k1x, v + 0.5 * h * k1v
        k2x = v2
        k2v = _accel(x2, v2, wk, c) - extra(x2, v2, c)
        x3, v3 = x + 0.5 * h * k2x, v + 0.5 * h * k2v
        k3x = v3
        k3v = _accel(x3, v3, wk, c) - extra(x3, v3, c)
        x4, v4 = x + h * k3x, v + h * k3v
        k4x = v4
        k4v = _accel(x4, v4, wk, c) - extra(x4, v4, c)
    x += h / 6.0 * (k1x + 2.0 * k2x + 2.0 * k3x + k4x)
    v += h / 6.0 * (k1v + 2.0 * k2v + 2.0 * k3v + k4v)
    return x, v, g


@numba.njit(cache=True)
def _integrate(w, n_out, sub, h, c, wc, burn, xs, vs, x0, v0, g0):  # pragma: no cover
    """RK4 with piecewise-constant forcing ``w`` (one value per sub-step), built-in
    terms only.  Cached on disk: its signature holds no function type (a
    function-typed argument made numba's cache index fail to pickle and crash
    concurrent processes).
    """
    x, v, g = x0, v0, g0
    k = 0
    for i in range(burn + n_out):
        for _ in range(sub):
            x, v, g = _rk4(x, v, g, w[k], h, c, wc, _no_drift)
            k += 1
        if i >= burn:
            xs[i - burn] = x
            vs[i - burn] = v
    return x, v, g


@numba.njit
def _integrate_extra(w, n_out, sub, h, c, wc, burn, extra, xs, vs, x0, v0, g0):  # pragma: no cover
    """As :func:`_integrate` with a user drift ``extra`` (compiled per process).

    The loop is repeated rather than shared: a cached :func:`_integrate` that calls
    this function with the global ``_no_drift`` cannot be cached by numba
    ("dynamic globals"), and a function-typed argument breaks its cache index.
    """
    x, v, g = x0, v0, g0
    k = 0
    for i in range(burn + n_out):
        for _ in range(sub):
            x, v, g = _rk4(x, v, g, w[k], h, c, wc, extra)
            k += 1
        if i >= burn:
            xs[i - burn] = x
            vs[i - burn] = v
    return x, v, g


def _coefficients(params: Mapping[str, float]) -> np.ndarray:
    unknown = set(params) - set(TERM_ORDER) - {"S0", "wc", "noise_sd"}
    if unknown:
        raise ValueError(f"unknown simulation parameter(s): {sorted(unknown)}")
    return np.array([float(params.get(k, 0.0)) for k in TERM_ORDER])


def simulate(
    params: Mapping[str, float],
    *,
    duration: float = 2000.0,
    dt: float = 0.02,
    rng: np.random.Generator,
    substeps: int = 4,
    burn_in: float = 60.0,
    extra_drift: Callable | None = None,
    name: str = "",
    return_velocity: bool = False,
) -> Record | tuple[Record, np.ndarray]:
    r"""Simulate one stationary displacement record.

    Parameters
    ----------
    params : mapping
        Coefficients by name: ``a1, n1, a2, n2`` (eq 40), optional ``b2``
        (quadratic stiffness), ``mu`` (Coulomb friction), ``m`` (mean force),
        ``wc`` (low-pass corner of coloured excitation, 0 = white), ``noise_sd``
        (measurement noise) and the excitation level ``S0`` (two-sided,
        :math:`D^2 = 2\pi S_0`, eq 42-43).
    duration, dt : float
        Record length and sampling interval in seconds.
    rng : numpy.random.Generator
        The only source of randomness.
    substeps : int
        RK4 steps per sample; the white noise is held over each sub-step.
    burn_in : float
        Seconds simulated from rest and discarded.
    extra_drift : numba-compiled callable, optional
        ``extra_drift(x, v, coeffs)``, an additional force moved to the left-hand side.
    return_velocity : bool
        Also return the simulated velocity at the sampling instants (for tests).

    Returns
    -------
    Record
    """
    if not isinstance(rng, np.random.Generator):
        raise TypeError("rng must be a numpy.random.Generator")
    S0 = float(params.get("S0", 0.0))
    if not (np.isfinite(S0) and S0 >= 0):
        raise ValueError("S0 must be finite and non-negative")
    if not (dt > 0 and duration > 0 and np.isfinite(dt) and np.isfinite(duration)):
        raise ValueError("dt and duration must be positive")
    if int(substeps) < 1:
        raise ValueError("substeps must be >= 1")
    c = _coefficients(params)
    wc = float(params.get("wc", 0.0) or 0.0)
    n_out = round(duration / dt)
    burn = round(burn_in / dt)
    sub = int(substeps)
    h = dt / sub
    w = rng.standard_normal((burn + n_out) * sub)
    w *= np.sqrt(2.0 * np.pi * S0 / h)
    xs = np.empty(n_out)
    vs = np.empty(n_out)
    if extra_drift is None:
        _integrate(w, n_out, sub, h, c, wc, burn, xs, vs, 0.0, 0.0, 0.0)
    else:
        _integrate_extra(w, n_out, sub, h, c, wc, burn, extra_drift, xs, vs, 0.0, 0.0, 0.0)
    noise_sd = float(params.get("noise_sd", 0.0) or 0.0)
    if noise_sd > 0:
        xs += noise_sd * rng.standard_normal(n_out)
    record = Record(x=xs, dt=float(dt), name=name)
    return (record, vs) if return_velocity else record


def simulate_ensemble(
    params: Mapping[str, float],
    n_records: int,
    *,
    rng: np.random.Generator,
    **kwargs,
) -> list[Record]:
    """Independent records, each from its own child generator (``rng.spawn``)."""
    return [
        simulate(params, rng=child, name=f"record-{i}", **kwargs)
        for i, child in enumerate(rng.spawn(int(n_records)))
    ]
