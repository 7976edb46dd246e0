"""SYNTHETIC fit results for the plotting, report and CLI tests.

Not the output of any sampler: Gaussian draws around the paper's oscillator and a
quadratic bowl as cost map, in the layout of ``hosid.results``. They test the
plumbing and the figures' structure, never numbers.
"""

import math

import numpy as np

from hosid import results

TRUTHS = {"a1": 0.5, "n1": 0.5, "a2": 25.0, "n2": 5.0, "S0": 100.0}
SDS = {"a1": 0.05, "n1": 0.05, "a2": 0.5, "n2": 0.3, "S0": 5.0}
SIGMA_V = 1.2


def synthetic_tree(*, stuck=False, cost_map=True, truths=True, seed=0, n_chain=16, n_draw=200):
    """A fit-shaped ``DataTree``; ``stuck`` walkers sit apart (R-hat and ESS fail)."""
    rng = np.random.default_rng(seed)
    shape = (n_chain, n_draw)
    if stuck:
        offsets = 3.0 * rng.standard_normal((n_chain, 1))
        noise = {k: offsets + 0.01 * rng.standard_normal(shape) for k in TRUTHS}
    else:
        noise = {k: rng.standard_normal(shape) for k in TRUTHS}
    post = {k: TRUTHS[k] + SDS[k] * noise[k] for k in TRUTHS}
    post["a1eq"] = post["a1"] + post["n1"] * math.sqrt(8 / math.pi) * SIGMA_V
    grid = None
    if cost_map:
        a1, n1 = np.linspace(-0.2, 1.2, 29), np.linspace(0.0, 1.0, 21)
        a, n = np.meshgrid(a1, n1, indexing="ij")
        grid = {"a1": a1, "n1": n1, "cost": (a - 0.5) ** 2 + 4 * (n - 0.5) ** 2 - 0.3}
    lp = -0.5 * sum(noise[k] ** 2 for k in TRUTHS)
    return results.build_tree(
        post,
        sample_stats={"lp": lp, "log_prior": np.zeros(shape)},
        log_likelihood={"J4AW": lp},
        cost_map=grid,
        attrs={
            "cost": "J4A",
            "constrained": True,
            "temperature": 3.5,
            "sigma_v": SIGMA_V,
            "x_max": 0.8,
            "record": "synthetic",
            "fit_seconds": 12.5,
            "truths": dict(TRUTHS) if truths else None,
            "settings": {"window": "hann", "block_seconds": 20.48, "omega_max": 8.0},
            "calibration": {"method": "synthetic", "temperature": 3.5},
        },
    )
