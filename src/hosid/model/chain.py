r"""Simulation of a system of :mod:`hosid.model.system`, and its multi-channel records.

The equations :math:`M\ddot q + \Phi(q, \dot q)\theta = F` are integrated by the
stochastic Heun method of :mod:`hosid.model.simulate` (weak order 2 for additive noise)
on ``substeps`` sub-steps of :math:`h = \Delta t/\mathrm{substeps}` per sample, with the
same two normals a sub-step and driven dof :math:`d`: the velocity increment
:math:`\Delta W_d/m_d`, :math:`\Delta W_d \sim N(0, 2\pi S_{0,d}h)`, and the
displacement's share of the force beyond Heun's :math:`h\Delta W_d/2`, an independent
normal of variance :math:`2\pi S_{0,d}h^3/12` over :math:`m_d^2` (without it the sampled
spectrum's top falls as if the force were low-passed).  The forces are independent
across dofs; undriven dofs get none.  Forces of a shape :math:`L`
(:attr:`hosid.model.system.System.excitation`) are drawn for the whole run on the
sub-step grid (:func:`hosid.model.simulate.shaped_force`: white noise shaped by one FFT)
and taken as linear over a sub-step: its integral is :math:`\Delta W_d`, its share in
the displacement beyond Heun's :math:`-h^2(f_{k+1} - f_k)/12`.  The run starts at rest,
and the samples start after a burn-in (default 30 decay times of the slowest linear mode,
at least 60 s).  The normals are drawn from the given generator in chunks of
:data:`CHUNK` samples (increments, then displacement shares, per chunk), so memory stays
small on long runs (a shaped force's run is held whole).

**What an acceleration channel holds.**  Under a white force the acceleration
:math:`\ddot q = M^{-1}(F - \Phi\theta)` has no finite value at an instant (its white
part has infinite variance); a sensor sees it through a low-pass filter.  A channel
declared ``acceleration`` holds the average acceleration over the sample interval
centred on :math:`t_n`,

.. math:: \bar a_n = \frac{\dot q(t_n + \Delta t/2) - \dot q(t_n - \Delta t/2)}{\Delta t}
    = \frac{1}{\Delta t}\int_{t_n - \Delta t/2}^{t_n + \Delta t/2}
    M^{-1}(F - \Phi\theta)\,dt,

the model's exact acceleration through a boxcar (integrate-and-dump) filter, computed
from the simulated velocities (so ``substeps`` is even).  It is the closest of the simple
definitions to an accelerometer behind an ideal anti-alias filter: the force's white part
sampled so has exactly the white spectrum :math:`S_{0,d}/m_d^2` up to the Nyquist
frequency with nothing aliased beyond (the increments of a Brownian motion are
independent; equivalently :math:`\sum_k\mathrm{sinc}^2(\omega\Delta t/2 + k\pi) = 1`),
which is what an ideal filter passes; the smooth drift part, far below the Nyquist
frequency, is passed with the gain :math:`\mathrm{sinc}^2(\omega\Delta t/2)` (0.996 at a
tenth of the Nyquist frequency).  The second difference of the sampled displacement
would give the white part the spectrum :math:`(2 + \cos\omega\Delta t)/3` (a triangle
filter, a third of the level at the Nyquist frequency), and the drift acceleration alone
would drop the white part that dominates an accelerometer's high frequencies.  Its
covariance for a linear system: :math:`\mathrm{Cov}\,\bar a =
(2P_{vv} - R_{vv}(\Delta t) - R_{vv}(\Delta t)^{\mathsf T})/\Delta t^2`, with
:math:`R(\tau) = e^{A\tau}P` (:mod:`hosid.model.linear_chain`).

Records: a :class:`hosid.record.Record` with one channel a dof (named as the dofs, each
a displacement or an acceleration), written by :func:`hosid.record.write_record` to CSV
(header ``t,x1,x2,...``) or ``.npz`` (one array a dof, ``dt``, ``dofs``, ``measured``);
a single displacement dof named ``x`` gives today's single-channel files.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from .._jit import njit
from ..errors import HosidInputError
from ..record import Record, write_record
from ..screen import THRESHOLDS
from .linear_chain import modes, state_matrices
from .simulate import shaped_force
from .system import GROUND, System
from .system_file import check_measured

__all__ = ["CHUNK", "CODES", "simulate_chain", "write_chain_record"]

#: Samples simulated per call of the compiled kernel (the normals are drawn per chunk).
CHUNK = 2048
#: The drift terms the compiled kernel knows, by its code.
CODES = {
    "linear_damping": 0,
    "quadratic_damping": 1,
    "linear_stiffness": 2,
    "cubic_stiffness": 3,
    "quadratic_stiffness": 4,
    "coulomb_friction": 5,
    "excitation_mean": 6,
}


@njit(cache=True)
def _forces(q, v, ei, ej, code, coef, out):  # pragma: no cover - compiled
    r"""The elements' forces on the dofs, :math:`B^{\mathsf T}f`, into ``out``."""
    out[:] = 0.0
    for c in range(code.size):
        i, j = ei[c], ej[c]
        r, rd = q[j], v[j]
        if i >= 0:
            r -= q[i]
            rd -= v[i]
        k = code[c]
        if k == 0:
            f = rd
        elif k == 1:
            f = rd * abs(rd)
        elif k == 2:
            f = r
        elif k == 3:
            f = r * r * r
        elif k == 4:
            f = r * r
        elif k == 5:
            f = np.sign(rd)
        else:
            f = -1.0
        f *= coef[c]
        out[j] += f
        if i >= 0:
            out[i] -= f


