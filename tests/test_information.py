"""The information limit: Cramer-Rao bound of the drift coefficients (NOTES.md table)."""

import math

import numpy as np
import pytest

from hosid.model import PAPER_PARAMS, Model
from hosid.model.information import cramer_rao

#: NOTES.md, "The information limit", S0 = 100, T = 2000 s.
NOTES_SD = {"a1": 0.221, "n1": 0.0192, "a2": 0.90, "n2": 0.236}


@pytest.fixture(scope="module")
def bound():
    # a 40 000 s simulation, ~1 s
    return cramer_rao("paper", PAPER_PARAMS, duration=2000.0, rng=np.random.default_rng(31))


def test_cramer_rao_reproduces_the_notes_table(bound):
    assert bound.names == ("a1", "n1", "a2", "n2")
    sd = bound.sd
    # the table came from one 40 000 s simulation too; this seed gives a1 0.2211, n1 0.01921,
    # a2 0.897, n2 0.2358 (three other seeds: all within 0.6 % of the table)
    for name, ref in NOTES_SD.items():
        assert sd[name] == pytest.approx(ref, rel=0.05), name
    assert bound.corr("a1", "n1") == pytest.approx(-0.94, abs=0.01)  # measured -0.938
    assert bound.corr("n1", "a1") == pytest.approx(bound.corr("a1", "n1"), rel=1e-12)
    assert bound.duration == 2000.0


def test_bound_is_the_inverse_girsanov_fisher_matrix(bound):
    cov = bound.cov
    assert cov.shape == (4, 4)
    np.testing.assert_allclose(cov, cov.T, rtol=1e-12)
    assert np.all(np.linalg.eigvalsh(cov) > 0)
    # a1eq = a1 + n1 sqrt(8/pi) sigma_v: its sd is g^T cov g
    g = np.array([1.0, math.sqrt(8 / math.pi) * bound.sigma_v, 0.0, 0.0])
    assert bound.sd["a1eq"] == pytest.approx(math.sqrt(g @ cov @ g), rel=1e-12)
    assert 7.0 < bound.sigma_v < 7.5  # the paper oscillator's velocity sd at S0 = 100
    # a1eq is much better determined than a1 or n1 (the valley of J2)
    assert bound.sd["a1eq"] < 0.5 * bound.sd["a1"]


def test_bound_scales_as_one_over_duration():
    kw = {"rng": np.random.default_rng(5), "sim_duration": 4000.0}
    short = cramer_rao("linear", {"a1": 1.0, "a2": 25.0, "S0": 10.0}, duration=500.0, **kw)
    kw["rng"] = np.random.default_rng(5)
    long = cramer_rao("linear", {"a1": 1.0, "a2": 25.0, "S0": 10.0}, duration=2000.0, **kw)
    np.testing.assert_allclose(short.cov, 4 * long.cov, rtol=1e-12)
    # linear oscillator: I = T / (2 pi S0) diag(E v^2, E x^2) = T / (2 pi S0) pi S0 (1/a1,
    # 1/(a1 a2)): sd a1 = sqrt(2 a1 / T), sd a2 = sqrt(2 a1 a2 / T); 4000 s of simulation
    # estimate E v^2 and E x^2 to ~2 %, so the sd to ~1 %
    assert long.sd["a1"] == pytest.approx(math.sqrt(2 * 1.0 / 2000.0), rel=0.03)
    assert long.sd["a2"] == pytest.approx(math.sqrt(2 * 25.0 / 2000.0), rel=0.03)
    assert long.sd["a1eq"] == pytest.approx(long.sd["a1"], rel=1e-12)


def test_bound_refuses_measurement_noise():
    model = Model.from_spec("linear,measurement_noise")
    with pytest.raises(ValueError, match="noise-free"):
        cramer_rao(
            model,
            {"a1": 1.0, "a2": 25.0, "S0": 10.0, "noise_sd": 0.01},
            duration=100.0,
            rng=np.random.default_rng(0),
            sim_duration=200.0,
        )
