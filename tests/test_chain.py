"""The chain simulator, its records and the information limit of n degrees of freedom.

Oracles: the Lyapunov covariance of a linear 2-dof chain and of its interval-averaged
accelerations, with the exact standard error of a sample second moment of a Gaussian
sequence, var = (1/N) sum_k [R_aa(k) R_bb(k) + R_ab(k) R_ba(k)] (R(k) = expm(A dt)^k P);
the energy balance of a nonlinear chain, sum_e E[f_damp,e r'_e] = sum_d pi S0_d / m_d
(exact for white forces); the single oscillator's bound I = T / (2 pi S0) E[phi phi^T]
with E[v^2] = pi S0 / a1, E[x^2] = pi S0 / (a1 a2) (NOTES.md), and the exact Lyapunov
bound of a linear chain.  Tolerances are 4 standard errors (exact ones, or jackknife /
batch means where stated), all on fixed seeds.
"""

import importlib
import math
import sys
from pathlib import Path

import numpy as np
import pytest
from scipy import linalg

from hosid.errors import HosidInputError
from hosid.model.chain import simulate_chain, write_chain_record
from hosid.model.chain_information import chain_bound, linear_information, weights
from hosid.model.linear_chain import state_matrices, stationary_covariance
from hosid.model.system import System
from hosid.record import read_record

ANALYSES = Path(__file__).resolve().parents[1] / "analyses"
DT = 0.02

#: A linear 2-dof chain: modes 3.9 and 8.1 rad/s, damping ratios 0.09 and 0.13.
LINEAR2 = System(
    ("x1", "x2"),
    [(("ground", "x1"), ("linear",)), (("x1", "x2"), ("linear",))],
    values={
        "a1[ground-x1]": 1.0, "a2[ground-x1]": 25.0, "a1[x1-x2]": 0.5, "a2[x1-x2]": 15.0,
        "mass[x2]": 0.5, "S0[x1]": 10.0, "S0[x2]": 5.0,
    },
)  # fmt: skip


def _lag_covariances(A, P, dt, n_lags):
    """R(k) = E[s(t + k dt) s(t)^T] = expm(A dt)^k P, k = 0 .. n_lags - 1."""
    step = linalg.expm(A * dt)
    out = [P]
    for _ in range(n_lags - 1):
        out.append(step @ out[-1])
    return np.array(out)


def _second_moment_se(R, n):
    """Exact sd of the sample mean of s_a s_b over n samples of a Gaussian sequence."""
    aa = np.einsum("kaa->ka", R)
    terms = aa[:, :, None] * aa[:, None, :] + R * np.swapaxes(R, 1, 2)
    total = terms[0] + 2.0 * terms[1:].sum(axis=0)
    return np.sqrt(total / n)


@pytest.fixture(scope="module")
def linear_run():
    return simulate_chain(
        LINEAR2, duration=1000.0, dt=DT, rng=np.random.default_rng(32001), return_state=True,
        measured={"x2": "acceleration"},
    )  # fmt: skip


def test_linear_chain_state_covariance_is_lyapunov(linear_run):
    record, q, v = linear_run
    s = np.hstack([q, v])
    P = stationary_covariance(LINEAR2)
    A, _ = state_matrices(LINEAR2)
    rate = np.min(-np.linalg.eigvals(A).real)
    R = _lag_covariances(A, P, DT, int(25.0 / (rate * DT)))
    se = _second_moment_se(R, s.shape[0])
    z = (s.T @ s / s.shape[0] - P) / se
    assert np.abs(z).max() < 4.0, z
    # the displacement channel holds q itself
    np.testing.assert_array_equal(record.channel("x1").x, q[:, 0])


def test_acceleration_channel_is_the_interval_average(linear_run):
    # Cov(a) = (2 P_vv - R_vv(dt) - R_vv(dt)^T) / dt^2 at lag 0; at lag k >= 1 the lagged
    # covariances 2 R(k dt) - R((k + 1) dt) - R((k - 1) dt) (R(-t) = R(t)^T)
    record, _, _ = linear_run
    A, _ = state_matrices(LINEAR2)
    P = stationary_covariance(LINEAR2)
    rate = np.min(-np.linalg.eigvals(A).real)
    Rv = _lag_covariances(A, P, DT, int(25.0 / (rate * DT)) + 2)[:, 2:, 2:]
    Ra = np.empty_like(Rv[:-1])
    Ra[0] = 2 * Rv[0] - Rv[1] - Rv[1].T
    Ra[1:] = 2 * Rv[1:-1] - Rv[2:] - Rv[:-2]
    Ra /= DT**2
    a2 = record.channel("x2").x
    se = _second_moment_se(Ra[:, 1:, 1:], a2.size)[0, 0]
    assert record.measured == ("displacement", "acceleration")
    assert abs(np.mean(a2**2) - Ra[0, 1, 1]) < 4.0 * se, (np.mean(a2**2), Ra[0, 1, 1], se)
    # the white part dominates: 2 pi S0 / (m^2 dt) is most of the variance
    assert 0.5 < 2 * math.pi * 5.0 / (0.25 * DT) / Ra[0, 1, 1] < 1.0


