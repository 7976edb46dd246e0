"""The exchange of shaping filter and oscillator: the mirror start and the side the
trispectrum keeps (hosid.inference.swap)."""

import importlib
import sys
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from hosid.inference import swap
from hosid.inference.estimate import estimate
from hosid.model import Model

NB = Model.from_spec("paper,narrowband_excitation")
ANALYSES = Path(__file__).resolve().parents[1] / "analyses"


def _state(sigma_x=0.05, sigma_v=0.03):
    return SimpleNamespace(scales=SimpleNamespace(sigma_x=sigma_x, sigma_v=sigma_v))


def _response(theta, w):
    """The displacement spectrum of the linear system (n1 = n2 = 0): filter times
    oscillator, S0 wf^4 / (|wf^2 - w^2 + 2i zf wf w|^2 |a2 - w^2 + i a1 w|^2)."""
    p = NB.params(theta)
    filt = (p["wf"] ** 2 - w**2) ** 2 + (2 * p["zf"] * p["wf"] * w) ** 2
    osc = (p["a2"] - w**2) ** 2 + (p["a1"] * w) ** 2
    return p["S0"] * p["wf"] ** 4 / (filt * osc)


def test_mirror_of_a_linear_system_keeps_its_response_and_is_its_own_inverse():
    theta = NB.vector({"a1": 0.03, "n1": 0.0, "a2": 0.35, "n2": 0.0, "S0": 2.6e-4,
                       "wf": 0.7, "zf": 0.25})  # fmt: skip
    m = swap.mirror(_state(), NB, theta)
    p = NB.params(m)
    assert p["wf"] == pytest.approx(0.35**0.5, rel=1e-12)
    assert p["zf"] == pytest.approx(0.03 / (2 * 0.35**0.5), rel=1e-12)
    assert p["a1"] == pytest.approx(2 * 0.25 * 0.7, rel=1e-12)
    assert p["a2"] == pytest.approx(0.49, rel=1e-12)
    w = np.linspace(0.05, 3.0, 200)
    np.testing.assert_allclose(_response(m, w), _response(theta, w), rtol=1e-12)
    np.testing.assert_allclose(swap.mirror(_state(), NB, m), theta, rtol=1e-12)


def test_mirror_trades_the_equivalent_linear_pair_and_keeps_the_nonlinear_terms():
    st = _state()
    theta = NB.vector({"a1": 0.03, "n1": 0.15, "a2": 0.35, "n2": 0.2, "S0": 2.6e-4,
                       "wf": 0.6, "zf": 0.25})  # fmt: skip
    m = NB.params(swap.mirror(st, NB, theta))
    c = 0.03 + 0.15 * np.sqrt(8 / np.pi) * st.scales.sigma_v
    k = 0.35 + 3 * 0.2 * st.scales.sigma_x**2
    assert (m["n1"], m["n2"]) == (0.15, 0.2)
    assert m["a1"] + 0.15 * np.sqrt(8 / np.pi) * st.scales.sigma_v == pytest.approx(0.3)
    assert m["a2"] + 3 * 0.2 * st.scales.sigma_x**2 == pytest.approx(0.36)
    assert (m["wf"], m["zf"]) == (pytest.approx(k**0.5), pytest.approx(c / (2 * k**0.5)))
    assert m["S0"] * m["wf"] ** 4 == pytest.approx(2.6e-4 * 0.6**4)
    assert swap.mirror(st, Model.from_spec("paper"), theta[:5]) is None


def _found(js):
    """Solutions whose own J is ``js[i]`` (a constant quasi-likelihood)."""
    return [(np.full(7, float(i + 1)), lambda th, J=J: -J / 2.0, None) for i, J in enumerate(js)]


@pytest.mark.parametrize(
    ("rejects", "kept"),
    [
        ({(1, 0)}, 1),  # 1's J4B rejects 0, 0's does not reject 1: 1's side
        ({(1, 0), (0, 1)}, 0),  # each rejects the other: the trispectrum does not choose
        ({(0, 1)}, 0),  # 0's J4B rejects 1: 0 stays
        ({(2, 0)}, 0),  # 2 rejects 0 but fails its own Hansen test
        ({(1, 0), (3, 0)}, 3),  # two see 0 from the true side: the smaller own J
    ],
)
def test_the_side_kept_is_the_one_whose_trispectrum_sees_the_other(monkeypatch, rejects, kept):
    found = _found([3.0, 6.0, 60.0, 5.0])

    def term(state, model, theta):  # J4B frozen at solution i, evaluated at solution j
        i = int(theta[0]) - 1
        return lambda th: 2 * swap.FLOOR if (i, int(th[0]) - 1) in rejects else -0.5

    monkeypatch.setattr(swap, "_term", term)
    assert swap.trispectral_side(None, NB, found, 0, df=7) == kept


@pytest.fixture(scope="module")
def swapped_record():
    """A ship-roll-like record under a broad filter at its resonance (independent
    simulator, 4000 s) whose estimate from the pilots alone is the swapped one (zf 0.09
    against 0.25, a1 0.17 against 0.03)."""
    sys.path.insert(0, str(ANALYSES))
    try:
        sim = importlib.import_module("independent_sim")
        truth = {"a1": 0.03, "n1": 0.15, "a2": 0.35, "n2": 0.2, "S0": 2.6e-4, "wf": 0.6,
                 "zf": 0.25}  # fmt: skip
        rec, _ = sim.simulate(truth, duration=4000.0, dt=0.1, rng=np.random.default_rng([305, 77]))
    finally:
        sys.path.remove(str(ANALYSES))
        sys.modules.pop("independent_sim", None)
        sys.modules.pop("independent_forces", None)
    return rec


def test_the_mirror_start_brings_a_swapped_estimate_back(swapped_record, monkeypatch):
    est = estimate(swapped_record, NB, simulations=0)
    p = est.model.params(est.theta)
    assert p["zf"] > 0.2 and p["a1"] < 0.06  # measured 0.274 and 0.028
    search = importlib.import_module("hosid.inference.search")
    monkeypatch.setattr(search, "mirror", lambda *a: None)
    p = NB.params(estimate(swapped_record, NB, simulations=0).theta)
    assert p["zf"] < 0.15 and p["a1"] > 0.1  # measured 0.092 and 0.170
