"""Priors, pseudo-likelihoods, calibration and the emcee fit."""

import math

import numpy as np
import pytest
from scipy import integrate

from hosid import calibrate as K
from hosid import likelihood as L
from hosid import priors as P
from hosid import results as R
from hosid import sampling as S
from hosid.errors import HosidInputError
from hosid.estimators import velocity_tail
from hosid.simulate import PAPER_PARAMS, simulate


@pytest.fixture
def rng():
    return np.random.default_rng(20261121)


# ------------------------------------------------------------------ priors
@pytest.mark.parametrize(
    "prior", [P.Uniform(-2.0, 3.0), P.LogUniform(0.1, 50.0), P.Normal(1.0, 2.0)]
)
def test_prior_normalized_and_sampled_inside(prior, rng):
    lo = max(prior.lower, -30.0)
    hi = min(prior.upper, 60.0)
    area = integrate.quad(lambda x: math.exp(prior.ln_prob(x)), lo, hi, limit=200)[0]
    assert area == pytest.approx(1.0, abs=2e-3)
    x = prior.sample(rng, 4000)
    assert np.all(np.isfinite(prior.ln_prob(x)))
    # the sample's CDF matches the rescale (inverse CDF) at the quartiles
    # (binomial sd of a fraction of 4000 draws is <= 0.008)
    for u in (0.25, 0.5, 0.75):
        assert np.mean(x <= prior.rescale(u)) == pytest.approx(u, abs=0.03)


def test_prior_rejects_bad_arguments():
    with pytest.raises(ValueError, match="lower < upper"):
        P.Uniform(1.0, 1.0)
    with pytest.raises(ValueError, match="0 < lower"):
        P.LogUniform(0.0, 1.0)
    with pytest.raises(ValueError, match="sigma > 0"):
        P.Normal(0.0, -1.0)


def test_priorset_eq65_constraint(rng):
    ps = P.default_priors(sigma_v=7.0)
    th = np.array([[0.5, 0.5, 25, 5, 100], [-0.5, -0.5, 25, 5, 100], [-3.0, 0.5, 25, 5, 100]])
    lp = ps.ln_prob(th)
    # a1eq = a1 + n1 sqrt(8/pi) 7 = 0.5 + 5.59 > 0; -0.5 - 5.59 < 0; -3 + 5.59 > 0
    assert np.isfinite(lp[0]) and not np.isfinite(lp[1]) and np.isfinite(lp[2])
    draws = ps.sample(rng, 500)
    assert draws.shape == (500, 5) and np.all(ps.a1eq(draws) > 0)
    free = P.default_priors(constrained=False)
    assert np.isfinite(free.ln_prob(th)).all()
    with pytest.raises(ValueError, match="sigma_v"):
        P.default_priors()


# ------------------------------------------------------------------ likelihood
def test_components_and_errors():
    assert L.components_for("J2") == ("moments", "J2W")
    assert L.components_for("J4A") == ("moments", "J2W", "J4AW")
    assert L.components_for("J4B", "literal") == ("moments", "J2", "J4B")
    with pytest.raises(HosidInputError, match="unknown cost"):
        L.components_for("J5")
    with pytest.raises(HosidInputError, match="form"):
        L.components_for("J2", "odd")


def test_moment_criterion_is_chi2_2_at_truth():
    """J_M at the true parameters is asymptotically chi^2 with 2 degrees of freedom."""
    truth = np.array([0.5, 0.5, 25.0, 5.0, 100.0])
    vals = []
    for child in np.random.default_rng(11).spawn(40):
        rec = simulate(PAPER_PARAMS, duration=1000.0, rng=child)
        md = L.moment_data(rec, batch_samples=1024, tail=velocity_tail(rec))
        vals.append(float(md.cost(truth)))
    # chi2_2: mean 2, sd 2 -> sd of the mean of 40 is 0.32; allow the batch-means
    # covariance estimate (48 batches) some slack
    assert 1.0 < np.mean(vals) < 3.5


def test_pseudolikelihood_tempering(paper_record):
    pl, sv = S.prepare_likelihood(paper_record, cost="J4A")
    th = np.array([[0.5, 0.5, 25.0, 5.0, 100.0], [1.0, 0.4, 25.0, 5.0, 110.0]])
    pw = pl.pointwise(th)
    assert set(pw) == {"moments", "J2W", "J4AW"}
    assert np.allclose(sum(pw.values()), pl(th))
    hot = pl.with_(temperature={"J2W": 2.0, "J4AW": 4.0})
    pw2 = hot.pointwise(th)
    assert np.allclose(pw2["J2W"], pw["J2W"] / 2) and np.allclose(pw2["J4AW"], pw["J4AW"] / 4)
    assert np.allclose(pw2["moments"], pw["moments"])  # never tempered
    cut = pl.with_(stiffness=(30.0, 1.0))
    moved = th.copy()
    moved[:, 2:4] = [20.0, 9.0]
    assert np.allclose(cut.raw(moved)["J4AW"], cut.raw(th)["J4AW"])
    assert not np.allclose(cut.raw(moved)["moments"], cut.raw(th)["moments"])
    with pytest.raises(HosidInputError, match="positive"):
        pl.with_(temperature=0.0)
    assert sv > 0


