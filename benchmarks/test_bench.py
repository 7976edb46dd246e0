"""pytest-benchmark timings (``make bench``): simulation, the record's processing and
one quasi-likelihood evaluation (the sampler's inner loop)."""

import numpy as np
import pytest

from hosid.inference import components_for, estimate
from hosid.model import PAPER_PARAMS, simulate


@pytest.fixture(scope="module")
def record():
    return simulate(PAPER_PARAMS, duration=2000.0, dt=0.02, rng=np.random.default_rng(2024))


@pytest.fixture(scope="module")
def est(record):
    return estimate(record, "paper", components_for())


def test_simulate_2000s(benchmark):
    simulate(PAPER_PARAMS, duration=10.0, rng=np.random.default_rng(0))  # compile
    rec = benchmark(lambda: simulate(PAPER_PARAMS, rng=np.random.default_rng(1)))
    assert rec.n == 100_000


def test_estimate_default(benchmark, record):
    e = benchmark(lambda: estimate(record, "paper", components_for()))
    assert abs(e.values["a2"] - 25.0) < 4.0


def test_estimate_J4A(benchmark, record):
    e = benchmark(lambda: estimate(record, "paper", components_for("J4A")))
    assert abs(e.values["S0"] - 100.0) < 10.0


def test_quasi_likelihood_32_walkers(benchmark, est):
    theta = est.theta + 1e-3 * np.random.default_rng(0).standard_normal((32, 5))
    out = benchmark(lambda: est.ql(theta))
    assert out.shape == (32,) and np.all(np.isfinite(out))
