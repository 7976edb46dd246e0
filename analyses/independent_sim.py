r"""An independent simulator of the study's oscillator (not hosid's).

The estimator is checked on records it did not generate itself:
:func:`hosid.model.simulate` is a stochastic Heun predictor-corrector; this module
integrates the same equation,

    x'' + a1 x' + n1 x'|x'| + a2 x + n2 x^3 = f(t),   R_f(tau) = 2 pi S0 delta(tau),

with a BAOAB-style Strang splitting on ``substeps`` (default 40) sub-steps of length
``h`` per sample:

* B: half kick by the restoring force, ``v += h/2 (-a2 x - n2 x^3)``;
* A: half drift, ``x += h/2 v``;
* O: the exact flow of the damping ``v' = -a1 v - n1 v|v|`` over ``h/2``
  (a Bernoulli equation: ``v -> v e^{-a1 t} / (1 + n1 |v| (1 - e^{-a1 t}) / a1)``),
  one Brownian increment ``v += sqrt(2 pi S0) dW``, ``dW ~ N(0, h)``, and the damping
  flow over ``h/2`` again;
* A, B: the half drift and half kick again.

The conservative part is a symplectic leapfrog and the damping is integrated exactly,
so the scheme shares no step with Heun's method.  Records start at rest and are kept
after a burn-in of ``max(100 s, 40 / a1eq)`` (``a1eq`` from the stationary power
balance ``a1 s^2 + n1 sqrt(8/pi) s^3 = pi S0``).  Randomness comes only from the
``numpy.random.Generator`` passed in; noise is drawn in chunks so memory stays flat.

Agreement with hosid's simulator (``python analyses/independent_sim.py --compare``;
paper oscillator, S0 = 100, 40 records of 2000 s from each, seed 11; mean over records
+- its standard error; z = difference / combined standard error)::

    quantity      independent (BAOAB, 40)    hosid (Heun, 10)           z
    E[x^2]        1.3191 +- 0.0026           1.3144 +- 0.0026       +1.27
    E[v^2]        53.27  +- 0.12             53.18  +- 0.08         +0.61
    kurt(v)       2.4956 +- 0.0026           2.5004 +- 0.0025       -1.32
    balance       1.0012 +- 0.0030           0.9996 +- 0.0021       +0.44

(``kurt(v) = E[v^4] / E[v^2]^2``; ``balance = (a1 E[v^2] + n1 E[|v|^3]) / (pi S0)``,
exactly 1 for a stationary response.)  Both agree within sampling error on every
quantity; a second run with 60 records each (other seeds; BAOAB with 10 and 40
sub-steps, Heun with 10 and 40) gave E[x^2] 1.3167, 1.3162, 1.3151, 1.3145 (se 0.002),
E[v^2] 53.19, 53.25, 53.13, 53.10 (se 0.07) and kurt(v) 2.4950, 2.4973, 2.4950, 2.4979
(se 0.002): no step-size or scheme effect is visible at this precision.

The candidate effects of ``hosid diagnose`` are optional keys (absent = 0), for the
power study (``diagnose_power.py``):

* ``b2`` (x^2 spring) and ``m`` (mean force) join the restoring kick B:
  ``v += h/2 (m - a2 x - b2 x^2 - n2 x^3)``;
* ``mu`` (Coulomb friction ``mu sign(v)``) joins the damping flow O as its own exact
  flow, ``v -> sign(v) max(|v| - mu t, 0)`` (sticking at rest), applied for ``h/4``
  around each Bernoulli half flow;
* ``wc`` (the force through the low-pass ``g' = wc (w - g)``, spectrum
  ``S0 wc^2 / (wc^2 + w^2)``): the O step's kick is the force's exact impulse over the
  sub-step, drawn jointly with the force's next value (both Gaussian given the force
  now: an exact Ornstein-Uhlenbeck step and its integral, two normals per sub-step);
* ``noise_sd``: white noise added to the sampled displacement after the simulation.

Two more forces replace the white one (``independent_forces.py``; the O step's kick is
the force's exact impulse over the sub-step, drawn a chunk ahead since the force does
not depend on the oscillator):

* ``wf, zf`` (together, both > 0): a narrow-band force, the white noise through
  ``g'' + 2 zf wf g' + wf^2 g = wf^2 w``, two-sided spectrum
  ``S0 wf^4 / ((wf^2 - omega^2)^2 + (2 zf wf omega)^2)`` (``S0`` at ``omega = 0``);
  ``(g, g', impulse)`` advance by the exact transition matrix and noise covariance of
  the linear SDE over ``h`` (Van Loan; three normals a sub-step), ``(g, g')`` starting
  from its stationary law (two normals before the first chunk).  Not with ``wc``.
* ``rate`` (> 0): Poisson impulses of rate ``rate`` per second with areas
  ``N(0, 2 pi S0 / rate)``: the flat spectrum ``S0`` of the white force, not Gaussian
  (the white force is the limit ``rate -> inf``); the kick is the sum of the
  ``Poisson(rate h)`` areas in the sub-step.  Not with ``wc`` or ``wf``.

A change of the parameters at ``change_at`` seconds from the first sample (a step, or a
ramp over ``ramp`` seconds) to ``a1_after, n1_after, a2_after, n2_after, S0_after``
(also ``b2_after, mu_after, m_after``; absent = unchanged) runs the kernel piecewise,
the kicks scaled by ``sqrt(S0(t) / S0)`` (``independent_forces.ParameterChange``).

With none of them the random stream and the records are those of the paper-only
simulator above.
"""

