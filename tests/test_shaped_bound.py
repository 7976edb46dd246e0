"""``analyses/shaped_bound.py``: the information limit under a narrow-band force.

Oracles: the white limit (wf -> inf on the same path), the linear oscillator (Whittle's
information of the Gaussian x process, by quadrature), closed forms of the excitation
block, and the frequency-domain form of the drift blocks.  Tolerances refer to the fixed
seeds below; the Monte Carlo errors quoted were measured over seeds.
"""

import importlib
import math
import sys
from pathlib import Path

import numpy as np
import pytest

ANALYSES = Path(__file__).resolve().parents[1] / "analyses"
PAPER = {"a1": 0.5, "n1": 0.5, "a2": 25.0, "n2": 5.0, "S0": 100.0}
#: linear oscillator of the Gaussian oracle
LIN = {"a1": 1.0, "n1": 0.0, "a2": 4.0, "n2": 0.0, "S0": 1.0}
LIN_WF, LIN_ZF, LIN_T = 3.0, 0.3, 1000.0


@pytest.fixture(scope="module")
def sb():
    sys.path.insert(0, str(ANALYSES))
    try:
        yield importlib.import_module("shaped_bound")
    finally:
        sys.path.remove(str(ANALYSES))
        sys.modules.pop("shaped_bound", None)


def _normalized_gap(a, b):
    s = np.sqrt(np.outer(np.diag(b), np.diag(b)))
    return np.abs(a - b) / s


def test_filter_step_keeps_the_stationary_law(sb):
    for wf, zf, h in [(7.0, 0.2, 0.002), (0.6, 0.05, 0.01), (1600.0, 0.7, 6e-5)]:
        Phi, C, Sigma = sb.filter_matrices(100.0, wf, zf, h)
        assert _normalized_gap(Phi @ Sigma @ Phi.T + C @ C.T, Sigma).max() < 1e-9


def test_excitation_block_closed_form(sb):
    # (T / 4 pi) int d log D d log D dw at fixed S0 wf^4 = T [[(1+zf^2)/(zf wf), 1], [1, wf/zf]]
    for wf, zf in [(3.0, 0.3), (0.6, 0.05), (13.0, 0.7)]:
        T = 500.0
        info = sb.excitation_information(wf, zf, T)
        ref = T * np.array([[(1 + zf**2) / (zf * wf), 1.0], [1.0, wf / zf]])
        np.testing.assert_allclose(info, ref, rtol=1e-7)


def test_linear_drift_block_is_the_white_one(sb):
    # P x has the spectrum S0 |H|^2 whatever L: I_a1a1 = T / (2 a1), I_a2a2 = T / (2 a1 a2)
    names, info = sb.linear_whittle(1.0, 4.0, 1.0, LIN_WF, LIN_ZF, duration=LIN_T)
    assert names == ("a1", "a2", "wf", "zf")
    np.testing.assert_allclose(info[:2, :2], [[500.0, 0.0], [0.0, 125.0]], rtol=1e-8, atol=1e-8)


def test_full_bound_is_the_limit_of_the_band_limited_one(sb):
    # with (S0, wf) both free the S0 wf^4 direction grows like omega_max; the bound of
    # the rest tends to the fixed-c one, and sd S0 to 4 S0 sd(wf) / wf
    _, info = sb.linear_whittle(1.0, 4.0, 1.0, LIN_WF, LIN_ZF, duration=LIN_T)
    sd = np.sqrt(np.diag(np.linalg.inv(info)))
    gaps = []
    for wmax in (100.0, 1e3, 1e4):
        _, I5 = sb.linear_whittle(1.0, 4.0, 1.0, LIN_WF, LIN_ZF, duration=LIN_T, omega_max=wmax)
        sd5 = np.sqrt(np.diag(np.linalg.inv(I5)))
        ref = np.array([sd[0], sd[1], 4.0 * sd[2] / LIN_WF, sd[2], sd[3]])
        gaps.append(np.max(np.abs(sd5 / ref - 1.0)))
    assert gaps[2] < 1e-3
    assert gaps[0] > 5 * gaps[1] > 25 * gaps[2]  # ~ 1 / omega_max


def test_rk4_with_hermite_force_is_fourth_order(sb):
    # no noise: the force decays deterministically (smooth), so the error falls as h^4
    p = np.array([0.5, 0.5, 25.0, 5.0])
    finals = {}
    for h in (0.02, 0.01, 0.005):
        Phi, C, _ = sb.filter_matrices(100.0, 7.0, 0.2, h)
        state = np.array([0.3, -1.0, 40.0, 100.0])
        n = round(4.0 / h)
        sb._advance(
            state, np.zeros((n, 2)), h, p, Phi, C, 7.0, 0.2, False, np.zeros(sb.N_ACC), False,
            np.zeros((0, 5)),
        )  # fmt: skip
        finals[h] = state[:2].copy()
    e1 = np.abs(finals[0.02] - finals[0.005]).max()
    e2 = np.abs(finals[0.01] - finals[0.005]).max()
    assert e2 < 1e-5
    assert e1 / e2 > 10.0  # 17 for exact fourth order


