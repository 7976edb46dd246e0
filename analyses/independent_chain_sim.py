r"""An independent simulator of a system's chain (not hosid's).

The estimator is checked on records it did not generate itself:
:func:`hosid.model.chain.simulate_chain` is a stochastic Heun predictor-corrector on the
whole drift; this module integrates the same equations,

    m_d q_d'' + sum_e B_ed f_e(r_e, r_e') = F_d,   E[F_d(t) F_d(t + s)] = 2 pi S0_d delta(s),

with a BAOAB-style Strang splitting (as ``independent_sim.py`` does for the single
oscillator) on ``substeps`` (default 40) sub-steps of length ``h`` per sample:

* B: half kick by the elements' restoring forces (their displacement and constant terms),
  ``v += h/2 M^-1 (-Phi_x(q) theta_x)``;
* A: half drift, ``q += h/2 v``;
* O: the damping flow ``v' = -M^-1 Phi_v(v) theta_v`` over ``h/2`` by the classical
  fourth-order Runge-Kutta step, one kick ``v_d += sqrt(2 pi S0_d h) xi / m_d`` on every
  driven dof, and the damping flow over ``h/2`` again;
* A, B: the half drift and the half kick again.

The conservative part is a symplectic leapfrog and the dissipation a separate flow:
the scheme shares no step with Heun's method.  An acceleration channel holds the same
measurement as hosid's (:mod:`hosid.model.chain`): the interval average
``(v(t_n + dt/2) - v(t_n - dt/2)) / dt``, from the velocity at the sample's half steps
(``substeps`` even).  Records start at rest and are kept after a burn-in of 30 decay
times of the slowest linear mode (at least 100 s).  Randomness comes only from the
``numpy.random.Generator`` passed in, drawn in chunks.

Agreement with hosid's simulator: ``python analyses/independent_chain_sim.py --compare``
(module :func:`compare`; written to ``results/independent_chain_sim.md``).
"""

from __future__ import annotations

import argparse
import math
import sys
import tomllib
from pathlib import Path

import numba
import numpy as np

from hosid.model.chain import CODES, simulate_chain
from hosid.model.linear_chain import state_matrices
from hosid.model.system import GROUND, System
from hosid.model.system_file import system_from_dict
from hosid.record import Record

__all__ = ["compare", "simulate", "simulate_file"]

CHUNK = 4096  # samples per noise chunk
RESULTS = Path(__file__).resolve().parent / "results"


@numba.njit(cache=True)
def _force(q, v, ei, ej, code, coef, which, out):  # pragma: no cover - compiled
    """The elements' forces on the dofs of the terms of ``which`` (0: displacement and
    constant terms, 1: velocity terms), into ``out``.
    """
    out[:] = 0.0
    for c in range(code.size):
        k = code[c]
        velocity = k == 0 or k == 1 or k == 5
        if velocity != (which == 1):
            continue
        i, j = ei[c], ej[c]
        r, rd = q[j], v[j]
        if i >= 0:
            r -= q[i]
            rd -= v[i]
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
            f = math.tanh(rd / 1e-3)  # a steep, smooth sign for the ODE solver
        else:
            f = -1.0
        f *= coef[c]
        out[j] += f
        if i >= 0:
            out[i] -= f


@numba.njit(cache=True)
def _damp(q, v, t, sys_, k1, k2, k3, k4, tmp):  # pragma: no cover - compiled
    """The damping flow of ``v`` over ``t``: one classical Runge-Kutta step."""
    ei, ej, code, coef, minv = sys_
    _force(q, v, ei, ej, code, coef, 1, k1)
    for d in range(v.size):
        tmp[d] = v[d] - 0.5 * t * k1[d] * minv[d]
    _force(q, tmp, ei, ej, code, coef, 1, k2)
    for d in range(v.size):
        tmp[d] = v[d] - 0.5 * t * k2[d] * minv[d]
    _force(q, tmp, ei, ej, code, coef, 1, k3)
    for d in range(v.size):
        tmp[d] = v[d] - t * k3[d] * minv[d]
    _force(q, tmp, ei, ej, code, coef, 1, k4)
    for d in range(v.size):
        v[d] -= t * (k1[d] + 2.0 * k2[d] + 2.0 * k3[d] + k4[d]) * minv[d] / 6.0