@njit(cache=True)
def _heun_chain(q, v, dW, dZ, i0, sub, h, sys, burn, qs, vs, vh):  # pragma: no cover
    """Heun on ``(q, v)`` over the intervals ``i0, i0 + 1, ...`` of this chunk.

    ``sys`` is ``(ei, ej, code, coef, minv, drv)``.  Interval ``i`` ends at sample time
    ``i + 1``; samples are the times ``burn .. burn + n_out - 1`` (``qs``, ``vs``), and
    ``vh[k]`` is the velocity half an interval after the start of interval
    ``burn - 1 + k``.
    """
    ei, ej, code, coef, minv, drv = sys
    n = q.size
    f0, f1 = np.empty(n), np.empty(n)
    qp, vp = np.empty(n), np.empty(n)
    n_int = dW.shape[0] // sub
    k = 0
    for ii in range(n_int):
        i = i0 + ii
        for s in range(sub):
            _forces(q, v, ei, ej, code, coef, f0)
            for d in range(n):
                qp[d] = q[d] + h * v[d]
                vp[d] = v[d] - h * f0[d] * minv[d]
            for m in range(drv.size):
                vp[drv[m]] += dW[k, m] * minv[drv[m]]
            _forces(qp, vp, ei, ej, code, coef, f1)
            for d in range(n):
                q[d] += 0.5 * h * (v[d] + vp[d])
                v[d] -= 0.5 * h * (f0[d] + f1[d]) * minv[d]
            for m in range(drv.size):
                d = drv[m]
                q[d] += dZ[k, m] * minv[d]
                v[d] += dW[k, m] * minv[d]
            k += 1
            if s == sub // 2 - 1 and vh.shape[0] > 0 and 0 <= i - burn + 1 < vh.shape[0]:
                vh[i - burn + 1] = v
        j = i + 1 - burn
        if 0 <= j < qs.shape[0]:
            qs[j] = q
            vs[j] = v


def _kernel_system(system: System, th: np.ndarray):
    ei, ej, code = [], [], []
    for e, term in system.columns:
        if term.name not in CODES:
            raise HosidInputError(f"the chain simulator does not know the term {term.name}")
        a, b = system.elements[e].between
        ei.append(-1 if a == GROUND else system.dofs.index(a))
        ej.append(system.dofs.index(b))
        code.append(CODES[term.name])
    m = system.mass_vector(th)
    drv = np.array([system.dofs.index(d) for d in system.driven], dtype=np.int64)
    ints = (np.array(ei, dtype=np.int64), np.array(ej, dtype=np.int64))
    return (*ints, np.array(code, dtype=np.int64), th[: system.n_drift].copy(), 1.0 / m, drv)


def _check(system: System, th: np.ndarray, duration: float, dt: float, sub: int) -> float:
    """Check the settings; return the slowest linear decay rate (0 if none)."""
    if not np.all(np.isfinite(th)):
        raise HosidInputError("simulation parameters must be finite")
    if not np.all(system.mass_vector(th) > 0):
        raise HosidInputError("masses must be positive")
    if not np.all(system.levels(th)[[system.dofs.index(d) for d in system.driven]] > 0):
        raise HosidInputError("S0 must be positive on every driven degree of freedom")
    if not (math.isfinite(dt) and dt > 0 and math.isfinite(duration) and duration > 0):
        raise HosidInputError("dt and duration must be finite and positive")
    if round(duration / dt) < 16:
        raise HosidInputError(
            f"duration {duration:g} s at dt {dt:g} s gives fewer than 16 samples"
        )
    if sub < 2 or sub % 2:
        raise HosidInputError("substeps must be even and at least 2 (the half-interval velocity)")
    lam = np.linalg.eigvals(state_matrices(system, th)[0])
    w = float(np.max(modes(system, th).omega, initial=0.0))
    limit = float(THRESHOLDS["sampling"][1])
    if w * dt / math.pi > limit:
        raise HosidInputError(
            f"dt = {dt:g} s is too coarse for this system: its linear mode near {w:.3g} rad/s "
            f"needs dt < {limit * math.pi / w:.3g} s"
        )
    return float(max(np.min(-lam.real), 0.0))


