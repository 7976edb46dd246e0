"""pytest-benchmark timings (``make bench``): simulation, J2 and J4A."""

import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))

from reference import j2_reference, j4a_reference

from hosid import costs as C
from hosid.simulate import PAPER_PARAMS, simulate
from hosid.spectra import block_spectra


@pytest.fixture(scope="module")
def data():
    rec = simulate(PAPER_PARAMS, duration=2000.0, dt=0.02, rng=np.random.default_rng(2024))
    return C.prepare(block_spectra(rec, window="hann"), "principal")


def _thetas(n, seed=0):
    rng = np.random.default_rng(seed)
    return np.array([0.5, 0.5, 25.0, 5.0, 100.0]) * rng.uniform(0.8, 1.2, size=(n, 5))


def test_simulate_2000s(benchmark):
    simulate(PAPER_PARAMS, duration=10.0, rng=np.random.default_rng(0))  # compile
    rec = benchmark(
        lambda: simulate(PAPER_PARAMS, duration=2000.0, dt=0.02, rng=np.random.default_rng(1))
    )
    assert rec.n == 100_000


@pytest.mark.parametrize("n_sets", [1, 64])
@pytest.mark.parametrize("impl", ["hosid", "numpy_reference"])
@pytest.mark.parametrize("cost", ["J2", "J4A"])
def test_cost(benchmark, data, cost, impl, n_sets):
    th = _thetas(n_sets, seed=n_sets)
    if impl == "hosid":
        f = C.COSTS[cost]
        f(th, data)  # compile / warm caches

        def run():
            return f(th, data)
    elif cost == "J2":

        def run():
            return j2_reference(
                th, data.Ysigned.transpose(0, 2, 1), data.band_index, data.T, data.k2
            )
    else:

        def run():
            return j4a_reference(
                th, data.Ysigned.transpose(0, 2, 1), data.tri_index, data.domain.gauss, data.T
            )

    benchmark.extra_info["n_sets"] = n_sets
    vals = benchmark(run)
    np.testing.assert_allclose(vals, C.COSTS[cost](th, data), rtol=1e-8)


@pytest.mark.parametrize("impl", ["direct", "expansion", "expansion_build"])
@pytest.mark.parametrize("cost", ["J2W", "J4AW"])
def test_damping_expansion(benchmark, data, cost, impl):
    """16 walkers' worth of parameter sets at a fixed (cut) stiffness, as in a fit:
    the direct block/triple pass against the exact damping polynomials."""
    th = _thetas(16, seed=3)
    th[:, 2:4] = (25.0, 5.0)
    ex = C.DampingExpansion(data, 25.0, 5.0, (15.0, 1.3))
    if impl == "direct":
        vals = benchmark(lambda: C.COSTS[cost](th, data))
    elif impl == "expansion":
        vals = benchmark(lambda: ex.fast_cost(cost, th))
    else:
        benchmark(lambda: C.DampingExpansion(data, 25.0, 5.0, (15.0, 1.3)))
        vals = ex.fast_cost(cost, th)
    benchmark.extra_info["n_sets"] = 16
    np.testing.assert_allclose(vals, C.COSTS[cost](th, data), rtol=1e-8)
