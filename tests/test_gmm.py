"""The calibrated quasi-likelihood (efficient GMM) on synthetic linear estimating equations,
where every quantity has a closed form."""

import math

import numpy as np
import pytest
from scipy import stats

from hosid.components.base import Moments
from hosid.inference.gmm import (
    BlockCovariance,
    QuasiLikelihood,
    hansen,
    quasi_likelihood,
    solve,
    weight_factor,
)

#: Equations m_b(theta) = y_b - A theta, y_b ~ N(A theta0, SIGMA): k = 4, p = 2.
A = np.array([[1.0, 0.0], [0.0, 1.0], [1.0, 1.0], [1.0, -2.0]])
SIGMA = np.array(
    [[1.0, 0.3, 0.0, 0.0], [0.3, 2.0, 0.1, 0.0], [0.0, 0.1, 1.5, -0.4], [0.0, 0.0, -0.4, 1.0]]
)
THETA0 = np.array([0.7, -1.2])


def _moments(y, rows, name):
    """Moments of the equations ``rows`` of ``y_b - A theta``."""
    ybar = y.mean(axis=0)[rows]
    Ar = A[rows]

    def mean(theta):
        return ybar - np.asarray(theta) @ Ar.T

    return Moments(name, tuple(f"{name} {i}" for i in rows), mean, y[:, rows] - ybar)


def _data(rng, B=40):
    return (A @ THETA0)[None] + rng.standard_normal((B, 4)) @ np.linalg.cholesky(SIGMA).T


@pytest.fixture(scope="module")
def synthetic():
    y = _data(np.random.default_rng(2))
    parts = [_moments(y, [0, 1], "first"), _moments(y, [2, 3], "second")]
    return y, parts, quasi_likelihood(parts, n_params=2)


def test_a_covariance_from_elsewhere_is_the_weight_with_its_own_wishart_factor(synthetic):
    y, parts, _ = synthetic
    B, k = y.shape
    labels = tuple(lab for m in parts for lab in m.labels)
    dof = 400  # e.g. ten simulated records of 41 blocks
    cov = BlockCovariance(SIGMA, dof, labels, "ten records")
    ql = quasi_likelihood(parts, n_params=2, covariance=cov)
    factor = (dof - k - 1) / dof
    assert ql.info["weight_factor"] == pytest.approx(factor, rel=1e-15)
    assert ql.info["covariance_dof"] == dof and "ten records" in ql.info["weighting"]
    W = factor * np.linalg.inv(SIGMA)
    for theta in [THETA0, np.array([0.1, 0.4])]:
        mbar = y.mean(axis=0) - A @ theta
        assert ql(theta) == pytest.approx(-0.5 * B * mbar @ W @ mbar, rel=1e-12)
    with pytest.raises(ValueError, match="other estimating equations"):
        quasi_likelihood(parts[::-1], n_params=2, covariance=cov)


def test_a_known_covariance_takes_the_weight_noise_out_of_the_ratio():
    """D of one restriction over 4000 records of B = 10 Gaussian blocks, k = 4 equations,
    p = 2.  With each record's own weight, Rao's test of additional information is the
    exact oracle, (n - q) D' / (n + J') ~ F(1, n - q) (n = B - 1, q = k - p; primes: the
    statistics without the Wishart factor), and D's tail is heavier than chi2(1); with the
    true covariance D is chi2(1).  Tolerance: 3 binomial sd of a 1 % share (0.0047).
    """
    rng = np.random.default_rng(11)
    n_rec, B, k, p = 4000, 10, 4, 2
    labels = tuple(f"e {i}" for i in range(k))
    cov = BlockCovariance(SIGMA, 10**7, labels)
    own, rao, known = [], [], []
    for _ in range(n_rec):
        y = _data(rng, B)
        parts = [Moments("e", labels, lambda th, y=y: y.mean(axis=0) - np.asarray(th) @ A.T,
                         y - y.mean(axis=0))]  # fmt: skip
        for c in (None, cov):
            ql = quasi_likelihood(parts, n_params=p, covariance=c)
            # linear equations: each J is a least-squares problem in the whitened residual
            r0 = ql.residual(np.zeros(p))
            G = np.stack([ql.residual(np.eye(p)[j]) - r0 for j in range(p)], axis=1)
            J = np.sum((r0 - G @ np.linalg.lstsq(G, r0, rcond=None)[0]) ** 2)
            rr = r0 + G[:, 1] * THETA0[1]  # theta_1 fixed at its true value
            J0 = np.sum((rr - G[:, :1] @ np.linalg.lstsq(G[:, :1], rr, rcond=None)[0]) ** 2)
            if c is None:
                f = ql.info["weight_factor"]
                n, q = B - 1, k - p
                own.append(J0 - J)
                rao.append((n - q) * (J0 - J) / f / (n + J / f))
            else:
                known.append(J0 - J)
    tol = 3 * math.sqrt(0.01 * 0.99 / n_rec)
    assert np.mean(np.array(known) > stats.chi2.isf(0.01, 1)) == pytest.approx(0.01, abs=tol)
    assert np.mean(np.array(rao) > stats.f.isf(0.01, 1, B - 1 - (k - p))) == pytest.approx(
        0.01, abs=tol
    )
    assert np.mean(np.array(own) > stats.chi2.isf(0.01, 1)) > 0.01 + tol


