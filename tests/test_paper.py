"""``analyses/paper_*.py`` and ``analyses/peer*.py``: the paper's figures and its peers.

Oracles: the printed costs against the block products and the force periodogram they
are built from; covariance-driven SSI and the IV regression against a linear
oscillator's known frequency and damping (tolerances: several standard deviations of
the estimates over seeds, measured on the fixed seeds below); the quick runs end to end.
"""

import importlib
import math
import sys
from pathlib import Path

import numpy as np
import pytest

import hosid
from hosid.components.base import feature_ffts, restoration
from hosid.components.spectral import force_periodogram
from hosid.inference.estimate import prepare_state

ANALYSES = Path(__file__).resolve().parents[1] / "analyses"
PAPER = {"a1": 0.5, "n1": 0.5, "a2": 25.0, "n2": 5.0, "S0": 100.0}
LINEAR = {"a1": 1.0, "n1": 0.0, "a2": 4.0, "n2": 0.0, "S0": 1.0}


@pytest.fixture(scope="module")
def mods():
    sys.path.insert(0, str(ANALYSES))
    names = ("paper_estimators", "paper_figures", "peer_methods", "peers")
    try:
        yield {n: importlib.import_module(n) for n in names}
    finally:
        sys.path.remove(str(ANALYSES))


@pytest.fixture(scope="module")
def record():
    return hosid.simulate(PAPER, duration=600.0, dt=0.02, rng=np.random.default_rng(5))


def test_j4a_map_is_the_block_products_exactly(mods, record):
    pe = mods["paper_estimators"]
    costs = pe.PrintedCosts(record, PAPER)
    a1 = np.array([-7.3, -0.5, 0.5, 2.2, 6.9])
    n1 = np.array([-0.9, -0.5, 0.5, 0.1, 0.8])
    fast = costs.j4a(a1, n1)
    direct = np.array([costs.direct_j4a(a, n) for a, n in zip(a1, n1, strict=True)])
    np.testing.assert_allclose(fast, direct, rtol=1e-9)


def test_j2_map_is_the_force_periodogram(mods, record):
    pe = mods["paper_estimators"]
    costs = pe.PrintedCosts(record, PAPER)
    model = hosid.Model.from_spec("paper")
    state = prepare_state(record, model, block_seconds=pe.BLOCK_SECONDS)
    bins = state.layout.bins(0.0, pe.OMEGA_MAX, k_min=1)
    theta = np.array([PAPER[p] for p in model.param_names])
    k2 = state.window.k2
    fp = force_periodogram(state, model, theta, bins)  # all five features, eq 45
    assert costs.j2(0.5, 0.5) == pytest.approx(np.sum((k2 * fp - k2 * 100.0) ** 2), rel=1e-9)
    # elsewhere on the map, the block transforms of every feature at the map's restoration
    s2, _ = restoration(state, model, theta)
    Y = feature_ffts(state, model, s2, bins)
    for a1, n1 in ((-3.0, 0.2), (6.0, -0.4), (-0.5, -0.5)):
        X = np.tensordot(np.array([1.0, a1, n1, 25.0, 5.0]), Y, axes=1)
        Va = np.mean(np.abs(X) ** 2, axis=0) / (2 * math.pi * state.layout.T)
        want = np.sum((Va - k2 * 100.0) ** 2)
        assert costs.j2(a1, n1) == pytest.approx(want, rel=1e-9)


def test_paper_estimators_give_their_parameters(mods, record):
    pe = mods["paper_estimators"]
    est = pe.point_estimates(record)
    assert set(est) == set(pe.ESTIMATORS)
    assert math.isnan(est["J2"]["a1"]) and math.isfinite(est["J2"]["a1eq"])
    assert math.isnan(est["moments"]["S0"])
    line = est["J4A line"]
    # on the line of eq (65) at J2's a1eq, inside the positive quadrant
    sv = prepare_state(record, hosid.Model.from_spec("paper"), block_seconds=20.48).scales.sigma_v
    assert line["a1"] + line["n1"] * pe.SQRT_8_PI * sv == pytest.approx(est["J2"]["a1eq"])
    assert line["a1"] >= 0 and line["n1"] >= 0
    # the moment method within 10 % on 600 s (its sd there is about 3 %)
    assert est["moments"]["a2"] == pytest.approx(25.0, rel=0.1)


@pytest.mark.parametrize("seed", [0, 1])
def test_ssi_and_iv_recover_a_linear_oscillator(mods, seed):
    pm = mods["peer_methods"]
    indep = importlib.import_module("independent_sim")
    rec, v = indep.simulate(LINEAR, duration=4000.0, dt=0.05, rng=np.random.default_rng(seed))
    ssi = pm.ssi_cov(rec.x, rec.dt)
    # omega_n = 2, zeta = 0.25: sd over seeds about 1.5 % and 3 %
    assert ssi["omega_n"] == pytest.approx(2.0, rel=0.05)
    assert ssi["zeta"] == pytest.approx(0.25, rel=0.1)
    iv = pm.iv_drift(rec.x, rec.dt, float(np.std(v)))
    for p in ("a1", "n1", "a2", "n2"):
        assert abs(iv[p] - LINEAR[p]) < 4 * iv[f"sd_{p}"] + 0.05 * abs(LINEAR[p])
    assert iv["S0"] == pytest.approx(1.0, rel=0.05)
    km = pm.km_drift(rec.x - rec.x.mean(), v, rec.dt, float(np.std(v)))
    assert km["a2"] == pytest.approx(4.0, rel=0.1)


def test_paper_quick_run_writes_every_figure(mods, tmp_path):
    pf = mods["paper_figures"]
    result = pf.main(["--quick", "--out", str(tmp_path)])
    for name in ("fig01_a2", "fig02_n2", "fig03_restoring_force", "fig04_a1eq", "fig05_S0",
                 "fig06_damping", "fig07_08_maps"):  # fmt: skip
        assert (tmp_path / f"{name}.png").stat().st_size > 10_000
    page = (tmp_path / "paper.md").read_text()
    for heading in ("Figures 1-2", "Figure 3", "Figures 4-5", "Figure 6", "Figures 7-8"):
        assert f"## {heading}" in page
    assert "*Paper:*" in page and "*Measured*" in page
    rows = (tmp_path / "paper.csv").read_text().splitlines()
    assert len(rows) - 1 == len(result["rows"]) == 2 * 5 + 2 * 3


def test_peers_quick_run_resumes(mods, tmp_path):
    peers = mods["peers"]
    peers.main(["--records", "1", "--regimes", "paper_S100", "--out", str(tmp_path),
                "--n-steps", "200"])  # fmt: skip
    rows = peers.read_rows(tmp_path / "records.csv")
    assert [r["method"] for r in rows] == list(peers.METHODS)
    assert rows[0]["record_hash"] == rows[-1]["record_hash"]
    page = (tmp_path / "peers.md").read_text()
    assert "| hosid |" in page and "| iv_regression |" in page
    peers.main(["--records", "1", "--regimes", "paper_S100", "--out", str(tmp_path)])
    assert len(peers.read_rows(tmp_path / "records.csv")) == len(rows)  # nothing redone
