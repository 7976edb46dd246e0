"""Poisson impulses (``impulsive_excitation``): the simulator's force, the jump terms of
the generator identities against closed forms, the kink constants, and the estimate.
"""

import math

import numpy as np
import pytest

from hosid.components.jumps import GRID, jump_table, kink_constants, read_table
from hosid.errors import HosidInputError
from hosid.inference.correction import bias, shifted
from hosid.inference.estimate import estimate
from hosid.model import Model
from hosid.model.simulate import poisson_impulses, simulate

IMP = "paper,impulsive_excitation"
PAPER = {"a1": 0.5, "n1": 0.5, "a2": 25.0, "n2": 5.0, "S0": 100.0}


def test_impulses_have_the_white_level_and_the_poisson_fourth_cumulant():
    # over windows of n sub-steps the summed areas have variance 2 pi S0 tau and fourth
    # cumulant 3 (2 pi S0)^2 tau / r (tau = n h): 2 % and 10 % at 200 000 windows
    rng = np.random.default_rng(1)
    h, S0, rate, n = 0.001, 3.0, 5.0, 200
    dW, dZ = poisson_impulses(200_000 * n, h, S0, rate, rng)
    w = dW.reshape(-1, n).sum(axis=1)
    tau = n * h
    assert w.var() == pytest.approx(2 * math.pi * S0 * tau, rel=0.02)
    k4 = np.mean(w**4) - 3 * w.var() ** 2
    assert k4 == pytest.approx(3 * (2 * math.pi * S0) ** 2 * tau / rate, rel=0.1)
    # the displacement's extra share A (h/2 - s): mean 0, variance sigma_A^2 h^2/12 per impulse
    assert dZ.var() == pytest.approx(2 * math.pi * S0 * h * h**2 / 12, rel=0.05)


def test_simulate_rejects_impulses_with_a_shaped_force():
    with pytest.raises(HosidInputError, match="impulse"):
        simulate({"a1": 1, "a2": 25, "S0": 1, "rate": 2, "wc": 5}, duration=10,
                 rng=np.random.default_rng(0))  # fmt: skip
    with pytest.raises(ValueError, match="impulsive_excitation"):
        Model.from_spec("paper,impulsive_excitation,coloured_excitation")


def test_jump_table_against_closed_forms():
    # G = v^2 / 2 (psi = v): e = 1 whatever the area; G = v^4 / 4 (psi = v^3): the jump
    # generator's mean is (3/2) sigma^2 E(v^2 + s2) + (3/4) sigma^4, so
    # e = 3 E(v^2 + s2) + (3/2) sigma^2 (Gaussian moments; the grid of 0.02 sd and its
    # linear interpolation leave 3e-4)
    rng = np.random.default_rng(2)
    v = rng.normal(0.0, 1.3, (3, 4000))
    s2 = 0.05
    sv = float(v.std())
    quad = jump_table(lambda u: u**2 / 2, v, s2, sv)
    np.testing.assert_allclose(quad, 1.0, rtol=1e-4)
    quart = jump_table(lambda u: u**4 / 4, v, s2, sv)
    var = GRID * sv**2
    want = 3 * (np.mean(v**2, axis=1)[:, None] + s2) + 1.5 * var[None, :]
    np.testing.assert_allclose(quart, want, rtol=1e-3)
    # read off between grid points: linear in log sigma^2, held at the ends
    mid = math.sqrt(var[10] * var[11])
    got = read_table(quart, np.array([mid, 1e-9, 1e9]), sv)
    assert got.shape == (3, 3)
    np.testing.assert_allclose(got[0], 0.5 * (quart[:, 10] + quart[:, 11]))
    np.testing.assert_allclose(got[1], quart[:, 0])
    np.testing.assert_allclose(got[2], quart[:, -1])


