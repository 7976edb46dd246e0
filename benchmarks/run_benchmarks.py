"""Timing table: simulation, J2 and J4A (hosid vs a plain-numpy loop), the
damping expansion of the fit's path against the direct pass, and the issue-4
term-model fit and diagnose run (against the issue-3 emcee fit and one simulation).

Run ``python benchmarks/run_benchmarks.py``; prints a table and writes
``benchmarks/results.md``.  Times are the best of 5 repeats (``timeit`` style).
"""

from __future__ import annotations

import os
import platform
import sys
import timeit
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from reference import j2_reference, j4a_reference

from hosid import costs as C
from hosid.simulate import PAPER_PARAMS, simulate
from hosid.spectra import block_spectra

REPEATS = 5
SEED = 2024


def best(fn, number=1, repeat=REPEATS):
    """Best wall time of one call (s), timeit-style."""
    return min(timeit.repeat(fn, number=number, repeat=repeat)) / number


def thetas(n, seed=0):
    rng = np.random.default_rng(seed)
    base = np.array([0.5, 0.5, 25.0, 5.0, 100.0])
    return base * rng.uniform(0.8, 1.2, size=(n, 5))


def setup_data():
    rec = simulate(PAPER_PARAMS, duration=2000.0, dt=0.02, rng=np.random.default_rng(SEED))
    return C.prepare(block_spectra(rec, window="hann"), "principal")


def check_agreement(data, th):
    """Reference and hosid agree to 1e-8 relative; returns the worst relative error."""
    Y = data.Ysigned.transpose(0, 2, 1)  # (5, N, 2K+1) for the reference
    r2 = j2_reference(th, Y, data.band_index, data.T, data.k2)
    r4 = j4a_reference(th, Y, data.tri_index, data.domain.gauss, data.T)
    e2 = np.max(np.abs(r2 - C.J2(th, data)) / np.abs(r2))
    e4 = np.max(np.abs(r4 - C.J4A(th, data)) / np.abs(r4))
    if max(e2, e4) > 1e-8:
        raise AssertionError(f"reference and hosid disagree: J2 {e2:.2e}, J4A {e4:.2e}")
    return max(e2, e4)


def main() -> list[tuple]:
    simulate(PAPER_PARAMS, duration=10.0, rng=np.random.default_rng(0))  # compile
    t_sim = best(
        lambda: simulate(PAPER_PARAMS, duration=2000.0, dt=0.02, rng=np.random.default_rng(1))
    )
    data = setup_data()
    err = check_agreement(data, thetas(8))
    Y = data.Ysigned.transpose(0, 2, 1)  # (5, N, 2K+1) for the reference
    rows = [("simulate 2000 s record (dt 0.02, 4 RK4 substeps)", 1, t_sim, None, None)]
    for P in (1, 64):
        th = thetas(P, seed=P)
        C.J2(th, data), C.J4A(th, data)  # warm caches and compiled kernels
        t2 = best(lambda th=th: C.J2(th, data))
        r2 = best(lambda th=th: j2_reference(th, Y, data.band_index, data.T, data.k2))
        t4 = best(lambda th=th: C.J4A(th, data))
        r4 = best(lambda th=th: j4a_reference(th, Y, data.tri_index, data.domain.gauss, data.T))
        rows.append((f"J2, {P} parameter set(s)", P, t2, r2, r2 / t2))
        rows.append((f"J4A, {P} parameter set(s)", P, t4, r4, r4 / t4))

    # the fit's path: 16 walkers at the cut stiffness, direct pass vs damping polynomials
    th = thetas(16, seed=3)
    th[:, 2:4] = (25.0, 5.0)
    t_build = best(lambda: C.DampingExpansion(data, 25.0, 5.0, (15.0, 1.3)))
    ex = C.DampingExpansion(data, 25.0, 5.0, (15.0, 1.3))
    rows.append(("build DampingExpansion (81 direct passes)", 1, t_build, None, None))
    for name in ("J2W", "J4AW"):
        np.testing.assert_allclose(ex.fast_cost(name, th), C.COSTS[name](th, data), rtol=1e-8)
        td = best(lambda name=name: C.COSTS[name](th, data))
        tf = best(lambda name=name: ex.fast_cost(name, th))
        rows.append((f"{name}, 16 sets, expansion (ref = direct pass)", 16, tf, td, td / tf))

    # issue 4: the term-model fit against the issue-3 emcee fit of the same record
    from hosid.diagnose import diagnose
    from hosid.modelfit import estimate_model, fit_model
    from hosid.sampling import fit

    rec = simulate(PAPER_PARAMS, duration=2000.0, dt=0.02, rng=np.random.default_rng(SEED))
    t_est = best(lambda: estimate_model(rec, "paper"))
    t_mf = best(lambda: fit_model(rec, "paper", rng=np.random.default_rng(0)), repeat=3)
    t_emcee = best(lambda: fit(rec, cost="J4A", seed=0, progress=False, n_bootstrap=30), repeat=1)
    rows.append(("estimate_model, paper (generator + J2W)", 1, t_est, None, None))
    rows.append(
        ("fit_model, paper (ref = issue-3 emcee fit, J4A)", 1, t_mf, t_emcee, t_emcee / t_mf)
    )
    t_diag = best(lambda: diagnose(rec, "paper", rng=np.random.default_rng(0)), repeat=1)
    rows.append(
        (
            f"diagnose, paper + 5 candidates, 20 replicates (= {t_diag / t_sim:.0f} simulations)",
            1,
            t_diag,
            None,
            None,
        )
    )

    sp = data.spectra
    header = (
        f"2000 s paper record, Hann, {sp.n_blocks} blocks x {sp.M} samples, "
        f"{sp.band.size} band bins, principal domain of {data.domain.size} triples; "
        f"best of {REPEATS}; {platform.processor() or platform.machine()}, "
        f"{os.cpu_count()} CPUs, numba threads "
        f"{__import__('numba').config.NUMBA_NUM_THREADS}; max relative "
        f"reference/hosid difference {err:.1e}"
    )
    lines = [
        "| task | sets | hosid total (ms) | hosid per set (ms) | numpy ref per set (ms) "
        "| ref / hosid |",
        "|---|---:|---:|---:|---:|---:|",
    ]
    for name, P, t, r, ratio in rows:
        ref = f"{1e3 * r / P:.3f}" if r is not None else "-"
        rat = f"{ratio:.1f}" if ratio is not None else "-"
        lines.append(f"| {name} | {P} | {1e3 * t:.3f} | {1e3 * t / P:.3f} | {ref} | {rat} |")
    text = header + "\n\n" + "\n".join(lines) + "\n"
    print(text)
    Path(__file__).with_name("results.md").write_text("# hosid benchmarks\n\n" + text)
    return rows


if __name__ == "__main__":
    main()