from __future__ import annotations

import argparse
import importlib.util
import math
import sys
from collections.abc import Mapping, Sequence
from pathlib import Path

import numba
import numpy as np

from hosid.record import Record

try:
    import independent_forces
except ModuleNotFoundError:  # imported by path (hosid batch): analyses/ is not on sys.path
    _spec = importlib.util.spec_from_file_location(
        "independent_forces", Path(__file__).with_name("independent_forces.py")
    )
    independent_forces = importlib.util.module_from_spec(_spec)
    sys.modules["independent_forces"] = independent_forces
    _spec.loader.exec_module(independent_forces)

__all__ = ["compare", "simulate"]

CHUNK = 8192  # samples per noise chunk
_KEYS = ("a1", "n1", "a2", "n2", "S0")
#: Optional keys: the candidate effects (module docstring), 0 when absent.
EFFECT_KEYS = ("b2", "mu", "m", "wc", "noise_sd", "wf", "zf", "rate")


@numba.njit(cache=True, inline="always")
def _friction(v, d):  # pragma: no cover - compiled
    """Exact flow of ``v' = -mu sign(v)`` over a time with ``d = mu t``."""
    if v > d:
        return v - d
    if v < -d:
        return v + d
    return 0.0


@numba.njit(cache=True)
def _baoab(
    xi, n_out, sub, h, a1, n1, a2, n2, b2, mu, m, sigma, wc, direct, state, xs, vs
):  # pragma: no cover - compiled
    """Advance ``state = [x, v, g]`` by ``n_out`` samples of ``sub`` splitting steps.

    White force (``wc == 0``): the O kick is ``sigma sqrt(h) xi[0, k]``.  Low-pass force
    ``g = state[2]``: the kick is the force's exact impulse over ``h``, drawn jointly with
    its next value from ``xi[0, k]`` and ``xi[1, k]``.  ``direct``: ``xi[0, k]`` is the
    kick itself (the forces of ``independent_forces.py``).
    """
    hh = 0.5 * h
    e = math.exp(-a1 * hh)
    c = n1 * (1.0 - e) / a1 if a1 > 0.0 else n1 * hh
    s = sigma * math.sqrt(h)
    d = 0.25 * mu * h
    eg = one = l11 = l21 = l22 = 0.0
    if wc > 0.0:
        a = wc * h
        eg = math.exp(-a)
        one = -math.expm1(-a)  # 1 - e^{-wc h}
        two = -math.expm1(-2.0 * a)  # 1 - e^{-2 wc h}
        var_i = sigma * sigma * (a + 2.0 * math.expm1(-a) - 0.5 * math.expm1(-2.0 * a)) / wc
        var_g = 0.5 * sigma * sigma * wc * two
        l11 = math.sqrt(var_i)
        l21 = sigma * sigma * (one - 0.5 * two) / l11
        l22 = math.sqrt(max(var_g - l21 * l21, 0.0))
    x = state[0]
    v = state[1]
    g = state[2]
    k = 0
    for i in range(n_out):
        for _ in range(sub):
            v -= hh * (a2 * x + n2 * x * x * x + b2 * x * x - m)
            x += hh * v
            if mu > 0.0:
                v = _friction(v, d)
            v = v * e / (1.0 + c * abs(v))
            if mu > 0.0:
                v = _friction(v, d)
            if wc > 0.0:
                v += g * one / wc + l11 * xi[0, k]
                g = g * eg + l21 * xi[0, k] + l22 * xi[1, k]
            elif direct:
                v += xi[0, k]
            else:
                v += s * xi[0, k]
            k += 1
            if mu > 0.0:
                v = _friction(v, d)
            v = v * e / (1.0 + c * abs(v))
            if mu > 0.0:
                v = _friction(v, d)
            x += hh * v
            v -= hh * (a2 * x + n2 * x * x * x + b2 * x * x - m)
        xs[i] = x
        vs[i] = v
    state[0] = x
    state[1] = v
    state[2] = g