@numba.njit(cache=True)
def _baoab(q, v, xi, n_int, sub, h, sys_, kick, drv, store, skip):  # pragma: no cover
    """Advance ``(q, v)`` by ``n_int`` sample intervals of ``sub`` splitting steps.

    Interval ``i`` ends at sample time ``i + 1``; sample ``j`` (time ``skip + j``) goes to
    ``qs``, ``vs``, and the velocity half an interval before it to ``vh[j]`` (when ``vh``
    has rows); ``store`` is ``(qs, vs, vh)``.
    """
    ei, ej, code, coef, minv = sys_
    qs, vs, vh = store
    n = q.size
    f = np.empty(n)
    k1, k2, k3, k4, tmp = np.empty(n), np.empty(n), np.empty(n), np.empty(n), np.empty(n)
    hh = 0.5 * h
    k = 0
    for i in range(n_int):
        for s in range(sub):
            _force(q, v, ei, ej, code, coef, 0, f)
            for d in range(n):
                v[d] -= hh * f[d] * minv[d]
                q[d] += hh * v[d]
            _damp(q, v, hh, sys_, k1, k2, k3, k4, tmp)
            for m in range(drv.size):
                v[drv[m]] += kick[m] * xi[k, m]
            k += 1
            _damp(q, v, hh, sys_, k1, k2, k3, k4, tmp)
            for d in range(n):
                q[d] += hh * v[d]
            _force(q, v, ei, ej, code, coef, 0, f)
            for d in range(n):
                v[d] -= hh * f[d] * minv[d]
            j = i + 1 - skip  # interval i ends at sample time i + 1
            if s == sub // 2 - 1 and vh.shape[0] > 0 and 0 <= j < vh.shape[0]:
                vh[j] = v  # half an interval before sample j
        j = i + 1 - skip
        if 0 <= j < qs.shape[0]:
            qs[j] = q
            vs[j] = v


def _arrays(system: System, th: np.ndarray):
    ei, ej, code = [], [], []
    for e, term in system.columns:
        a, b = system.elements[e].between
        ei.append(-1 if a == GROUND else system.dofs.index(a))
        ej.append(system.dofs.index(b))
        code.append(CODES[term.name])
    return (
        np.array(ei, dtype=np.int64),
        np.array(ej, dtype=np.int64),
        np.array(code, dtype=np.int64),
        th[: system.n_drift].copy(),
        1.0 / system.mass_vector(th),
    )


def simulate(
    system: System,
    values=None,
    *,
    duration: float,
    dt: float,
    rng: np.random.Generator,
    substeps: int = 40,
    measured=None,
    name: str = "",
    return_state: bool = False,
):
    """One stationary record of ``system`` (module docstring): a
    :class:`hosid.record.Record` with one channel a dof (``measured``: the system's kinds,
    undeclared ones displacements, or one kind for all); with ``return_state`` also the
    displacements and velocities at the sample times, each ``(n, dofs)``.
    """
    th = system.vector(values)
    kinds = system.measured if measured is None else (measured,) * system.n
    kinds = tuple(k or "displacement" for k in kinds)
    lam = np.linalg.eigvals(state_matrices(system, th)[0])
    rate = float(np.min(-lam.real))
    skip = round(max(100.0, 30.0 / rate) / dt) if rate > 0 else round(600.0 / dt)
    n_out, n = round(duration / dt), system.n
    h = dt / substeps
    sys_ = _arrays(system, th)
    drv = np.array([system.dofs.index(d) for d in system.driven], dtype=np.int64)
    S0 = system.levels(th)[drv]
    kick = np.sqrt(2.0 * math.pi * S0 * h) * sys_[-1][drv]
    q, v = np.zeros(n), np.zeros(n)
    qs, vs = np.empty((n_out, n)), np.empty((n_out, n))
    vh = np.empty((n_out + 1 if "acceleration" in kinds else 0, n))
    done = 0
    total = skip + n_out
    while done < total:
        m = min(CHUNK, total - done)
        xi = rng.standard_normal((m * substeps, drv.size))
        _baoab(q, v, xi, m, substeps, h, sys_, kick, drv, (qs, vs, vh), skip - done)
        done += m
        if not (np.all(np.isfinite(q)) and np.all(np.isfinite(v))):
            raise RuntimeError("the simulated response escaped")
    x = qs.copy()
    if vh.size:
        acc = np.diff(vh, axis=0) / dt
        for d, kind in enumerate(kinds):
            if kind == "acceleration":
                x[:, d] = acc[:, d]
    record = Record(x, float(dt), name, channels=system.dofs, measured=kinds)
    return (record, qs, vs) if return_state else record


