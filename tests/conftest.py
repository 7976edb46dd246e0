"""Session-scoped simulated records shared by the numerical tests.

Every record is drawn from its own ``numpy.random.default_rng`` with a fixed seed, so
the statistical tolerances in the tests refer to one fixed realization (the numbers
quoted in the tests' comments were measured on these records).
"""

import numpy as np
import pytest

from hosid.model import PAPER_PARAMS, simulate

#: Linear oscillator of the spectral and variance oracles:
#: S_x = S0 / |a2 - w^2 + i a1 w|^2, E[x^2] = pi S0 / (a1 a2), E[v^2] = pi S0 / a1.
LINEAR_PARAMS = {"a1": 1.0, "a2": 25.0, "S0": 10.0}

PAPER_SEED = 20260101
LINEAR_SEED = 20260107
SHORT_SEED = 20260103


@pytest.fixture(scope="session")
def paper_run():
    """Paper oscillator (S0 = 100), 2000 s at dt = 0.02: ``(record, simulated velocity)``."""
    return simulate(
        PAPER_PARAMS,
        duration=2000.0,
        dt=0.02,
        rng=np.random.default_rng(PAPER_SEED),
        name="paper",
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
    """Linear oscillator, 4000 s at dt = 0.02: ``(record, simulated velocity)``."""
    return simulate(
        LINEAR_PARAMS,
        duration=4000.0,
        dt=0.02,
        rng=np.random.default_rng(LINEAR_SEED),
        name="linear",
        return_velocity=True,
    )


@pytest.fixture(scope="session")
def linear_record(linear_run):
    return linear_run[0]


@pytest.fixture(scope="session")
def short_paper_record():
    """Paper oscillator, 500 s at dt = 0.02 (24 blocks of 1024 samples)."""
    return simulate(
        PAPER_PARAMS,
        duration=500.0,
        dt=0.02,
        rng=np.random.default_rng(SHORT_SEED),
        name="short",
    )