def _equivalent_damping(a1: float, n1: float, S0: float) -> float:
    """``a1 + n1 sqrt(8/pi) s`` at the velocity scale of the power balance."""
    c8 = math.sqrt(8.0 / math.pi)
    lo, hi = 0.0, 1.0
    while a1 * hi**2 + n1 * c8 * hi**3 < math.pi * S0:
        hi *= 2.0
    for _ in range(100):
        s = 0.5 * (lo + hi)
        lo, hi = (s, hi) if a1 * s**2 + n1 * c8 * s**3 < math.pi * S0 else (lo, s)
    return a1 + n1 * c8 * 0.5 * (lo + hi)


def simulate(
    params: Mapping[str, float],
    *,
    duration: float,
    dt: float,
    rng: np.random.Generator,
    substeps: int = 40,
    burn_in: float | None = None,
    name: str = "",
) -> tuple[Record, np.ndarray]:
    """Simulate one stationary record and its velocity.

    Parameters
    ----------
    params : mapping
        ``a1, n1, a2, n2, S0`` (``a1, n1, n2 >= 0``, ``a1 + n1 > 0``, ``a2 > 0``,
        ``S0 > 0``) and optionally the effects ``b2, mu, m, wc, noise_sd`` and forces
        ``wf, zf, rate`` (module docstring; ``mu, wc, noise_sd, rate >= 0``, ``b2`` only
        with ``n2 > 0``, ``wf`` and ``zf`` both > 0 or both 0, one non-white force), and
        a change ``change_at, ramp, <p>_after`` (module docstring).
    duration, dt : float
        Record length and sampling interval (s).
    rng : numpy.random.Generator
        The only source of randomness.
    substeps : int
        Splitting steps per sample.
    burn_in : float, optional
        Seconds discarded after the start from rest (default ``max(100, 40 / a1eq)``).
    name : str
        Record label.

    Returns
    -------
    record : hosid.record.Record
        The sampled displacement.
    v : numpy.ndarray
        The velocity at the same instants (without measurement noise).

    Raises
    ------
    ValueError
        On missing, unknown or out-of-range parameters or settings.
    TypeError
        If ``rng`` is not a ``numpy.random.Generator``.
    """
    if not isinstance(rng, np.random.Generator):
        raise TypeError("rng must be a numpy.random.Generator")
    missing = set(_KEYS) - set(params)
    unknown = set(params) - set(_KEYS) - set(EFFECT_KEYS) - set(independent_forces.CHANGE_KEYS)
    if missing or unknown:
        raise ValueError(
            f"params must hold {', '.join(_KEYS)} (optional: {', '.join(EFFECT_KEYS)}); "
            f"missing {sorted(missing)}, unknown {sorted(unknown)}"
        )
    a1, n1, a2, n2, S0 = (float(params[k]) for k in _KEYS)
    b2, mu, m, wc, noise_sd, wf, zf, rate = (float(params.get(k, 0.0)) for k in EFFECT_KEYS)
    if not (a1 >= 0 and n1 >= 0 and n2 >= 0 and a1 + n1 > 0 and a2 > 0 and S0 > 0):
        raise ValueError(f"parameters out of range: {dict(params)}")
    if not (mu >= 0 and wc >= 0 and noise_sd >= 0 and (b2 == 0 or n2 > 0)):
        raise ValueError(
            f"effects out of range (mu, wc, noise_sd >= 0; b2 needs n2 > 0): {params}"
        )
    if not all(math.isfinite(f) for f in (wf, zf, rate)):
        raise ValueError(f"wf, zf and rate must be finite: {params}")
    if not (wf >= 0 and zf >= 0 and (wf > 0) == (zf > 0)):
        raise ValueError(f"the narrow-band force needs both wf > 0 and zf > 0: {params}")
    if wf > 0 and wc > 0:
        raise ValueError("wc (low-pass force) and wf, zf (narrow-band force) exclude each other")
    if not rate >= 0:
        raise ValueError(f"rate (Poisson impulses per second) must be >= 0: {params}")
    if rate > 0 and (wc > 0 or wf > 0):
        raise ValueError("rate (Poisson impulses) replaces the white force: not with wc or wf")
    if not (dt > 0 and duration > 0 and int(substeps) >= 1):
        raise ValueError("dt, duration and substeps must be positive")
    if burn_in is None:
        burn_in = max(100.0, 40.0 / _equivalent_damping(a1, n1, S0))
    sub = int(substeps)
    h = float(dt) / sub
    sigma = math.sqrt(2.0 * math.pi * S0)
    n_burn, n_out = round(burn_in / dt), round(duration / dt)
    state = np.zeros(3)
    xs, vs = np.empty(n_out), np.empty(n_out)
    scratch = np.empty((2, CHUNK))
    force = None
    if wf > 0:
        force = independent_forces.NarrowBand(wf, zf, S0, h, rng)
    elif rate > 0:
        force = independent_forces.PoissonImpulses(rate, S0, h)
    coefficients = (a1, n1, a2, n2, b2, mu, m, sigma, wc, force is not None)
    change = independent_forces.ParameterChange(params, coefficients, duration, dt, n_burn)
    done = 0
    while done < n_burn + n_out:
        k = min(CHUNK, n_burn + n_out - done)
        if force is not None:  # the force's impulses over the chunk's sub-steps
            xi = force.impulses(rng, k * sub)
        else:  # one normal a sub-step for a white force (the paper-only stream), two for wc
            xi = rng.standard_normal((2, k * sub) if wc > 0 else (1, k * sub))
        for lo, n, co, kicks in change.pieces(xi, done, k, sub):  # one without a change
            _baoab(kicks, n, sub, h, *co, state, *scratch[:, lo : lo + n])
        if done + k > n_burn:
            lo = max(n_burn - done, 0)
            a, b = done + lo - n_burn, done + k - n_burn
            xs[a:b], vs[a:b] = scratch[0, lo:k], scratch[1, lo:k]
        done += k
    if not (np.all(np.isfinite(xs)) and np.all(np.isfinite(vs))):
        raise ValueError("the simulated response escaped; reduce dt or raise substeps")
    if noise_sd > 0:
        xs = xs + noise_sd * rng.standard_normal(n_out)
    return Record(x=xs, dt=float(dt), name=name), vs


