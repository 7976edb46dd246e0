"""Estimators on one simulated paper record (S0 = 100, 2000 s, fixed seed)."""

import numpy as np
import pytest

from hosid.errors import HosidInputError
from hosid.estimators import SQRT_8_PI, estimate
from hosid.simulate import PAPER_PARAMS

P = PAPER_PARAMS


@pytest.fixture(scope="module")
def paper_estimate(paper_record):
    return estimate(paper_record, method="paper")


def test_moments_stiffness(paper_record):
    est = estimate(paper_record, method="moments")["estimates"]
    # NOTES.md: the moment method scatters a2 by ~3 % and n2 by ~4 % between 2000 s
    # records; damping terms neglected bias a2 by up to -5 %. Measured on this record
    # (seed 20240601): a2 = 23.81 (-4.8 %), n2 = 5.17 (+3.3 %).
    assert est["a2"] == pytest.approx(P["a2"], rel=0.06)
    assert est["n2"] == pytest.approx(P["n2"], rel=0.15)
    for key in ("a1", "n1", "S0", "a1eq"):
        assert np.isnan(est[key])


def test_paper_protocol(paper_estimate, paper_run):
    _, v = paper_run
    est = paper_estimate["estimates"]
    a1eq_true = P["a1"] + P["n1"] * SQRT_8_PI * np.std(v)  # eq (65), sqrt(8/pi)
    # tolerances: J2 level and a1eq scatter a few % between records; a1eq of the
    # Gaussian linearization itself is only approximate for n1 sigma_v ~ a1eq
    assert est["S0"] == pytest.approx(P["S0"], rel=0.10)
    assert est["a1eq"] == pytest.approx(a1eq_true, rel=0.10)
    # refined moments (damping terms kept): a2 within 3 %, n2 within 10 %.
    # Measured: S0 = 97.6 (-2.4 %), a1eq = 6.60 vs 6.32 (+4.4 %), a2 = 24.45 (-2.2 %),
    # n2 = 5.13 (+2.6 %); a1 = 1.06, n1 = 0.475 (not asserted).
    assert est["a2"] == pytest.approx(P["a2"], rel=0.03)
    assert est["n2"] == pytest.approx(P["n2"], rel=0.10)
    assert est["a1"] >= 0 and est["n1"] >= 0
    assert est["a1"] + est["n1"] * SQRT_8_PI * np.std(v) == pytest.approx(est["a1eq"], rel=0.05)


def test_estimate_output_structure(paper_estimate):
    out = paper_estimate
    assert set(out) == {"method", "estimates", "settings"}
    assert out["method"] == "paper"
    assert set(out["estimates"]) == {"a1", "n1", "a2", "n2", "S0", "a1eq"}
    assert all(isinstance(v, float) for v in out["estimates"].values())
    assert out["settings"] == {
        "window": "hann",
        "block_seconds": 20.48,
        "omega_max": 8.0,
        "domain": "principal",
        "form": "scaled",
        "derivative": "spectral",
    }


@pytest.mark.parametrize("method", ["J5", "", "Paper"])
def test_unknown_method_raises(paper_record, method):
    with pytest.raises(HosidInputError, match="unknown method"):
        estimate(paper_record, method=method)