def test_energy_balance_of_a_nonlinear_chain():
    # sum_e E[(a1 r' + n1 r'|r'|) r'] = sum_d pi S0_d / m_d (Ito, stationary)
    s = System(
        ("x1", "x2"),
        [(("ground", "x1"), ("paper",)), (("x1", "x2"), ("linear", "cubic_stiffness"))],
        values={
            "a1[ground-x1]": 0.3, "n1[ground-x1]": 0.1, "a2[ground-x1]": 25.0,
            "n2[ground-x1]": 5.0, "a1[x1-x2]": 0.2, "a2[x1-x2]": 15.0, "n2[x1-x2]": 10.0,
            "mass[x2]": 0.8, "S0[x1]": 2.0, "S0[x2]": 2.0,
        },
    )  # fmt: skip
    _, _, v = simulate_chain(s, duration=4000.0, dt=DT, rng=np.random.default_rng(32002),
                             return_state=True)  # fmt: skip
    rd = v @ s.incidence.T
    power = 0.3 * rd[:, 0] ** 2 + 0.1 * np.abs(rd[:, 0]) ** 3 + 0.2 * rd[:, 1] ** 2
    batches = power[: power.size // 20 * 20].reshape(20, -1).mean(axis=1)
    se = batches.std(ddof=1) / math.sqrt(20)  # batch means (200 s each)
    expected = math.pi * 2.0 / 1.0 + math.pi * 2.0 / 0.8
    assert abs(power.mean() - expected) < 4 * se, (power.mean(), expected, se)
    assert se / expected < 0.04  # measured 2.4 %


def test_simulation_is_seeded_and_checked():
    kw = {"duration": 20.0, "dt": DT}
    a = simulate_chain(LINEAR2, rng=np.random.default_rng(5), **kw)
    b = simulate_chain(LINEAR2, rng=np.random.default_rng(5), **kw)
    np.testing.assert_array_equal(a.x, b.x)
    assert a.x.shape == (1000, 2) and a.channels == ("x1", "x2")
    with pytest.raises(TypeError):
        simulate_chain(LINEAR2, rng=5, **kw)
    with pytest.raises(HosidInputError, match="substeps must be even"):
        simulate_chain(LINEAR2, rng=np.random.default_rng(1), substeps=5, **kw)
    with pytest.raises(HosidInputError, match="too coarse"):
        simulate_chain(LINEAR2, rng=np.random.default_rng(1), duration=100.0, dt=0.2)
    with pytest.raises(HosidInputError, match="values missing"):
        simulate_chain(System.single("paper"), rng=np.random.default_rng(1), **kw)
    with pytest.raises(HosidInputError, match="S0 must be positive"):
        bad = {**dict(LINEAR2.values), "S0[x2]": 0.0}
        simulate_chain(LINEAR2, bad, rng=np.random.default_rng(1), **kw)
    with pytest.raises(HosidInputError, match="measured must be"):
        simulate_chain(LINEAR2, rng=np.random.default_rng(1), measured="velocity", **kw)


def test_writer_csv_and_npz(tmp_path):
    rec = simulate_chain(LINEAR2, duration=10.0, dt=DT, rng=np.random.default_rng(7),
                         measured="acceleration")  # fmt: skip
    path = write_chain_record(rec, tmp_path / "chain.csv")
    assert path.read_text().splitlines()[0] == "t,x1,x2"
    data = np.loadtxt(path, delimiter=",", skiprows=1)
    np.testing.assert_allclose(data[:, 0], rec.t, rtol=1e-14, atol=1e-14)
    np.testing.assert_allclose(data[:, 1:], rec.x, rtol=1e-9)
    with np.load(write_chain_record(rec, tmp_path / "chain.npz"), allow_pickle=False) as z:
        np.testing.assert_array_equal(z["x2"], rec.x[:, 1])
        assert tuple(z["dofs"]) == ("x1", "x2") and float(z["dt"]) == DT
        assert tuple(z["measured"]) == ("acceleration", "acceleration")
    # one dof named x: today's single-channel files
    single = System.single("linear", {"a1": 1.0, "a2": 25.0, "S0": 1.0})
    one = simulate_chain(single, duration=10.0, dt=DT, rng=np.random.default_rng(8))
    for suffix in (".csv", ".npz"):
        back = read_record(write_chain_record(one, tmp_path / f"one{suffix}"))
        np.testing.assert_allclose(back.x, one.x, rtol=1e-9)
        assert back.dt == pytest.approx(DT, rel=1e-12)
    with pytest.raises(HosidInputError, match=r"use \.csv or \.npz"):
        write_chain_record(rec, tmp_path / "chain.txt")
    assert one.channels == ("x",) and one.x.shape == (500,)  # one dof: a 1-D record


def test_bound_of_the_linear_single_oscillator():
    # I = T diag(1 / (2 a1), 1 / (2 a1 a2)): sd a1 = sqrt(2 a1 / T), sd a2 = sqrt(2 a1 a2 / T)
    a1, a2, S0, T = 2.0, 25.0, 10.0, 2000.0
    s = System.single("linear", {"a1": a1, "a2": a2, "S0": S0})
    exact = np.array([math.sqrt(2 * a1 / T), math.sqrt(2 * a1 * a2 / T)])
    info = linear_information(s, duration=T)
    np.testing.assert_allclose(info, np.diag([T / (2 * a1), T / (2 * a1 * a2)]), rtol=1e-10,
                               atol=1e-8)  # fmt: skip
    bound = chain_bound(s, duration=T, rng=np.random.default_rng(32003), sim_duration=2000.0)
    sd = np.array(list(bound.sd.values()))
    # Monte Carlo error: relative sd of E[v^2] over L seconds sqrt(2 / (a1 L)) = 2.2 %,
    # of sd a1 half that; the jackknife's estimate agrees
    assert np.all(np.abs(sd / exact - 1) < 4 * bound.sd_se / exact), (sd, exact, bound.sd_se)
    assert np.all(bound.sd_se / exact < 0.03)


def test_bound_of_a_linear_chain_against_lyapunov():
    T = 2000.0
    exact = np.sqrt(np.diag(np.linalg.inv(linear_information(LINEAR2, duration=T))))
    bound = chain_bound(LINEAR2, duration=T, rng=np.random.default_rng(32004),
                        sim_duration=4000.0)  # fmt: skip
    sd = np.array(list(bound.sd.values()))
    assert bound.names == LINEAR2.param_names[:4]
    assert np.all(np.abs(sd - exact) < 4 * bound.sd_se), (sd, exact, bound.sd_se)


def test_bound_with_an_undriven_dof():
    s = System(LINEAR2.dofs, LINEAR2.elements, masses={"x2": 0.5}, driven=["x2"])
    values = [1.0, 25.0, 0.5, 15.0, 5.0]
    # only x2's equation informs: its element's coefficients; the ground's get NaN
    W = weights(s, values)
    np.testing.assert_allclose(np.diag(W), np.array([0, 0, 1, 1]) / (2 * math.pi * 5.0))
    bound = chain_bound(s, values, duration=2000.0, rng=np.random.default_rng(9),
                        sim_duration=400.0)  # fmt: skip
    assert np.isnan(bound.sd["a1[ground-x1]"]) and np.isnan(bound.sd["a2[ground-x1]"])
    assert np.isfinite(bound.sd["a1[x1-x2]"]) and np.isfinite(bound.sd["a2[x1-x2]"])


@pytest.fixture
def chain_bound_script():
    sys.path.insert(0, str(ANALYSES))
    try:
        yield importlib.import_module("chain_bound")
    finally:
        sys.path.remove(str(ANALYSES))
        sys.modules.pop("chain_bound", None)


def test_chain_bound_script_quick(chain_bound_script, tmp_path):
    results = chain_bound_script.main(["--quick", "--out", str(tmp_path)])
    assert set(results) == {"paper", "chain2", "chain3"}
    rows = [r for res in results.values() for r in res["rows"]]
    assert len(rows) == 4 + 7 + 10
    assert all(math.isfinite(r["sd"]) and r["sd"] > 0 for r in rows)
    text = (tmp_path / "chain_bound.md").read_text()
    assert "| chain3 | n1[x2-x3] |" in text
    assert (tmp_path / "chain_bound.csv").read_text().count("\n") == len(rows) + 1
    again = System.from_toml(tmp_path / "chain_bound_chain3.toml")
    assert again.n == 3 and len(again.values) == len(again.param_names)