def test_randomness_only_from_the_generator(sb):
    kw = {"wf": 0.6, "zf": 0.05, "duration": 4000.0, "h": 0.02, "sim_duration": 8000.0}
    p = {"a1": 0.03, "n1": 0.15, "a2": 0.35, "n2": 0.2, "S0": 2.6e-4}
    a = sb.shaped_bound(p, rng=np.random.default_rng(3), **kw)
    b = sb.shaped_bound(p, rng=np.random.default_rng(3), **kw)
    c = sb.shaped_bound(p, rng=np.random.default_rng(4), **kw)
    np.testing.assert_array_equal(a.cov, b.cov)
    assert not np.array_equal(a.cov, c.cov)
    assert a.names == ("a1", "n1", "a2", "n2", "S0", "wf", "zf")
    assert set(a.sd) == {*a.names, "a1eq"}


def test_white_limit_on_the_same_path(sb):
    # wf = 1600 (Butterworth zf = 1/sqrt 2, resolved: wf h = 0.1): the shaped drift
    # information T/(2 pi S0) E[(P phi)(P phi)^T] is the white T/(2 pi S0) E[phi phi^T]
    # of the same path up to O(1/wf): measured 0.42 % (n1), 0.25 % (a1) at 1600, 1.7 % and
    # 1.0 % at 400, 7.8 % and 4.3 % at 100.  The a1 excess is E[v''^2] / wf^4 ~
    # pi S0 / (2 zf wf) over E[v^2] (the other cross terms cancel at zf = 1/sqrt 2).
    T, zf = 2000.0, 1.0 / math.sqrt(2.0)
    excess = {}
    for wf, h, sim in [(400.0, 2.5e-4, 400.0), (1600.0, 6.25e-5, 200.0)]:
        acc = sb.simulate_moments(
            PAPER, wf=wf, zf=zf, rng=np.random.default_rng(11), h=h, sim_duration=sim,
            burn_in=20.0, n_batches=1,
        )  # fmt: skip
        E = sb.moments(acc[0])
        _, info = sb.information(E, PAPER["S0"], wf, zf, T, known_excitation=True)
        W = T / (2.0 * math.pi * PAPER["S0"]) * E["FF"]
        gap = _normalized_gap(info, W).max()
        sd_ratio = np.sqrt(np.diag(np.linalg.inv(info)) / np.diag(np.linalg.inv(W)))
        if wf == 1600.0:
            assert gap < 0.006
            np.testing.assert_allclose(sd_ratio, 1.0, atol=0.008)
            predicted = math.pi * PAPER["S0"] / (2 * zf * wf) / E["var_v"]
            assert info[0, 0] / W[0, 0] - 1.0 == pytest.approx(predicted, rel=0.15)
        excess[wf] = info[0, 0] / W[0, 0] - 1.0
    assert excess[400.0] / excess[1600.0] == pytest.approx(4.0, rel=0.15)


def test_linear_oracle(sb):
    # Simulation-based information of (a1, a2, wf, zf) against Whittle's of the Gaussian
    # x process.  Monte Carlo error of a 40 000 s simulation (measured over 6 seeds at
    # 20 000 s, halved in variance): about 0.7 % on the information entries and 0.5-1.5 %
    # on the sds; tolerances 3 % (entries, relative to the diagonal) and 4 % (sds).
    _, ref = sb.linear_whittle(LIN["a1"], LIN["a2"], LIN["S0"], LIN_WF, LIN_ZF, duration=LIN_T)
    acc = sb.simulate_moments(
        LIN, wf=LIN_WF, zf=LIN_ZF, rng=np.random.default_rng(20260211), h=0.005,
        sim_duration=40000.0,
    )  # fmt: skip
    E = sb.moments(acc.sum(axis=0))
    # the force is the designed one
    assert E["var_f"] == pytest.approx(math.pi * LIN_WF / (2 * LIN_ZF), rel=0.02)
    assert E["var_df"] == pytest.approx(math.pi * LIN_WF**3 / (2 * LIN_ZF), rel=0.02)
    names, info = sb.information(E, LIN["S0"], LIN_WF, LIN_ZF, LIN_T)
    idx = [names.index(k) for k in ("a1", "a2", "wf", "zf")]
    got = info[np.ix_(idx, idx)]
    assert _normalized_gap(got, ref).max() < 0.03
    sd = np.sqrt(np.diag(np.linalg.inv(got)))
    sd_ref = np.sqrt(np.diag(np.linalg.inv(ref)))
    np.testing.assert_allclose(sd, sd_ref, rtol=0.04)
    # drift only: the white bound sd a1 = sqrt(2 a1 / T), sd a2 = sqrt(2 a1 a2 / T)
    drift = np.sqrt(np.diag(np.linalg.inv(got[:2, :2])))
    np.testing.assert_allclose(drift, [math.sqrt(2 / LIN_T), math.sqrt(8 / LIN_T)], rtol=0.03)