def test_quasi_likelihood_is_the_exact_gaussian_form(synthetic):
    y, _, ql = synthetic
    B, k = y.shape
    assert isinstance(ql, QuasiLikelihood)
    assert (ql.B, ql.k) == (B, k)
    S = np.cov(y, rowvar=False)  # (B - 1) denominator, as the influence covariance
    factor = (B - k - 2) / (B - 1)  # Wishart: E[factor S^-1] = Sigma^-1
    assert ql.info["weight_factor"] == pytest.approx(factor, rel=1e-15)
    W = factor * np.linalg.inv(S)
    rng = np.random.default_rng(3)
    for theta in [THETA0, np.zeros(2), rng.normal(size=2)]:
        mbar = y.mean(axis=0) - A @ theta
        expected = -0.5 * B * mbar @ W @ mbar
        assert ql(theta) == pytest.approx(expected, rel=1e-12)
    th = rng.normal(size=(3, 5, 2))
    assert ql(th).shape == (3, 5)
    assert ql.mean(th).shape == (3, 5, 4) and ql.residual(th).shape == (3, 5, 4)


def test_by_component_sums_to_the_total(synthetic):
    _, _, ql = synthetic
    assert list(ql.slices) == ["first", "second"]
    th = np.random.default_rng(4).normal(size=(7, 2))
    parts = ql.by_component(th)
    np.testing.assert_allclose(parts["first"] + parts["second"], ql(th), rtol=1e-12)
    assert np.all(parts["first"] <= 0) and np.all(parts["second"] <= 0)
    # the first component, given nothing before it, is its own Gaussian form
    y, _, _ = synthetic
    B = y.shape[0]
    S1 = np.cov(y[:, :2], rowvar=False)
    f = (B - 4 - 2) / (B - 1)  # the factor of the whole stack
    m1 = y[:, :2].mean(0) - th @ A[:2].T
    np.testing.assert_allclose(
        parts["first"], -0.5 * B * f * np.einsum("ni,ij,nj->n", m1, np.linalg.inv(S1), m1)
    )


def test_solve_finds_the_gls_root_and_the_laplace_covariance(synthetic):
    y, _, ql = synthetic
    B, k = y.shape
    W = (B - k - 2) / (B - 1) * np.linalg.inv(np.cov(y, rowvar=False))
    ybar = y.mean(axis=0)
    gls = np.linalg.solve(A.T @ W @ A, A.T @ W @ ybar)  # minimizer of the quadratic form
    got = solve(ql, np.zeros(2), log_params=[], scale=np.ones(2))
    np.testing.assert_allclose(got, gls, rtol=1e-9, atol=1e-12)
    # the Godambe covariance of the estimator: (B A^T W A)^-1
    np.testing.assert_allclose(
        ql.laplace(got, np.ones(2)), np.linalg.inv(B * A.T @ W @ A), rtol=1e-6
    )


def test_solve_exactly_identified_root_and_log_parameters():
    # k = p: the root solves m(theta) = 0 exactly; a positive parameter in its logarithm
    y = _data(np.random.default_rng(5)) + np.array([3.0, 3.0, 6.0, -3.0])  # theta0 + 3
    part = _moments(y, [0, 1], "id")
    ql = quasi_likelihood([part], n_params=2)
    got = solve(ql, np.array([1.0, 1.0]), log_params=[0], scale=np.ones(2))
    np.testing.assert_allclose(got, y.mean(axis=0)[:2], rtol=1e-9)
    assert ql(got) == pytest.approx(0.0, abs=1e-15)
    assert math.isnan(hansen(ql, got)["p_value"])  # no over-identification
    assert hansen(ql, got)["df"] == 0


def test_hansen_J_is_chi2_over_replicated_data():
    """400 replicated data sets (one seed), B = 40, k = 4, p = 2: J at the estimate is
    about chi2 with k - p = 2 df (exactly: J/c is Hotelling's T^2, whose F reference gives
    the p-value), J at the truth has mean about k."""
    rng = np.random.default_rng(6)
    J_hat, J_true, pvals = [], [], []
    nu, q = 39, 2
    for _ in range(400):
        y = _data(rng)
        ql = quasi_likelihood([_moments(y, [0, 1, 2, 3], "all")], n_params=2)
        th = solve(ql, np.zeros(2), log_params=[], scale=np.ones(2))
        test = hansen(ql, th)
        assert test["df"] == q
        assert test["J"] == pytest.approx(-2 * ql(th))
        T2 = test["J"] / weight_factor(nu, 4)
        assert test["p_value"] == pytest.approx(
            stats.f.sf(T2 * (nu - q + 1) / (q * nu), q, nu - q + 1)
        )
        assert test["dispersion"] == pytest.approx(T2 * (nu - q - 1) / (q * nu))
        J_hat.append(test["J"])
        J_true.append(-2 * ql(THETA0))
        pvals.append(test["p_value"])
    # measured on this seed: mean J_true 3.86, J_hat 1.83, KS p-value 0.08 (against
    # chi2(2)); E[J_hat] = c q nu / (nu - q - 1) = 1.89
    assert np.mean(J_true) == pytest.approx(4.0, abs=3 * math.sqrt(10.5 / 400))
    assert np.mean(J_hat) == pytest.approx(1.89, abs=3 * 2.0 / math.sqrt(400))
    ks = stats.kstest(J_hat, stats.chi2(2).cdf)
    assert ks.pvalue > 0.01
    # p-values of the test are about uniform: 5 % below 0.05 (binomial sd 1.1 %)
    assert np.mean(np.array(pvals) < 0.05) == pytest.approx(0.05, abs=0.035)
    assert stats.kstest(pvals, "uniform").pvalue > 0.01


