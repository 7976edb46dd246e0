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


@pytest.fixture(scope="module")
def storeys():
    """A five-storey shear chain like the building's (``analyses/building.py``): masses
    unknown, a narrow-band roof force, each floor's sensor noise; 46 walkers (its fit's),
    1492 bins (its band)."""
    from hosid.model.system import System

    dofs = ("x1", "x2", "x3", "x4", "x5")
    pairs = zip(("ground", *dofs[:-1]), dofs, strict=True)
    system = System(dofs, [(p, ("linear",)) for p in pairs], driven=("x5",),
                    measured="acceleration", sensor_noise=True,
                    excitation="narrowband_excitation")  # fmt: skip
    th = np.array([2.0, 160.0] * 5 + [1.0] * 4 + [3e-5, 8.7, 0.6] + [1e-6] * 5)
    assert th.size == len(system.param_names)
    walkers = th * (1 + 0.01 * np.random.default_rng(0).standard_normal((46, th.size)))
    return system, walkers, np.linspace(1.2, 24.1, 1492)


def test_spectral_matrix_parts_46_walkers(benchmark, storeys):
    """The whole matrix, then its Hermitian parts (the sampler's path before the parts
    were built from the transfer's columns): the baseline of the next."""
    from hosid.components.chain_spectral_matrix import _hermitian_parts, spectral_matrix

    system, walkers, omega = storeys
    out = benchmark(lambda: _hermitian_parts(spectral_matrix(system, walkers, omega, 0.05)))
    assert out.shape == (46, 1492, 25)


def test_spectral_parts_46_walkers(benchmark, storeys):
    """The parts from the transfer's columns (the sampler's path)."""
    from hosid.components.chain_spectral_matrix import spectral_parts

    system, walkers, omega = storeys
    out = benchmark(lambda: spectral_parts(system, walkers, omega, 0.05))
    assert out.shape == (46, 1492, 25)