def simulate_file(params, *, duration, dt, rng, name=""):
    """The design simulator of ``hosid batch`` (``FILE.py:simulate_file``): ``params``
    holds ``system`` (a system file's path, its ``[values]`` the truth) and optionally
    ``measured``.
    """
    system = system_from_dict(tomllib.loads(Path(params["system"]).read_text()), "")
    return simulate(system, duration=duration, dt=dt, rng=rng, name=name,
                    measured=params.get("measured"))  # fmt: skip


def compare(system: System, records: int = 20, seed: int = 7, duration: float = 2000.0) -> str:
    """Moments of this simulator's records against hosid's (module docstring): per dof
    E[q^2], E[v^2], the velocity's kurtosis, and the power balance
    sum_e E[f_damp,e r_e'] / sum_d pi S0_d / m_d (exactly 1 for a stationary response).
    """
    th = system.vector()
    B = system.incidence
    m, S0 = system.mass_vector(th), system.levels(th)
    rows = {}
    sims = (("independent (BAOAB, 40)", simulate), ("hosid (Heun, 10)", simulate_chain))
    for label, sim in sims:
        seeds = np.random.SeedSequence(seed).spawn(records)
        stats = []
        for s in seeds:
            _, q, v = sim(system, th, duration=duration, dt=0.02, rng=np.random.default_rng(s),
                          return_state=True)  # fmt: skip
            rd = v @ B.T
            fd = np.zeros_like(rd)
            for c, (e, t) in enumerate(system.columns):
                if t.variable == "v":
                    fd[:, e] += th[c] * t.phi(rd[:, e])
            balance = np.mean(np.sum(fd * rd, axis=1)) / np.sum(math.pi * S0 / m)
            kurt = np.mean(v**4, axis=0) / np.mean(v**2, axis=0) ** 2
            stats.append(np.r_[np.mean(q**2, axis=0), np.mean(v**2, axis=0), kurt, balance])
        stats = np.array(stats)
        rows[label] = (stats.mean(axis=0), stats.std(axis=0, ddof=1) / math.sqrt(records))
    names = [f"E[{x}_{d}^2]" for x in ("q", "v") for d in system.dofs]
    names += [f"kurt(v_{d})" for d in system.dofs] + ["balance"]
    (ma, sa), (mb, sb) = rows.values()
    lines = [f"| quantity | {' | '.join(rows)} | z |", "|---|---|---|---|"]
    for k, nm in enumerate(names):
        z = (ma[k] - mb[k]) / math.hypot(sa[k], sb[k])
        lines.append(f"| {nm} | {ma[k]:.4g} +- {sa[k]:.2g} | {mb[k]:.4g} +- {sb[k]:.2g} | "
                     f"{z:+.2f} |")  # fmt: skip
    return "\n".join(lines)


def main(argv=None) -> None:
    """``--compare``: both simulators on the study's chains; writes the results file."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--compare", action="store_true")
    ap.add_argument("--records", type=int, default=20)
    ap.add_argument("--quick", action="store_true", help="3 records of 300 s")
    args = ap.parse_args(argv)
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from chain_bound import system as study_system

    records, duration = (3, 300.0) if args.quick else (args.records, 2000.0)
    text = ["# The independent chain simulator against hosid's", ""]
    for name in ("chain2", "chain3"):
        table = compare(study_system(name), records=records, duration=duration)
        text += [f"## {name}: {records} records of {duration:g} s each, seed 7", "", table, ""]
        print(name, table, sep="\n", flush=True)
    if not args.quick:
        (RESULTS / "independent_chain_sim.md").write_text("\n".join(text))


if __name__ == "__main__":
    main()