def test_posterior_covariance_against_the_estimator_s_with_many_equations_for_the_blocks():
    """The weight factor's margin (module docstring) on its Gaussian oracle: 3000 data
    sets of B = 20 blocks, k = 10 equations, p = 2 (nu = 19, q = 8).  The feasible
    efficient estimator's covariance is (nu - 1)/(nu - q - 1) times V0 = (A^T Sigma^-1
    A)^-1 / B, the Laplace covariance's mean (nu - q)/(c nu) times it: 1.31 times the
    estimator's.  Tolerance: 4 standard errors of the replicated variances (t-like
    estimates: se of a variance about 3.5 % here), 5 % on the mean Laplace variance.
    """
    rng = np.random.default_rng(12)
    k, p, B, n_rec = 10, 2, 20, 3000
    A10 = np.vstack([A, rng.normal(size=(k - 4, p))])
    L = np.linalg.cholesky(0.5 * np.eye(k) + 0.5 * np.ones((k, k)) / k)
    est, lap = [], []
    for _ in range(n_rec):
        y = (A10 @ THETA0)[None] + rng.standard_normal((B, k)) @ L.T
        ybar = y.mean(axis=0)
        part = Moments("e", tuple(f"e {i}" for i in range(k)),
                       lambda th, ybar=ybar: ybar - np.asarray(th) @ A10.T, y - ybar)  # fmt: skip
        ql = quasi_likelihood([part], n_params=p)
        W = ql.L_inv.T @ ql.L_inv  # B W is the curvature's weight
        est.append(np.linalg.solve(A10.T @ W @ A10, A10.T @ W @ ybar))
        lap.append(np.diag(ql.laplace(est[-1], np.ones(p))))
    nu, q, c = B - 1, k - p, weight_factor(B - 1, k)
    V0 = np.diag(np.linalg.inv(A10.T @ np.linalg.inv(L @ L.T) @ A10)) / B
    np.testing.assert_allclose(np.var(np.array(est), axis=0), V0 * (nu - 1) / (nu - q - 1),
                               rtol=4 * 0.035)  # fmt: skip
    np.testing.assert_allclose(np.mean(lap, axis=0), V0 * (nu - q) / (c * nu), rtol=0.05)


def test_too_few_blocks_singular_or_dead_equations_raise():
    y = _data(np.random.default_rng(7), B=6)
    with pytest.raises(ValueError, match="6 blocks are too few for 4 estimating equations"):
        quasi_likelihood([_moments(y, [0, 1, 2, 3], "all")], n_params=2)
    y = _data(np.random.default_rng(8))
    dead = Moments(
        "dead", ("dead 0",), lambda th: np.zeros((*np.shape(th)[:-1], 1)), np.zeros((40, 1))
    )
    with pytest.raises(ValueError, match="no variance: dead 0"):
        quasi_likelihood([_moments(y, [0, 1], "a"), dead], n_params=2)
    twice = [_moments(y, [0, 1], "a"), _moments(y, [0], "b")]
    with pytest.raises(ValueError, match="linearly dependent"):
        quasi_likelihood(twice, n_params=2)


def test_pooled_covariance_of_several_records():
    """sum_r U_r'U_r / sum_r (B_r - 1) over the records whose equations are the first
    one's (an equation without columns ignored); None from fewer than two.
    """
    from types import SimpleNamespace

    from hosid.inference.gmm import pooled_covariance

    rng = np.random.default_rng(0)
    U = [rng.normal(size=(b, 3)) for b in (20, 30, 25)]
    empty = SimpleNamespace(k=0, labels=(), influence=np.zeros((20, 0)))

    def record(labels, u):
        return [SimpleNamespace(k=3, labels=labels, influence=u), empty]

    sets = [record(("a", "b", "c"), U[0]), record(("a", "b", "x"), U[1]),
            record(("a", "b", "c"), U[2])]  # fmt: skip
    cov = pooled_covariance(sets, "test records")
    expected = (U[0].T @ U[0] + U[2].T @ U[2]) / (19 + 24)
    np.testing.assert_allclose(cov.S, expected, rtol=1e-12)
    assert (cov.dof, cov.labels, cov.source) == (43, ("a", "b", "c"), "2 test records")
    assert pooled_covariance(sets[:2]) is None
