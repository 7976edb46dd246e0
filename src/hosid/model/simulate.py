r"""Simulation of the randomly excited oscillator (paper section 7.4).

The equation of motion is assembled from the drift library,

.. math::

    \ddot x + a_1\dot x + n_1\dot x|\dot x| + a_2x + n_2x^3 + b_2x^2
    + \mu\,\mathrm{sign}(\dot x) = g(t) + m,

driven by a force :math:`g` that is Gaussian white noise of two-sided level :math:`S_0`
(:math:`R_g(\tau) = 2\pi S_0\,\delta(\tau)`, eqs 42-43) or, with a corner
:math:`\omega_c > 0`, white noise through the low-pass :math:`\dot g = \omega_c(w - g)`.
With a band edge :math:`\omega_b > 0` the force is Gaussian with the spectrum
:math:`S_0L(\omega)\mathbf 1\{|\omega| \le \omega_b\}/(1 + \beta\omega^2/\omega_b^2)`
(the low-pass's :math:`L`, or 1; :math:`\beta` the band's ``rolloff``, default 0):
white noise on the sub-step grid shaped once by an FFT of the whole run, then integrated
as a smooth input (Heun with the force at both ends of a sub-step).  A second-order
shaping filter (``wf``, ``zf``: :math:`S_0\omega_f^4/[(\omega_f^2 - \omega^2)^2 +
(2\zeta_f\omega_f\omega)^2]`, a narrow-band wave moment) is made the same way, on 40
sub-steps a sample.  Poisson impulses (``rate`` a second, Gaussian areas of variance
:math:`2\pi S_0/r`: the same white spectrum, not Gaussian) replace the white force's
increments on 40 sub-steps a sample: a sub-step's increment is the sum of its impulses'
areas, and the displacement's share :math:`\sum_iA_i(h - s_i)` is Heun's half of it plus
:math:`\sum_iA_i(h/2 - s_i)` (impulse times :math:`s_i` uniform in the sub-step).
Measurement noise (white, standard deviation ``noise_sd``) is added to the sampled
displacement only.

The scheme is the stochastic Heun method (an Itô-Taylor predictor-corrector, weak
order 2 for additive noise) with Brownian increments
:math:`\Delta W \sim N(0, h)` on ``substeps`` sub-steps per sample.  A white force
reaches the displacement over a sub-step as :math:`\int_0^h(h - s)\,dW(s)`, which is
Heun's :math:`h\Delta W/2` plus an independent part of variance :math:`h^3/12` (times
:math:`2\pi S_0`); the scheme adds it (one more normal a sub-step, drawn after the
increments).  Without it the sampled spectrum's top falls as if the force were coloured
by :math:`1/\omega_c^2 = h^2/12` (0.7 Cramer-Rao sd of the corner at the paper's point
with 10 sub-steps; ``tests/test_simulate.py``).  It keeps the force
white far above the Nyquist frequency, which is what a record of the model shows: the
paper's scheme, fourth-order Runge-Kutta with the noise held over each step, colours
the force (a zero-order hold is a low-pass filter, :math:`\mathrm{sinc}^2(\omega h/2)`)
and biases the damping split by more than the Cramer-Rao standard deviation.
Records start at rest and are recorded after a burn-in of at least 30 decay times of
the equivalent linear damping.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np
from scipy import fft

from .._jit import njit
from ..errors import HosidInputError
from ..record import Record
from ..screen import THRESHOLDS
from .change import Change, blend, switch

__all__ = [
    "PAPER_PARAMS",
    "SIM_KEYS",
    "band_limited_force",
    "equivalent_rate",
    "narrowband_shape",
    "poisson_impulses",
    "shaped_force",
    "simulate",
    "simulate_ensemble",
]

#: Paper parameter values (section 7.4) with the Figure 6-8 excitation level.
PAPER_PARAMS: dict[str, float] = {"a1": 0.5, "n1": 0.5, "a2": 25.0, "n2": 5.0, "S0": 100.0}

#: Drift coefficients in the order of the compiled kernel, then the other keys.
_DRIFT_KEYS = ("a1", "n1", "a2", "n2", "b2", "mu", "m")
SIM_KEYS = (*_DRIFT_KEYS, "S0", "wc", "wb", "rolloff", "wf", "zf", "rate", "noise_sd")


@njit(cache=True, inline="always")
def _accel(x, v, g, c):  # pragma: no cover - compiled
    a = g + c[6] - (c[0] * v + c[1] * v * abs(v) + c[2] * x + c[3] * x * x * x)
    if c[4] != 0.0:
        a -= c[4] * x * x
    if c[5] != 0.0:
        a -= c[5] * np.sign(v)
    return a


@njit(cache=True)
def _heun(dW, dZ, n_out, sub, h, c, wc, burn, xs, vs, sw):  # pragma: no cover - compiled
    """Stochastic Heun on (x, v) or, with ``wc > 0``, on (x, v, g); ``dZ`` is the part
    of the white force's double integral that ``dW`` does not hold (module docstring);
    ``sw`` a change of the parameters (:func:`hosid.model.change.switch`).
    """
    cc, s, k0, k1 = c.copy(), 1.0, round(sw[2] * sub), round(sw[3] * sub)
    x = 0.0
    v = 0.0
    g = 0.0
    k = 0
    for i in range(burn + n_out):
        for _ in range(sub):
            if k0 <= k <= k1:
                s = blend(k, k0, k1, c, sw, cc)
            w = dW[k] * s
            k += 1
            if wc > 0.0:
                a0 = _accel(x, v, g, cc)
                g0 = -wc * g
                xp = x + h * v
                vp = v + h * a0
                gp = g + h * g0 + wc * w
                a1 = _accel(xp, vp, gp, cc)
                x += 0.5 * h * (v + vp)
                v += 0.5 * h * (a0 + a1)
                g += 0.5 * h * (g0 - wc * gp) + wc * w
            else:
                a0 = _accel(x, v, 0.0, cc)
                xp = x + h * v
                vp = v + h * a0 + w
                a1 = _accel(xp, vp, 0.0, cc)
                x += 0.5 * h * (v + vp) + dZ[k - 1] * s
                v += 0.5 * h * (a0 + a1) + w
        if i >= burn:
            xs[i - burn] = x
            vs[i - burn] = v


@njit(cache=True)
def _heun_forced(f, n_out, sub, h, c, burn, xs, vs, sw):  # pragma: no cover - compiled
    """Heun on (x, v) driven by the smooth force ``f`` given on the sub-step grid."""
    cc, s, k0, k1 = c.copy(), 1.0, round(sw[2] * sub), round(sw[3] * sub)
    x = 0.0
    v = 0.0
    k = 0
    for i in range(burn + n_out):
        for _ in range(sub):
            if k0 <= k <= k1:
                s = blend(k, k0, k1, c, sw, cc)
            a0 = _accel(x, v, f[k] * s, cc)
            xp = x + h * v
            vp = v + h * a0
            a1 = _accel(xp, vp, f[k + 1] * s, cc)
            x += 0.5 * h * (v + vp)
            v += 0.5 * h * (a0 + a1)
            k += 1
        if i >= burn:
            xs[i - burn] = x
            vs[i - burn] = v


def shaped_force(n: int, h: float, S0: float, shape, rng: np.random.Generator) -> np.ndarray:
    r"""``n`` samples at step ``h`` of a stationary Gaussian force of two-sided spectrum
    :math:`S_0L(\omega)` (``shape`` is :math:`L`, a function of an array of frequencies):
    white noise on the grid shaped once by an FFT of the whole run (scipy's: 0.55 s against
    numpy's 1.8 s at an awkward length, 1 624 001 = 103 x 15 767; equal to 1e-15).
    """
    w = rng.standard_normal(n) * math.sqrt(2.0 * math.pi * S0 / h)
    omega = 2.0 * math.pi * np.fft.rfftfreq(n, h)
    return fft.irfft(fft.rfft(w) * np.sqrt(shape(omega)), n)


def band_limited_force(
    n: int,
    h: float,
    S0: float,
    wb: float,
    wc: float,
    rng: np.random.Generator,
    rolloff: float = 0.0,
) -> np.ndarray:
    r"""``n`` samples at step ``h`` of a stationary Gaussian force of two-sided spectrum
    :math:`S_0L(\omega)\mathbf 1\{|\omega| \le \omega_b\}/(1 + \beta\omega^2/\omega_b^2)`
    (module docstring).
    """

    def shape(omega):
        low = wc**2 / (wc**2 + omega**2) if wc > 0 else 1.0
        return (omega <= wb) * low / (1.0 + rolloff * (omega / wb) ** 2)

    return shaped_force(n, h, S0, shape, rng)


def poisson_impulses(
    n: int, h: float, S0: float, rate: float, rng: np.random.Generator
) -> tuple[np.ndarray, np.ndarray]:
    """The velocity and displacement increments of ``n`` sub-steps of length ``h`` under
    Poisson impulses (module docstring): each sub-step's sum of areas and
    ``sum A_i (h/2 - s_i)``.
    """
    counts = rng.poisson(rate * h, n)
    which = np.repeat(np.arange(n), counts)
    areas = rng.standard_normal(which.size) * math.sqrt(2.0 * math.pi * S0 / rate)
    times = rng.uniform(0.0, h, which.size)
    dW = np.bincount(which, weights=areas, minlength=n)
    dZ = np.bincount(which, weights=areas * (0.5 * h - times), minlength=n)
    return dW, dZ


def narrowband_shape(wf: float, zf: float):
    r"""The shaping filter's :math:`L(\omega) = \omega_f^4/[(\omega_f^2 - \omega^2)^2 +
    (2\zeta_f\omega_f\omega)^2]` (:class:`hosid.model.excitation.NarrowbandExcitation`).
    """
    return lambda omega: wf**4 / ((wf**2 - omega**2) ** 2 + (2.0 * zf * wf * omega) ** 2)


def equivalent_rate(params: Mapping[str, float]) -> float:
    r"""Decay rate of the equivalent linear system, :math:`a_{1eq}` of eq (65) at the
    velocity scale that balances the input power
    (:math:`a_1\sigma^2 + n_1\sqrt{8/\pi}\sigma^3 + \mu\sqrt{2/\pi}\sigma = \pi S_0`).
    """
    a1, n1, mu = (float(params.get(k, 0.0)) for k in ("a1", "n1", "mu"))
    S0 = float(params.get("S0", 0.0))
    c8, c2 = math.sqrt(8 / math.pi), math.sqrt(2 / math.pi)
    lo, hi = 1e-12, 1e12
    for _ in range(200):  # bisection on the power balance
        s = math.sqrt(lo * hi)
        if a1 * s * s + n1 * c8 * s**3 + mu * c2 * s > math.pi * S0:
            hi = s
        else:
            lo = s
    s = math.sqrt(lo * hi)
    return a1 + n1 * c8 * s + mu * c2 / s


def _check(params: Mapping[str, float], duration: float, dt: float, substeps) -> None:
    unknown = set(params) - set(SIM_KEYS)
    if unknown:
        raise HosidInputError(
            f"unknown simulation parameter(s) {', '.join(sorted(unknown))}; "
            f"valid: {', '.join(SIM_KEYS)}"
        )
    values = {k: float(v) for k, v in params.items()}
    if not all(math.isfinite(v) for v in values.values()):
        raise HosidInputError("simulation parameters must be finite")
    if not (math.isfinite(dt) and dt > 0 and math.isfinite(duration) and duration > 0):
        raise HosidInputError("dt and duration must be finite and positive")
    if round(duration / dt) < 16:
        raise HosidInputError(
            f"duration {duration:g} s at dt {dt:g} s gives fewer than 16 samples"
        )
    if values.get("S0", 0.0) <= 0:
        raise HosidInputError("S0 must be positive")
    if not equivalent_rate(values) > 0:
        raise HosidInputError(
            "the oscillator needs damping: the equivalent linear damping a1 + n1 sqrt(8/pi) "
            "sigma_v (+ friction) must be positive for a stationary response"
        )
    if values.get("a2", 0.0) <= 0 and values.get("n2", 0.0) <= 0:
        raise HosidInputError("the oscillator needs a restoring force: a2 > 0 or n2 > 0")
    if substeps is not None and int(substeps) < 1:
        raise HosidInputError("substeps must be at least 1")
    wf, zf = values.get("wf", 0.0), values.get("zf", 0.0)
    if (wf > 0) != (zf > 0) or wf < 0 or zf < 0:
        raise HosidInputError("a shaping filter needs both wf > 0 and zf > 0")
    if wf > 0 and (values.get("wc", 0.0) > 0 or values.get("wb", 0.0) > 0):
        raise HosidInputError("a shaping filter (wf, zf) cannot be combined with wc or wb")
    rate = values.get("rate", 0.0)
    if rate < 0 or (rate > 0 and any(values.get(k, 0.0) > 0 for k in ("wc", "wb", "wf"))):
        raise HosidInputError(
            "the impulse rate must be >= 0, and impulses (a white spectrum) are not combined "
            "with wc, wb or wf"
        )
    w = natural_frequency(values)
    limit = float(THRESHOLDS["sampling"][1])  # where the record check fails omega_e / omega_N
    if w * dt / math.pi > limit:
        raise HosidInputError(
            f"dt = {dt:g} s is too coarse for this oscillator: its resonance near {w:.3g} "
            f"rad/s needs dt < {limit * math.pi / w:.3g} s (more than {2 / limit:.1f} samples "
            "a period)"
        )


def natural_frequency(params: Mapping[str, float]) -> float:
    r"""The equivalent natural frequency :math:`\sqrt{a_2 + 3n_2\sigma_x^2}` of the
    Gaussian-linearized oscillator, :math:`\sigma_x^2 = \pi S_0/(a_{1eq}k_{eq})`
    (fixed point), for the simulation's sampling check.
    """
    a2, n2 = float(params.get("a2", 0.0)), float(params.get("n2", 0.0))
    c = equivalent_rate(params)
    k = max(a2, 1e-12)
    for _ in range(100):
        var = math.pi * float(params.get("S0", 0.0)) / (c * k)
        k_new = max(a2 + 3.0 * n2 * var, 1e-12)
        if abs(k_new - k) <= 1e-10 * k:
            break
        k = k_new
    return math.sqrt(k)


def simulate(
    params: Mapping[str, float],
    *,
    duration: float = 2000.0,
    dt: float = 0.02,
    rng: np.random.Generator,
    substeps: int | None = None,
    burn_in: float | None = None,
    name: str = "",
    return_velocity: bool = False,
    change: Change | None = None,
) -> Record | tuple[Record, np.ndarray]:
    r"""Simulate one stationary displacement record.

    Parameters
    ----------
    params : mapping
        ``a1, n1, a2, n2`` (eq 40), optional ``b2, mu, m`` (drift), ``S0`` (two-sided
        level, :math:`D^2 = 2\pi S_0`), ``wc`` (low-pass corner, 0 or absent = white),
        ``wb`` (band edge of the force, 0 or absent = none) and ``rolloff`` (the band's
        roll-off), ``wf, zf`` (a second-order shaping filter), ``rate`` (Poisson impulses
        a second, 0 or absent = Gaussian) and ``noise_sd`` (measurement noise).
    duration, dt : float
        Record length and sampling interval (s).
    rng : numpy.random.Generator
        The only source of randomness.
    substeps : int, optional
        Heun steps per sample: 10, or 40 under a shaping filter (with 10, the
        ship-roll-like oscillator's cubic stiffness came out 3 % low, 11 sd of the
        estimates of 8 records, in the identities of the augmented state, which weigh the
        jerk).
    burn_in : float, optional
        Seconds simulated from rest and discarded; default the larger of 60 s and 30
        decay times :math:`30/a_{1eq}` (at most 20 000 s).
    return_velocity : bool
        Also return the simulated velocity at the sampling instants.
    change : hosid.model.change.Change, optional
        A step or ramp of the parameters during the record (:mod:`hosid.model.change`).

    Raises
    ------
    HosidInputError
        On unknown or non-finite parameters, impossible settings, or a response that
        escapes (the oscillator has no stationary state, or ``dt`` is too coarse), also
        after a ``change``, or a ``change`` outside the record.
    """
    if not isinstance(rng, np.random.Generator):
        raise TypeError("rng must be a numpy.random.Generator")
    _check(params, duration, dt, substeps)
    c = np.array([float(params.get(k, 0.0)) for k in _DRIFT_KEYS])
    S0 = float(params["S0"])
    wc = float(params.get("wc", 0.0) or 0.0)
    if burn_in is None:
        rate = equivalent_rate(params)
        burn_in = min(max(60.0, 30.0 / rate), 20000.0) if rate > 0 else 60.0
    n_out = round(duration / dt)
    burn = round(burn_in / dt)
    sub = int(substeps) if substeps else 10
    h = dt / sub
    xs = np.empty(n_out)
    vs = np.empty(n_out)
    sw = switch(change, params, duration=duration, dt=dt, substeps=substeps, burn=burn)
    wb = float(params.get("wb", 0.0) or 0.0)
    wf = float(params.get("wf", 0.0) or 0.0)
    if wf > 0:
        sub = int(substeps) if substeps else 40
        h = dt / sub
        shape = narrowband_shape(wf, float(params["zf"]))
        f = shaped_force((burn + n_out) * sub + 1, h, S0, shape, rng)
        _heun_forced(f, n_out, sub, h, c, burn, xs, vs, sw)
    elif float(params.get("rate", 0.0) or 0.0) > 0:
        sub = int(substeps) if substeps else 40
        h = dt / sub
        dW, dZ = poisson_impulses((burn + n_out) * sub, h, S0, float(params["rate"]), rng)
        _heun(dW, dZ, n_out, sub, h, c, 0.0, burn, xs, vs, sw)
    elif wb > 0:
        rolloff = float(params.get("rolloff", 0.0) or 0.0)
        f = band_limited_force((burn + n_out) * sub + 1, h, S0, wb, wc, rng, rolloff)
        _heun_forced(f, n_out, sub, h, c, burn, xs, vs, sw)
    else:
        n_sub = (burn + n_out) * sub
        dW = rng.standard_normal(n_sub) * math.sqrt(2.0 * math.pi * S0 * h)
        # the displacement's share of a sub-step's force, int_0^h (h - s) dW(s), is
        # h dW / 2 (in the Heun step) plus an independent part of variance h^3 / 12
        dZ = (
            rng.standard_normal(n_sub) * math.sqrt(2.0 * math.pi * S0 * h**3 / 12.0)
            if wc <= 0.0
            else np.zeros(0)
        )
        _heun(dW, dZ, n_out, sub, h, c, wc, burn, xs, vs, sw)
    if not (np.all(np.isfinite(xs)) and np.all(np.isfinite(vs))):
        raise HosidInputError(
            "the simulated response escaped (no stationary state for these parameters, "
            f"or dt = {dt:g} s with {sub} substeps is too coarse for the system)"
        )
    noise_sd = float(params.get("noise_sd", 0.0) or 0.0)
    if noise_sd > 0:
        xs += noise_sd * rng.standard_normal(n_out)
    record = Record(x=xs, dt=float(dt), name=name)
    return (record, vs) if return_velocity else record


def simulate_ensemble(
    params: Mapping[str, float], n_records: int, *, rng: np.random.Generator, **kwargs
) -> list[Record]:
    """Independent records, each from its own child generator (``rng.spawn``)."""
    return [
        simulate(params, rng=child, name=f"record-{i}", **kwargs)
        for i, child in enumerate(rng.spawn(int(n_records)))
    ]