def test_kink_constants_exceed_the_ideal_low_pass():
    # the ideal low-pass of a unit impulse has int k^2 = 1/dt and int k^4 = (2/3)/dt^3;
    # the sampled kink's aliases add power to both
    c2, c4 = kink_constants()
    assert 1.0 < c2 < 1.2
    assert 2 / 3 < c4 < 1.4


@pytest.mark.parametrize("rate", [1.0, 4.0])
def test_estimate_recovers_an_impulsive_record(rate):
    # the paper oscillator under impulses, 2000 s, without the sampling-bias correction:
    # the drift within 3.5 sd of the truth; the rate within 30 % (the kink constant
    # overstates the kurtosis: the impulses' fast decay under quadratic damping rounds
    # the kink; about +15-20 % on the rate)
    truth = {"a1": 0.5, "n1": 0.5, "a2": 25.0, "n2": 5.0, "S0": 100.0}
    rec = simulate({**truth, "rate": rate}, duration=2000.0, rng=np.random.default_rng(7))
    est = estimate(rec, IMP, force=True, simulations=0)
    for k in ("a1", "n1", "a2", "n2", "S0"):
        assert abs(est.values[k] - truth[k]) < 3.5 * est.sd[k], k
    assert est.values["rate"] == pytest.approx(rate, rel=0.3)


def test_bias_correction_inverts_a_known_bias():
    # a toy estimator with a known bias (the "record" is its parameters): a ratio bias
    # 0.8 on a positive parameter is undone in one step; an additive bias -0.2 theta on
    # another converges as 1 + 0.2 + 0.2^2 ..., 1.24 after two evaluations
    theta_hat = np.array([2.0, 5.0])
    positive = np.array([False, True])

    def est(rec):
        return np.array([0.8 * rec[0], 0.8 * rec[1]])

    beta, spread = bias(
        est, lambda th, rng: th, theta_hat, positive, np.random.default_rng(0), n=3
    )
    moved = np.where(positive, theta_hat * np.exp(-beta), theta_hat - beta)
    np.testing.assert_allclose(moved, [2.0 * 1.24, 5.0 / 0.8], rtol=1e-12)
    np.testing.assert_allclose(spread, [0.0, 0.0], atol=1e-12)  # a deterministic estimator
    # a noisy one: additive noise of sd 0.3 and relative noise of sd 0.1, pooled within
    # the iterations (2 x 399 degrees of freedom: the sd within 10 %)
    rng = np.random.default_rng(1)

    def noisy(rec, rng=rng):
        return np.array(
            [rec[0] + 0.3 * rng.standard_normal(), rec[1] * np.exp(0.1 * rng.standard_normal())]
        )

    _, spread = bias(noisy, lambda th, r: th, theta_hat, positive, np.random.default_rng(2), n=400)
    np.testing.assert_allclose(spread, [0.3, 0.1], rtol=0.1)


def test_widening_only_where_the_spread_exceeds_the_curvature_beyond_chance():
    from hosid.inference.correction import widening

    # 14 df: the 95 % point of chi2/df is 1.69, of its square root 1.30
    w = widening(np.array([1.6, 1.2, 0.5]), np.ones(3), df=14)
    np.testing.assert_allclose(w, [1.6, 1.0, 1.0])
    # a bootstrapped parameter takes its spread, as Student's t on 14 df widens a
    # predictive interval at 90 % (t_14 1.7613 / z 1.6449 = 1.0708), whenever that is the
    # larger
    always = np.array([False, True, True, True])
    w = widening(np.array([1.2, 1.2, 0.5, 0.95]), np.ones(4), df=14, always=always)
    np.testing.assert_allclose(w, [1.0, 1.2 * 1.0708, 1.0, 0.95 * 1.0708], rtol=1e-4)


