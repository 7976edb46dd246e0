"""The fits under a shaping filter against the white force's, in one run.

Each fit is ``hosid.fit`` with its defaults (the stop rule decides the steps) on a record
of the ship-roll-like oscillator of ``analyses/excitation_study.py`` (4000 s at dt = 0.1,
40 000 samples), simulated by hosid's simulator with one seed: under a white force fitted
with the white model (the baseline) and with ``narrowband_excitation`` (the white records'
cost of the term: the search, and the test that settles it to white), and under the
narrow and the broad filter at the oscillator's resonance.  Reported per fit: the wall
time, its phases (estimate; sampling), the sampler's steps, the estimate without the
equations' weight from records simulated at it (``simulations=0``: what that weight
costs) and the cost of one quasi-likelihood evaluation for 32 walkers, each also as a
ratio to the baseline's in the same run (the machine's load changes the seconds, not
the ratios).

Run ``python benchmarks/shaped_fits.py [--quick]``; prints the table and writes
``benchmarks/shaped_results.md``.
"""

from __future__ import annotations

import argparse
import os
import platform
from pathlib import Path

import numpy as np
from fit_timing import best_seconds, evaluation, timed_fit

from hosid.inference import estimate
from hosid.model import simulate

SEED = 2024
SHIP = {"a1": 0.03, "n1": 0.15, "a2": 0.35, "n2": 0.2, "S0": 2.6e-4}
SHAPED = "paper,narrowband_excitation"
#: label, the force's filter (wf, zf; None: white), the model fitted
CASES = (
    ("white force, white model", None, "paper"),
    ("white force, shaping filter asked for", None, SHAPED),
    ("narrow filter at the resonance (zf 0.1)", (0.6, 0.1), SHAPED),
    ("broad filter at the resonance (zf 0.25)", (0.6, 0.25), SHAPED),
)


def _record(force, duration: float):
    params = dict(SHIP) if force is None else {**SHIP, "wf": force[0], "zf": force[1]}
    return simulate(params, duration=duration, dt=0.1, rng=np.random.default_rng(SEED))


def main(quick: bool = False) -> str:
    duration = 2000.0 if quick else 4000.0
    simulate(SHIP, duration=10.0, dt=0.1, rng=np.random.default_rng(0))  # compile
    rows = []
    for label, force, model in CASES:
        record = _record(force, duration)
        _, seconds, timings, steps = timed_fit(record, model, quick)
        est = estimate(record, model)
        bare = best_seconds(lambda r=record, m=model: estimate(r, m, simulations=0))
        kept = "wf" in est.model.param_names
        rows.append((label, kept, seconds, timings["estimate"], bare, timings["sampling"], steps,
                     evaluation(est)))  # fmt: skip
        print(f"{label}: {seconds:.1f} s ({steps} steps)", flush=True)
    base = rows[0]
    lines = [
        "# Fits under a shaping filter against the white force's (one run)",
        "",
        f"`python benchmarks/shaped_fits.py{' --quick' if quick else ''}`: the ship-roll-like "
        f"oscillator, {duration:g} s at dt = 0.1, seed {SEED}; "
        f"{platform.processor() or platform.machine()}, {os.cpu_count()} cores, load average "
        f"{os.getloadavg()[0]:.1f} at the end.  `filter kept`: the fitted model has wf, zf "
        "(a white record's settles to the white force).",
        "",
        "| record, model | filter kept | wall (s) | ratio | estimate (s) | ratio | "
        "estimate, simulations=0 (s) | sampling (s) | steps | evaluation, 32 walkers (ms) "
        "| ratio |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for label, kept, sec, est_s, bare, samp_s, steps, ev in rows:
        lines.append(
            f"| {label} | {'yes' if kept else 'no'} | {sec:.1f} | {sec / base[2]:.2f} | "
            f"{est_s:.1f} | {est_s / base[3]:.1f} | {bare:.1f} | {samp_s:.1f} | {steps} | "
            f"{1e3 * ev:.2f} | {ev / base[7]:.2f} |"
        )
    text = "\n".join(lines) + "\n"
    print(text)
    if not quick:
        Path(__file__).with_name("shaped_results.md").write_text(text)
    return text


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="2000 s records, 200 steps")
    main(ap.parse_args().quick)