# ------------------------------------------------------------------ calibration
def test_calibration_recovers_known_design_effect():
    """Data of n independent N(mu, 1) values each repeated m times: a least-squares
    cost over-counts the information by exactly m, so tau = m."""
    n, m = 400, 5

    def simulator(params, *, duration, dt, rng):
        return np.repeat(rng.normal(params["mu"], 1.0, size=n), m)

    def components(y):
        return lambda t: {"J4AW": np.sum((y[None, :] - t[:, :1]) ** 2, axis=1)}

    y0 = simulator({"mu": 0.0}, duration=0, dt=0, rng=np.random.default_rng(1))
    cal = K.calibrate(
        components(y0),
        components,
        np.array([y0.mean()]),
        {"mu": float(y0.mean())},
        duration=0.0,
        dt=0.0,
        scale=np.array([1.0]),
        n_bootstrap=300,
        rng=np.random.default_rng(2),
        coordinates=("mu",),
        simulator=simulator,
    )
    # sd of a variance estimate from 300 draws is ~8 %
    assert cal.temperatures["J4AW"] == pytest.approx(m, rel=0.25)
    assert cal.ratios[0] == pytest.approx(1.0, abs=1e-6)


def test_finite_difference_oracles():
    f = lambda x: np.sum(x**2 * np.array([1.0, 3.0]), axis=-1) + x[..., 0] * x[..., 1]  # noqa: E731
    x = np.array([0.3, -0.7])
    assert np.allclose(K.gradient(f, x, np.full(2, 1e-4)), [2 * 0.3 - 0.7, 6 * -0.7 + 0.3])
    assert np.allclose(K.hessian(f, x, np.full(2, 1e-3)), [[2, 1], [1, 6]], atol=1e-5)


# ------------------------------------------------------------------ fit
@pytest.fixture(scope="module")
def short_fit():
    rec = simulate(PAPER_PARAMS, duration=600.0, rng=np.random.default_rng(5))
    return S.fit(
        rec,
        cost="J4A",
        n_walkers=10,
        n_steps=60,
        n_bootstrap=3,
        seed=1,
        progress=False,
        truths=PAPER_PARAMS,
    )


def test_fit_tree_layout(short_fit, tmp_path):
    t = short_fit
    for g in ("posterior", "sample_stats", "log_likelihood", "observed_data", "cost_map"):
        assert g in t.children
    post = t["posterior"]
    assert set(post.data_vars) == {"a1", "n1", "a2", "n2", "S0", "a1eq"}
    assert post.sizes["chain"] == 10 and post.sizes["draw"] > 0
    assert set(t["log_likelihood"].data_vars) == {"moments", "J2W", "J4AW"}
    assert np.all(post["a1eq"].values > 0)  # eq-65 constraint on by default
    lp = t["sample_stats"]["lp"].values
    ll = sum(t["log_likelihood"][k].values for k in t["log_likelihood"].data_vars)
    assert np.allclose(lp, ll + t["sample_stats"]["log_prior"].values)
    s = R.summarize(t, warn=False)
    for k in ("a1", "n1", "a2", "n2", "S0"):
        assert {"mean", "sd", "q05", "q50", "q95", "r_hat", "ess_bulk"} <= set(s["parameters"][k])
    assert s["cost"] == "J4A" and s["constrained"] is True
    assert s["truths"]["a1"] == 0.5
    assert s["calibration"]["temperatures"]["J4AW"] > 0
    back = R.load(R.save(t, tmp_path / "posterior.nc"))
    assert np.allclose(back["posterior"]["S0"].values, post["S0"].values)


def test_fit_short_run_warns_on_diagnostics(short_fit):
    with pytest.warns(R.ConvergenceWarning, match="r_hat|ess"):
        R.summarize(short_fit)


@pytest.mark.parametrize(
    ("kw", "msg"),
    [
        ({"n_walkers": 7}, "n_walkers"),
        ({"n_walkers": 11}, "even"),
        ({"n_steps": 0}, "n_steps"),
        ({"cost": "J9"}, "unknown cost"),
    ],
)
def test_fit_rejects_bad_options(paper_record, kw, msg):
    with pytest.raises(HosidInputError, match=msg):
        S.fit(paper_record, progress=False, **kw)


def test_tau_max_guards_non_finite_autocorrelation_times():
    """A stuck parameter's NaN autocorrelation time must not crash the burn-in."""
    assert S._tau_max(np.array([4.9, 5.3]), 60) == 5.3
    assert S._tau_max(np.array([4.9, np.nan, np.inf]), 60) == 6.0  # n_steps / 10
