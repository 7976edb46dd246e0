"""Timing and memory of the engine, as ratios measured in one run.

- the default fit and ``--cost J4A`` of a 100 000-sample record (2000 s at dt = 0.02),
  with their phases (estimate, sampling);
- time and peak memory of the record's processing (``estimate``: state, components,
  GMM) and of a whole fit at 2000 s and 20 000 s: the ratios show how they scale with the
  record length (linear: 10);
- one evaluation of the quasi-likelihood for 32 walkers at both lengths (it never touches
  the samples again: ratio about 1), against one FFT of the record as the unit of work.

Run ``python benchmarks/run_benchmarks.py [--quick]``; prints the tables and writes
``benchmarks/results.md``.  Peak memory is :mod:`tracemalloc`'s (numpy allocations
included), measured in a second, traced run of each call.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import time
import tracemalloc
from pathlib import Path

import numpy as np

from hosid.inference import components_for, estimate, fit
from hosid.model import PAPER_PARAMS, simulate

SEED = 2024


def timed(fn):
    """``(result, seconds, peak MiB)``: one untraced call for the time, one traced by
    :mod:`tracemalloc` (which slows Python's allocations several times) for the memory.
    """
    t0 = time.perf_counter()
    out = fn()
    sec = time.perf_counter() - t0
    tracemalloc.start()
    fn()
    peak = tracemalloc.get_traced_memory()[1] / 2**20
    tracemalloc.stop()
    return out, sec, peak


def best(fn, repeat=5):
    """Best wall time of ``repeat`` calls (s)."""
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return min(times)


def main(quick: bool = False) -> str:
    simulate(PAPER_PARAMS, duration=10.0, rng=np.random.default_rng(0))  # compile
    lines = [
        "# Benchmarks",
        "",
        f"{platform.processor() or platform.machine()}, {os.cpu_count()} cores, "
        f"Python {platform.python_version()}; one run of `benchmarks/run_benchmarks.py`.",
        "",
    ]
    recs = {
        T: simulate(PAPER_PARAMS, duration=T, dt=0.02, rng=np.random.default_rng(SEED))
        for T in (2000.0, 20000.0)
    }
    unit = {T: best(lambda r=r: np.fft.rfft(r.x)) for T, r in recs.items()}

    rows = []
    for label, cost in (("default", None), ("--cost J4A", "J4A")):
        tree, sec, peak = timed(
            lambda c=cost: fit(recs[2000.0], cost=c, seed=1, progress=False, with_map=False)
        )
        tm = json.loads(tree.attrs["timings_json"])
        rows.append((label, sec, tm, peak))
    lines += [
        "## Fits of a 100 000-sample record (2000 s at dt = 0.02 s)",
        "",
        "| fit | wall time (s) | estimate | sampling | peak memory (MiB) |",
        "|---|---|---|---|---|",
    ]
    for label, sec, tm, peak in rows:
        lines.append(
            f"| {label} | {sec:.1f} | {tm['estimate']:.2f} | {tm['sampling']:.2f} | {peak:.0f} |"
        )

    comps = components_for()
    scale = {}
    for T, r in recs.items():
        est, sec_e, peak_e = timed(lambda r=r: estimate(r, "paper", comps))
        theta = est.theta + 1e-3 * np.random.default_rng(0).standard_normal((32, 5))
        ev = best(lambda e=est, th=theta: e.ql(th), repeat=50)
        if quick:
            sec_f, peak_f = float("nan"), float("nan")
        else:
            _, sec_f, peak_f = timed(lambda r=r: fit(r, seed=1, progress=False, with_map=False))
        scale[T] = (sec_e, peak_e, ev, sec_f, peak_f)
    a, b = scale[2000.0], scale[20000.0]
    lines += [
        "",
        "## Scaling with the record length (default components)",
        "",
        "| | 2000 s | 20 000 s | ratio |",
        "|---|---|---|---|",
        f"| one FFT of the record (s) | {unit[2000.0]:.4f} | {unit[20000.0]:.4f} | "
        f"{unit[20000.0] / unit[2000.0]:.1f} |",
        f"| estimate: time (s) | {a[0]:.2f} | {b[0]:.2f} | {b[0] / a[0]:.1f} |",
        f"| estimate: peak memory (MiB) | {a[1]:.0f} | {b[1]:.0f} | {b[1] / a[1]:.1f} |",
        f"| quasi-likelihood, 32 walkers (ms) | {1e3 * a[2]:.3f} | {1e3 * b[2]:.3f} | "
        f"{b[2] / a[2]:.2f} |",
        f"| whole fit: time (s) | {a[3]:.1f} | {b[3]:.1f} | {b[3] / a[3]:.1f} |",
        f"| whole fit: peak memory (MiB) | {a[4]:.0f} | {b[4]:.0f} | {b[4] / a[4]:.1f} |",
        "",
        "The record is processed once (`estimate`); sampling evaluates precomputed "
        "sufficient statistics, so its cost does not grow with the record.",
        "",
    ]
    text = "\n".join(lines)
    print(text)
    return text


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="skip the 20 000 s whole fit")
    args = ap.parse_args()
    out = main(quick=args.quick)
    (Path(__file__).parent / "results.md").write_text(out)
    sys.exit(0)
