"""What the fit benchmarks (``chain_fits.py``, ``shaped_fits.py``) measure of one fit: its
wall time, phases and steps, and one quasi-likelihood evaluation for 32 walkers."""

from __future__ import annotations

import json
import time

import numpy as np

from hosid.inference import fit


def timed_fit(record, model, quick: bool) -> tuple:
    """``hosid.fit`` with its defaults (200 steps when ``quick``): the tree, its wall
    time (s), its phases' timings and the sampler's steps."""
    t0 = time.perf_counter()
    tree = fit(record, model=model, seed=1, progress=False, with_map=False,
               n_steps=200 if quick else None)  # fmt: skip
    seconds = time.perf_counter() - t0
    steps = json.loads(tree.attrs["sampler_json"])["steps"]
    return tree, seconds, json.loads(tree.attrs["timings_json"]), steps


def best_seconds(fn, repeat: int = 1) -> float:
    """Best wall time of ``repeat`` calls of ``fn`` (s)."""
    best = np.inf
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best


def evaluation(est) -> float:
    """Seconds of one evaluation of ``est``'s quasi-likelihood for 32 walkers about its
    mode (best of 20)."""
    rng = np.random.default_rng(0)
    theta = est.theta + 1e-3 * np.abs(est.theta) * rng.standard_normal((32, est.theta.size))
    return best_seconds(lambda: est.ql(theta), repeat=20)