def test_spectral_form_matches_the_moment_form(sb):
    # The frequency-domain drift blocks (cross-periodograms, Hann, 65 536 samples) and the
    # time-domain P-form on the same 2000 s path agree: they weigh the samples differently
    # (the Hann windows), so they differ by a part of the sampling error (4000 s paths:
    # within 0.9 % of the diagonal).
    wf, zf, h, T = 7.0, 0.2, 0.002, 2000.0
    path = sb.simulate_path(
        PAPER, wf=wf, zf=zf, rng=np.random.default_rng(5), h=h, duration=2000.0
    )
    x, v, a, f, fd = path.T
    p = PAPER
    j = fd - (p["a1"] + 2 * p["n1"] * np.abs(v)) * a - (p["a2"] + 3 * p["n2"] * x**2) * v
    phi0 = np.stack([v, v * np.abs(v), x, x**3])
    phi1 = np.stack([a, 2 * np.abs(v) * a, v, 3 * x**2 * v])
    phi2 = np.stack([j, 2 * np.sign(v) * a**2 + 2 * np.abs(v) * j, a, 6 * x * v**2 + 3 * x**2 * a])
    P = phi0 + 2 * zf / wf * phi1 + phi2 / wf**2
    n = x.size
    E = {"PP": P @ P.T / n, "phi_f": phi0 @ f / n, "dphi_df": phi1 @ fd / n}
    _, info = sb.information(E, p["S0"], wf, zf, T)
    DD, DE = sb.spectral_information(path, p, wf=wf, zf=zf, h=h, duration=T, nperseg=1 << 16)
    assert _normalized_gap(DD, info[:4, :4]).max() < 0.02
    scale = np.sqrt(np.outer(np.diag(info[:4, :4]), np.diag(info[4:, 4:])))
    assert (np.abs(DE - info[:4, 4:]) / scale).max() < 0.02


def test_cli_one_case(sb, capsys):
    out = sb.main(["--system", "ship", "--wf", "0.6", "--zf", "0.05", "--sim-factor", "1"])
    assert len(out) == 1 and {"drift", "full"} <= set(out[0])
    text = capsys.readouterr().out
    assert "| ship | 0.6 | 0.05 | drift only |" in text and "| all 7 |" in text


@pytest.mark.slow
def test_white_case_reproduces_notes(sb):
    # NOTES.md: paper oscillator, S0 = 100, T = 2000 s; Monte Carlo error ~0.2 %
    b = sb.shaped_bound(
        PAPER, wf=None, zf=None, duration=2000.0, rng=np.random.default_rng(1), h=0.002
    )
    ref = {"a1": 0.221, "n1": 0.0192, "a2": 0.90, "n2": 0.236}
    for k, v in ref.items():
        assert b.sd[k] == pytest.approx(v, rel=0.02)


@pytest.mark.slow
def test_step_halving(sb):
    # paper oscillator, wf = 7, zf = 0.2: h = 0.002 and 0.001 agree within the Monte
    # Carlo error (about 0.3 % per sd; independent paths)
    res = []
    for h in (0.002, 0.001):
        b = sb.shaped_bound(
            PAPER, wf=7.0, zf=0.2, duration=2000.0, rng=np.random.default_rng(8), h=h
        )
        res.append((b.sd, b.mc))
    for k in ("a1", "n1", "a2", "n2", "wf", "zf"):
        se = math.hypot(res[0][1][k], res[1][1][k])
        assert res[0][0][k] / res[1][0][k] - 1.0 == pytest.approx(0.0, abs=4 * se + 0.002)


@pytest.mark.slow
def test_linear_oracle_long(sb):
    # 400 000 s: Monte Carlo error ~0.2 % on the entries
    _, ref = sb.linear_whittle(LIN["a1"], LIN["a2"], LIN["S0"], LIN_WF, LIN_ZF, duration=LIN_T)
    acc = sb.simulate_moments(
        LIN, wf=LIN_WF, zf=LIN_ZF, rng=np.random.default_rng(7), h=0.005,
        sim_duration=400000.0,
    )  # fmt: skip
    names, info = sb.information(sb.moments(acc.sum(axis=0)), LIN["S0"], LIN_WF, LIN_ZF, LIN_T)
    idx = [names.index(k) for k in ("a1", "a2", "wf", "zf")]
    got = info[np.ix_(idx, idx)]
    assert _normalized_gap(got, ref).max() < 0.01
    np.testing.assert_allclose(
        np.sqrt(np.diag(np.linalg.inv(got))), np.sqrt(np.diag(np.linalg.inv(ref))), rtol=0.015
    )