def test_shifted_quasi_likelihood_peaks_at_the_corrected_estimate():
    # l(theta + b) has its mode at theta_hat - b (theta_hat e^-b for a positive one) and
    # is flatter by 1 + 1/n
    from hosid.components.base import Moments
    from hosid.inference.gmm import quasi_likelihood

    rng = np.random.default_rng(3)
    U = rng.normal(size=(50, 2))
    m = Moments("toy", ("a", "b"), lambda th: np.asarray(th) - [1.0, 2.0], U - U.mean(0))
    ql = quasi_likelihood([m], n_params=2)
    positive = np.array([False, True])
    beta = np.array([0.5, np.log(1.25)])
    q = shifted(ql, beta, positive, n=4)
    mode = np.array([1.0 - 0.5, 2.0 / 1.25])
    assert q(mode) == pytest.approx(0.0, abs=1e-12)
    step = np.array([0.1, 0.0])
    assert q(mode + step) == pytest.approx(ql(np.array([1.1, 2.0])) / 1.25, rel=1e-12)
    # widened twofold in the first parameter about the mode: a step of 0.2 there is the
    # unwidened step of 0.1; widened 1.5-fold in the second (relative): the ratio
    # 1.1^1.5 there is the unwidened ratio 1.1; the mode stays
    w = shifted(ql, beta, positive, n=4, centre=mode, widen=np.array([2.0, 1.5]))
    assert w(mode) == pytest.approx(0.0, abs=1e-12)
    assert w(mode + np.array([0.2, 0.0])) == pytest.approx(q(mode + step), rel=1e-12)
    up = mode * [1.0, 1.1**1.5]
    assert w(up) == pytest.approx(q(mode * [1.0, 1.1]), rel=1e-12)


def test_estimate_corrects_an_impulsive_record_and_says_so():
    rec = simulate({**PAPER, "rate": 1.0}, duration=300.0, rng=np.random.default_rng(8))
    raw = estimate(rec, IMP, force=True, simulations=0)
    est = estimate(rec, IMP, force=True, simulations=2)
    assert any("sampling bias" in n for n in est.notes)
    assert est.excitation_test["p_value"] < 1e-3  # the impulses show: kept
    assert not np.allclose(est.theta, raw.theta)
    # the same record gives the same estimate (the simulations' seed is the record's)
    again = estimate(rec, IMP, force=True, simulations=2)
    np.testing.assert_array_equal(again.theta, est.theta)
    # a white record: many impulses a sample at the estimate, nothing to correct; and the
    # record does not reject the white Gaussian force, so the white model is estimated
    white = simulate(PAPER, duration=300.0, rng=np.random.default_rng(9))
    est = estimate(white, IMP, force=True, simulations=2, settle=False)
    assert est.values["rate"] * white.dt > 1.0
    assert not any("sampling bias" in n for n in est.notes)
    settled = estimate(white, IMP, force=True, simulations=2)
    assert settled.model.names == Model.from_spec("paper").names
    test = settled.excitation_test
    assert test["p_value"] >= test["level"] == 1e-3 and "chi-bar" in test["reference"]
    assert est.excitation_test is None and "rate" in est.model.param_names


@pytest.mark.slow
def test_corrected_estimate_is_unbiased_at_half_an_impulse_a_second():
    # 10 records of the independent simulator (paper oscillator, 0.5 impulses a second,
    # 2000 s): the mean corrected estimate within 3 standard errors of the truth
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "analyses"))
    from independent_sim import simulate as independent

    truth = {**PAPER, "rate": 0.5}
    model = Model.from_spec(IMP)
    est = []
    for seed in range(10):
        rec, _ = independent(
            truth, duration=2000.0, dt=0.02, rng=np.random.default_rng(400 + seed)
        )
        est.append(estimate(rec, model, force=True).theta)
    est = np.array(est)
    want = np.array([truth[p] for p in model.param_names])
    se = est.std(axis=0, ddof=1) / math.sqrt(len(est))
    assert np.all(np.abs(est.mean(axis=0) - want) < 3 * se), (est.mean(axis=0), se)
