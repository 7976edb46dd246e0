"""The fits of 2- and 3-degree-of-freedom chains against the single oscillator's, in one run.

Each fit is ``hosid.fit`` with its defaults (the stop rule decides the steps) on a record
of 2000 s at dt = 0.02 (100 000 samples a channel): the paper's oscillator (S0 = 100),
and the chains of ``analyses/chain_bound.py`` from displacement records (and the 2-dof
chain from acceleration records), all simulated by hosid's simulators with one seed.
Reported per fit: the wall time, its phases (estimate: state, pilot and two rounds of
GMM; sampling), the sampler's steps and the cost of one quasi-likelihood evaluation for
32 walkers, each also as a ratio to the single oscillator's in the same run (the
machine's load changes the seconds, not the ratios).  The issue's target: a 2-dof fit
of 2000 s in under 30 s.

Run ``python benchmarks/chain_fits.py [--quick]``; prints the table and writes
``benchmarks/chain_results.md``.
"""

from __future__ import annotations

import argparse
import os
import platform
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "analyses"))

from chain_bound import system
from fit_timing import evaluation, timed_fit

from hosid.inference import estimate
from hosid.model import PAPER_PARAMS, simulate
from hosid.model.chain import simulate_chain

SEED = 2024
CASES = (
    ("single oscillator (paper)", "paper", "displacement"),
    ("2-dof chain", "chain2", "displacement"),
    ("2-dof chain, accelerations", "chain2", "acceleration"),
    ("3-dof chain", "chain3", "displacement"),
)


def _record(name: str, measured: str, duration: float):
    rng = np.random.default_rng(SEED)
    if name == "paper":
        return simulate(PAPER_PARAMS, duration=duration, dt=0.02, rng=rng), "paper"
    s = system(name)
    return simulate_chain(s, duration=duration, dt=0.02, rng=rng, measured=measured), s


def main(quick: bool = False) -> str:
    duration = 400.0 if quick else 2000.0
    simulate(PAPER_PARAMS, duration=10.0, rng=np.random.default_rng(0))  # compile
    rows = []
    for label, name, measured in CASES:
        record, structure = _record(name, measured, duration)
        tree, seconds, timings, steps = timed_fit(record, structure, quick)
        n_var = len(tree["posterior"].data_vars)
        ev = evaluation(estimate(record, structure))
        rows.append((label, seconds, timings["estimate"], timings["sampling"], steps, ev, n_var))
        print(f"{label}: {seconds:.1f} s ({steps} steps)", flush=True)
    base = rows[0]
    lines = [
        "# Chain fits against the single oscillator (one run)",
        "",
        f"`python benchmarks/chain_fits.py{' --quick' if quick else ''}`: records of "
        f"{duration:g} s at dt = 0.02, seed {SEED}; {platform.processor() or platform.machine()}, "
        f"{os.cpu_count()} cores, load average {os.getloadavg()[0]:.1f} at the end.",
        "",
        "| fit | variables | wall (s) | ratio | estimate (s) | sampling (s) | steps | "
        "evaluation, 32 walkers (ms) | ratio |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for label, sec, est_s, samp_s, steps, ev, nvar in rows:
        lines.append(
            f"| {label} | {nvar} | {sec:.1f} | {sec / base[1]:.2f} | {est_s:.1f} | {samp_s:.1f} | "
            f"{steps} | {1e3 * ev:.2f} | {ev / base[5]:.2f} |"
        )
    text = "\n".join(lines) + "\n"
    print(text)
    if not quick:
        (Path(__file__).with_name("chain_results.md")).write_text(text)
    return text


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="400 s records, 200 steps")
    main(ap.parse_args().quick)
