"""The evidence of ``diagnose``: the nested quasi-likelihood ratio (exact oracles on linear
estimating equations), the regular coordinates, the Wald and ratio statistics of a
candidate effect on simulated records, and the calibrated decision of a round.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import stats

from hosid.check.evidence import COORDINATES, Coordinate, Evidence, critical_z, screen, weigh
from hosid.check.selection import Round, null_min_log_p
from hosid.components.base import Moments
from hosid.errors import HosidInputError
from hosid.inference.estimate import estimate
from hosid.inference.gmm import Transformed, j_difference, quasi_likelihood, solve
from hosid.model import PAPER_PARAMS, Model, simulate

# ------------------------------------------------------------ the nested ratio
#: Linear equations m_b(theta) = y_b - A theta, k = 4, p = 2 (as in test_gmm.py).
A = np.array([[1.0, 0.0], [0.0, 1.0], [1.0, 1.0], [1.0, -2.0]])
SIGMA = [[1.0, 0.3, 0, 0], [0.3, 2.0, 0.1, 0], [0, 0.1, 1.5, -0.4], [0, 0, -0.4, 1.0]]
L_SIGMA = np.linalg.cholesky(np.array(SIGMA))


def _linear_ql(rng, theta0, B=60):
    y = (A @ theta0)[None] + rng.standard_normal((B, 4)) @ L_SIGMA.T
    ybar = y.mean(axis=0)
    mom = Moments("lin", ("a", "b", "c", "d"), lambda th: ybar - np.asarray(th) @ A.T, y - ybar)
    return quasi_likelihood([mom], n_params=2)


def _nested(ql):
    """(D, Wald z) of theta[1] = 0 with one weight."""
    scale = np.ones(2)
    free = solve(ql, np.zeros(2), log_params=[], scale=scale)
    fixed = Transformed.of(ql, lambda v: np.insert(np.asarray(v), 1, 0.0, axis=-1))
    restricted = solve(fixed, np.zeros(1), log_params=[], scale=scale[:1])
    D = -2.0 * float(fixed(restricted)) + 2.0 * float(ql(free))
    sd = math.sqrt(ql.laplace(free, scale)[1, 1])
    return D, free[1] / sd


def test_distance_statistic_of_linear_equations_is_the_squared_wald_z():
    # with one weight and linear equations the criterion is exactly quadratic: D = z^2
    for seed in range(3):
        D, z = _nested(_linear_ql(np.random.default_rng(seed), np.array([0.5, 0.3])))
        assert D == pytest.approx(z**2, rel=1e-6)


def test_distance_statistic_is_chi2_under_the_null():
    # 150 replicated data sets at theta[1] = 0: mean of chi2(1) is 1 (sd of the mean
    # 0.115), P(D > 3.84) = 0.05 (sd 0.018); tolerances 3 sd
    rng = np.random.default_rng(11)
    D = np.array([_nested(_linear_ql(rng, np.array([0.5, 0.0])))[0] for _ in range(150)])
    assert abs(D.mean() - 1.0) < 0.35
    assert abs(np.mean(D > 3.841) - 0.05) < 0.055


def test_j_difference_references():
    t = j_difference(10.0, 10.0 - 3.841459, df=1)
    assert t["D"] == pytest.approx(3.841459) and t["p_value"] == pytest.approx(0.05, rel=1e-5)
    t = j_difference(10.0, 10.0 - 2.705543, boundary=True)  # chi-bar: 0.5 chi2(1) tail
    assert t["p_value"] == pytest.approx(0.05, rel=1e-5) and "chi-bar" in t["reference"]
    assert j_difference(1.0, 2.0, boundary=True) == {**t, "D": 0.0, "p_value": 1.0, "log_p": 0.0}
    assert j_difference(8.0, 0.0, dispersion=2.0)["D"] == 4.0
    assert j_difference(9.0, 1.0, df=2)["p_value"] == pytest.approx(stats.chi2.sf(8.0, 2))
    with pytest.raises(ValueError, match="one parameter"):
        j_difference(3.0, 1.0, df=2, boundary=True)


# ------------------------------------------------------------ coordinates
@pytest.mark.parametrize("effect", list(COORDINATES))
def test_coordinates_map_the_null_to_zero(effect):
    c = COORDINATES[effect]
    assert c.to_u(float(c.to_param(0.0))) == 0.0
    for u in (1e-4, 0.3):
        assert c.to_u(float(c.to_param(u))) == pytest.approx(u, rel=1e-12)
    lo, hi = c.bounds(0.5, 4.0)
    assert lo == 0.0 if c.boundary else lo == 0.5
    assert hi == {"identity": 4.0, "inverse_square": 4.0, "inverse": 2.0, "square": 16.0}[c.kind]


def test_critical_z():
    assert critical_z(0.05, False) == pytest.approx(1.959964, rel=1e-6)
    assert critical_z(0.05, True) == pytest.approx(1.644854, rel=1e-6)


# ------------------------------------------------------------ on records
@pytest.fixture(scope="module")
def clean():
    return simulate(PAPER_PARAMS, duration=1000.0, dt=0.02, rng=np.random.default_rng(8))


@pytest.fixture(scope="module")
def hidden_b2():
    rec = simulate(
        {**PAPER_PARAMS, "b2": 3.0}, duration=1000.0, dt=0.02, rng=np.random.default_rng(9)
    )
    return rec, screen(rec, Model.from_spec("paper"), Model.from_spec("paper").candidates)[0]


def test_clean_record_supports_no_candidate(clean):
    found, failed = screen(clean, Model.from_spec("paper"), Model.from_spec("paper").candidates)
    assert not failed and set(found) == set(Model.from_spec("paper").candidates)
    for ev in found.values():
        # measured on this record: |z| <= 1.4, p >= 0.16
        assert abs(ev.z) < 3.0 and ev.p_value > 0.01, ev.as_dict()
        assert ev.u >= 0.0 or not ev.coordinate.boundary
        if not ev.coordinate.boundary:  # nearly quadratic criterion: D close to z^2
            assert ev.D == pytest.approx(ev.z**2, abs=0.5)


def test_hidden_quadratic_stiffness_is_weighed(hidden_b2):
    rec, found = hidden_b2
    ev = found["quadratic_stiffness"]
    # b2 = 3 on 1000 s is about 8 CRB sd (sd 0.39 at T = 1000 s); measured z 7.9, D 63
    assert ev.z > 5.0 and ev.p_value < 1e-8
    assert abs(ev.estimate["b2"] - 3.0) < 3 * ev.sd["b2"]
    assert ev.D == pytest.approx(ev.z**2, rel=0.3)
    # the same equations as the fit: the engine's estimate of the extended model agrees
    eng = estimate(rec, "paper,quadratic_stiffness")
    assert ev.estimate["b2"] == pytest.approx(eng.values["b2"], abs=0.5 * eng.sd["b2"])
    assert ev.sd["b2"] == pytest.approx(eng.sd["b2"], rel=0.2)
    assert min(found, key=lambda c: found[c].p_value) == "quadratic_stiffness"
    row = ev.as_dict()
    assert row["param"] == "b2" and row["value"] == ev.estimate["b2"]


def test_weigh_rejects_what_is_not_a_candidate(clean):
    with pytest.raises(HosidInputError, match="not a candidate"):
        weigh(clean, "paper", "linear_damping", start=PAPER_PARAMS)


# ------------------------------------------------------------ the decision
def _ev(effect, z, p, boundary=False):
    coord = Coordinate("x", "x", boundary)
    return Evidence(
        effect, coord, z, 1.0, z, z * z, p, "", {"x": z}, {"x": 1.0}, {}, 1.0, 0.0, 0.0
    )


def test_round_adjusts_by_the_replicates_smallest_p_values():
    ev = {"a": _ev("a", 4.0, 1e-4), "b": _ev("b", 3.0, 0.003), "c": _ev("c", 1.0, 0.3)}
    null = np.log([0.002, 0.05, 0.2, 0.5] + [0.9] * 15)  # R = 19
    rnd = Round(Model.from_spec("paper"), ev, {}, 0.05, 5, null, replicates=19, calibrated=True)
    assert rnd.adjusted("a") == pytest.approx(1 / 20)
    assert rnd.adjusted("b") == pytest.approx(2 / 20)
    assert rnd.adjusted("c") == pytest.approx(4 / 20)
    assert rnd.supported() == ["a"] and rnd.best() == "a" and not rnd.stopped
    # calibrated: the Wald z needs level alpha only (two-sided 1.96), not alpha / m
    rnd.evidence["a"] = _ev("a", 2.2, 1e-4)
    assert rnd.wald_level == 0.05 and rnd.wald_ok("a") and rnd.supported() == ["a"]
    rnd.evidence["a"] = _ev("a", 1.9, 1e-4)
    assert not rnd.wald_ok("a") and rnd.supported() == []
    rnd.evidence["a"] = _ev("a", 4.0, 1e-4)
    d = rnd.as_dict()
    # not calibrated: Bonferroni
    plain = Round(Model.from_spec("paper"), dict(ev), {}, 0.05, 5)
    assert plain.adjusted("b") == pytest.approx(0.015) and plain.supported() == ["a", "b"]
    # the Wald z must pass Bonferroni's two-sided alpha / m = 0.01 too: 2.576
    plain.evidence["a"] = _ev("a", 2.5, 1e-4)
    assert plain.supported() == ["b"] and not plain.wald_ok("a")
    assert d["calibration_replicates"] == 19 and [r["effect"] for r in d["candidates"]] == [
        "a",
        "b",
        "c",
    ]


@pytest.mark.parametrize("df", [1, 2, 3, 6])
def test_chi2_logsf_beyond_the_underflow_matches_quadrature(df):
    """log P(chi2 >= x) where scipy's logsf is -inf, against the upper incomplete gamma by
    quadrature: Gamma(a, y) = e^-y y^(a-1) int_0^inf (1 + t/y)^(a-1) e^-t dt (rel 1e-9)."""
    from scipy import integrate

    from hosid.inference.gmm import chi2_logsf

    for x in (1600.0, 5000.0):
        a, y = df / 2, x / 2
        quad = integrate.quad(lambda t, a=a, y=y: (1 + t / y) ** (a - 1) * np.exp(-t), 0, np.inf)[
            0
        ]
        exact = -y + (a - 1) * np.log(y) + np.log(quad) - math.lgamma(a)
        assert chi2_logsf(x, df) == pytest.approx(exact, rel=1e-9)
    assert chi2_logsf(10.0, df) == pytest.approx(stats.chi2.logsf(10.0, df), rel=1e-12)


def test_round_orders_p_values_that_underflow_by_their_logarithm():
    """A narrow-band force's D of thousands underflows p to 0 on the record and on some
    replicates of the white model: compared as p the ties counted against the record
    (3/41 on a record with D = 4562); compared on log p the record is more extreme."""
    from hosid.inference.gmm import j_difference

    t_rec, t_rep = j_difference(4562.0, 0.0, df=2), j_difference(1500.0, 0.0, df=2)
    assert t_rec["p_value"] == t_rep["p_value"] == 0.0
    assert t_rec["log_p"] == pytest.approx(-4562.0 / 2)  # chi2(2): log sf = -D/2
    assert j_difference(2000.0, 0.0, boundary=True)["log_p"] < -990
    ev = {"nb": _ev("nb", 38.0, 0.0), "q": _ev("q", 1.0, 0.3)}
    ev["nb"].log_p = t_rec["log_p"]
    null = np.array([t_rep["log_p"], t_rep["log_p"] - 100.0] + [np.log(0.5)] * 38)  # R = 40
    rnd = Round(Model.from_spec("paper"), ev, {}, 0.05, 5, null, replicates=40, calibrated=True)
    assert rnd.adjusted("nb") == pytest.approx(1 / 41) and rnd.supported() == ["nb"]
    ev["nb"].log_p = t_rep["log_p"] - 50.0  # between the two extreme replicates
    assert rnd.adjusted("nb") == pytest.approx(2 / 41)


def test_null_min_log_p_stops_once_the_decision_is_known(clean):
    model = Model.from_spec("paper")
    reps = [clean, clean, clean]
    start = np.tile(model.vector(estimate(clean, model).values), (3, 1))
    full = null_min_log_p(reps, model, ["quadratic_stiffness", "excitation_mean"], start)
    assert full.shape == (3,) and np.all(full == full[0])
    stopped = null_min_log_p(
        reps, model, ["quadratic_stiffness", "excitation_mean"], start, stop=(0.0, 0)
    )
    assert stopped.shape == (1,)


def test_null_covariances_pool_only_replicates_with_the_same_equations(monkeypatch):
    """A replicate whose state gave other null equations (another band: 12 labels instead
    of 8) is left out of the pool instead of failing the round (it failed with a shape
    error); the pooled covariance is that of the matching replicates, by hand."""
    import numpy as np

    from hosid.check import selection
    from hosid.components.base import Moments

    rng = np.random.default_rng(0)
    blocks = [rng.standard_normal((20, k)) for k in (8, 12, 8)]

    def fake(rep, model, c, start, st):
        U = blocks[rep]
        return [Moments("m", tuple(f"e{i}" for i in range(U.shape[1])), lambda t: t, U, {})]

    monkeypatch.setattr(selection, "null_moments", fake)
    out = selection.null_covariances([0, 1, 2], None, ["cubic_stiffness"], {})
    cov = out["cubic_stiffness"]
    U0, U2 = blocks[0], blocks[2]
    np.testing.assert_allclose(cov.S, (U0.T @ U0 + U2.T @ U2) / 38, rtol=1e-12)
    assert cov.dof == 38 and len(cov.labels) == 8
