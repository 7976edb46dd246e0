"""Session-scoped simulated records shared by the numerical tests.

Every record is drawn from its own ``numpy.random.default_rng`` with a fixed seed,
so the statistical tolerances in the tests refer to one fixed realization (the
numbers quoted in comments were measured on it).
"""

import numpy as np
import pytest

from hosid.simulate import PAPER_PARAMS, simulate

#: Linear oscillator used by the spectral oracles (S_x = S0 / |a2 - w^2 + i a1 w|^2).
LINEAR_PARAMS = {"a1": 1.0, "n1": 0.0, "a2": 25.0, "n2": 0.0, "S0": 10.0}

PAPER_SEED = 20240601
LINEAR_SEED = 20240602


@pytest.fixture(scope="session")
def paper_run():
    """Paper oscillator (S0 = 100), 2000 s at dt = 0.02: ``(record, simulated velocity)``."""
    return simulate(
        PAPER_PARAMS,
        duration=2000.0,
        dt=0.02,
        rng=np.random.default_rng(PAPER_SEED),
        return_velocity=True,
    )


@pytest.fixture(scope="session")
def paper_record(paper_run):
    return paper_run[0]


@pytest.fixture(scope="session")
def linear_params():
    return dict(LINEAR_PARAMS)


@pytest.fixture(scope="session")
def linear_run():
    """Linear oscillator, 4000 s at dt = 0.02 (195 blocks of 20.48 s)."""
    return simulate(
        LINEAR_PARAMS,
        duration=4000.0,
        dt=0.02,
        rng=np.random.default_rng(LINEAR_SEED),
        return_velocity=True,
    )


@pytest.fixture(scope="session")
def linear_record(linear_run):
    return linear_run[0]