def _stats(x: np.ndarray, v: np.ndarray, p: Mapping[str, float]) -> dict[str, float]:
    ev2 = float(np.mean(v**2))
    power = p["a1"] * ev2 + p["n1"] * float(np.mean(np.abs(v) ** 3))
    return {
        "E[x^2]": float(np.mean(x**2)),
        "E[v^2]": ev2,
        "kurt(v)": float(np.mean(v**4) / ev2**2),
        "balance": power / (math.pi * p["S0"]),
    }


def compare(
    params: Mapping[str, float],
    *,
    n_records: int,
    duration: float,
    dt: float,
    seed: int,
) -> dict[str, dict[str, tuple[float, float]]]:
    """Moments of both simulators over replicated records (mean, standard error).

    Parameters
    ----------
    params : mapping
        ``a1, n1, a2, n2, S0``.
    n_records : int
        Records per simulator.
    duration, dt : float
        Record length and sampling interval (s).
    seed : int
        Root of the ``SeedSequence`` both simulators' records are spawned from.

    Returns
    -------
    dict
        ``{"independent": {quantity: (mean, se)}, "hosid": {...}}``.
    """
    from hosid.model import simulate as hosid_simulate

    ind_ss, hos_ss = np.random.SeedSequence(seed).spawn(2)
    out = {}
    for label, root in (("independent", ind_ss), ("hosid", hos_ss)):
        rows = []
        for ss in root.spawn(n_records):
            rng = np.random.default_rng(ss)
            if label == "independent":
                rec, v = simulate(params, duration=duration, dt=dt, rng=rng)
            else:
                rec, v = hosid_simulate(
                    params, duration=duration, dt=dt, rng=rng, return_velocity=True
                )
            rows.append(_stats(rec.x, v, params))
        out[label] = {
            k: (
                float(np.mean([r[k] for r in rows])),
                float(np.std([r[k] for r in rows], ddof=1) / math.sqrt(n_records)),
            )
            for k in rows[0]
        }
    return out


def main(argv: Sequence[str] | None = None) -> None:
    """``--compare``: the agreement table of the module docstring."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--compare", action="store_true", help="print the agreement table")
    ap.add_argument("--records", type=int, default=40)
    ap.add_argument("--duration", type=float, default=2000.0)
    ap.add_argument("--seed", type=int, default=11)
    args = ap.parse_args(argv)
    if not args.compare:
        ap.print_help()
        return
    params = {"a1": 0.5, "n1": 0.5, "a2": 25.0, "n2": 5.0, "S0": 100.0}
    res = compare(params, n_records=args.records, duration=args.duration, dt=0.02, seed=args.seed)
    print(f"{'quantity':<12}{'independent (BAOAB, 40)':>26}{'hosid (Heun, 10)':>26}{'z':>8}")
    for k, (m1, s1) in res["independent"].items():
        m2, s2 = res["hosid"][k]
        z = (m1 - m2) / math.hypot(s1, s2)
        print(f"{k:<12}{m1:>15.6g} +- {s1:<8.2g}{m2:>15.6g} +- {s2:<8.2g}{z:>+8.2f}")


if __name__ == "__main__":
    main()