def simulate_chain(
    system: System,
    values=None,
    *,
    duration: float = 2000.0,
    dt: float = 0.02,
    rng: np.random.Generator,
    substeps: int = 10,
    burn_in: float | None = None,
    measured=None,
    name: str = "",
    return_state: bool = False,
) -> Record | tuple[Record, np.ndarray, np.ndarray]:
    r"""Simulate one stationary multi-channel record of ``system`` (module docstring).

    Parameters
    ----------
    system : System
    values : mapping or vector, optional
        The parameters (default the system's own ``values``, all needed); a sensor noise
        level ``N[dof]`` adds a white noise of variance :math:`2\pi N/\Delta t` to the
        channel.
    duration, dt : float
        Record length and sampling interval (s).
    rng : numpy.random.Generator
        The only source of randomness.
    substeps : int
        Heun steps per sample (even).
    burn_in : float, optional
        Seconds simulated from rest and discarded: default 30 decay times of the slowest
        mode of the linear part, :math:`\min(-\mathrm{Re}\,\lambda)`, between 60 and
        20 000 s (600 s if the linear part does not decay).
    measured : str or mapping, optional
        What each channel holds (default the system's ``measured``; an undeclared
        channel holds the displacement).
    return_state : bool
        Also return the displacements and velocities at the sample times, each
        ``(n_samples, n)``.

    Raises
    ------
    HosidInputError
        On missing or impossible values or settings, or a response that escapes.
    """
    if not isinstance(rng, np.random.Generator):
        raise TypeError("rng must be a numpy.random.Generator")
    th = system.vector(values)
    if th.ndim != 1:
        raise HosidInputError("simulate_chain takes one parameter vector")
    kinds = system.measured if measured is None else check_measured(measured, system.dofs)
    kinds = tuple(k or "displacement" for k in kinds)
    rate = _check(system, th, duration, dt, int(substeps))
    if burn_in is None:
        burn_in = min(max(60.0, 30.0 / rate), 20000.0) if rate > 0 else 600.0
    n_out, sub, n = round(duration / dt), int(substeps), system.n
    burn = max(round(burn_in / dt), 1)
    h = dt / sub
    kernel = _kernel_system(system, th)
    levels = system.levels(th)[kernel[-1]]
    sd_w = np.sqrt(2.0 * math.pi * levels * h)
    sd_z = np.sqrt(2.0 * math.pi * levels * h**3 / 12.0)
    q, v = np.zeros(n), np.zeros(n)
    qs, vs = np.empty((n_out, n)), np.empty((n_out, n))
    vh = np.empty((n_out + 1 if "acceleration" in kinds else 0, n))
    shaped = None
    if not system.spectrum.white:  # the whole run's forces on the sub-step grid

        def shape(omega):
            return system.spectrum.shape(omega, th)

        shaped = np.stack([shaped_force((burn + n_out) * sub + 1, h, lev, shape, rng)
                           for lev in levels], axis=-1)  # fmt: skip
    for i0 in range(0, burn + n_out, CHUNK):
        size = (min(i0 + CHUNK, burn + n_out) - i0) * sub
        if shaped is None:
            dW = rng.standard_normal((size, levels.size)) * sd_w
            dZ = rng.standard_normal((size, levels.size)) * sd_z
        else:  # a smooth force, linear over a sub-step: its integral and (h - s) moment
            f = shaped[i0 * sub : i0 * sub + size + 1]
            dW = 0.5 * h * (f[1:] + f[:-1])
            dZ = -(h**2 / 12.0) * (f[1:] - f[:-1])
        _heun_chain(q, v, dW, dZ, i0, sub, h, kernel, burn, qs, vs, vh)
        if not (np.all(np.isfinite(q)) and np.all(np.isfinite(v))):
            raise HosidInputError(
                "the simulated response escaped (no stationary state for these values, or "
                f"dt = {dt:g} s with {sub} substeps is too coarse for the system)"
            )
    x = qs.copy()
    if vh.size:
        acc = np.diff(vh, axis=0) / dt
        for d, kind in enumerate(kinds):
            if kind == "acceleration":
                x[:, d] = acc[:, d]
    noise = system.noise_levels(th)  # each channel's sensor noise, after the motion's draws
    if np.any(noise > 0):
        x = x + rng.standard_normal(x.shape) * np.sqrt(2.0 * math.pi * noise / dt)
    record = Record(x, float(dt), name, channels=system.dofs, measured=kinds)
    return (record, qs, vs) if return_state else record


def write_chain_record(record: Record, path: str | Path) -> Path:
    """Write a simulated record (:func:`hosid.record.write_record`: CSV with header
    ``t,<dof>,...`` or ``.npz`` with one array a dof, ``dt``, ``dofs``, ``measured``).

    Raises
    ------
    HosidInputError
        If the suffix is not ``.csv`` or ``.npz`` or the file cannot be written.
    """
    return write_record(record, path)
