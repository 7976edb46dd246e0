"""The quasi-likelihood widened to the spread of the estimates on records simulated at
the estimate (:func:`hosid.inference.simulated.spread_widening`), on linear equations
whose estimates and curvature are known exactly.
"""

from __future__ import annotations

import numpy as np
import pytest

from hosid.components.base import Moments
from hosid.inference.correction import shifted
from hosid.inference.gmm import BlockCovariance, quasi_likelihood
from hosid.inference.simulated import spread_widening

B = 60  # blocks a record
#: eight deviations with mean 0 and sample sd (ddof 1) exactly 1
PATTERN = np.array([-1.5, -1.0, -0.5, 0.0, 0.0, 0.5, 1.0, 1.5])
PATTERN = PATTERN / PATTERN.std(ddof=1)


def _moments(x: np.ndarray, rng) -> Moments:
    """Equations theta - x: their estimate is x exactly."""
    U = rng.normal(size=(B, 2))
    return Moments("toy", ("a", "b"), lambda th, x=x: np.asarray(th) - x, U - U.mean(0))


def test_the_spread_beyond_chance_widens_its_parameter_about_the_mode():
    rng = np.random.default_rng(4)
    cov = BlockCovariance(np.eye(2), dof=400, labels=("a", "b"), source="test")
    theta = np.array([1.0, 2.0])
    ql = quasi_likelihood([_moments(theta, rng)], n_params=2, covariance=cov)
    scale = np.ones(2)
    sd = np.sqrt(np.diag(ql.laplace(theta, scale)))
    # the simulated records' estimates scatter 3 sd along a (beyond chance: the 95 %
    # point of sqrt(chi2_7/7) is 1.42) and 1.2 sd along b (within chance)
    sets = [[_moments(theta + np.array([3.0, 1.2]) * sd * p, rng)] for p in PATTERN]
    lower, upper = np.full(2, -10.0), np.full(2, 10.0)
    wide = spread_widening(ql, theta, sets, theta, cov, [], lower, upper, scale)
    assert wide(theta) == pytest.approx(0.0, abs=1e-12)  # the mode stays
    np.testing.assert_allclose(np.sqrt(np.diag(wide.laplace(theta, scale))), sd * [3.0, 1.0],
                               rtol=1e-5)  # fmt: skip
    assert wide.info["simulated_spread"]["widened"] == pytest.approx([3.0, 1.0], rel=1e-6)
    # within chance everywhere: the quasi-likelihood is returned as it is
    calm = [[_moments(theta + sd * p, rng)] for p in PATTERN]
    assert spread_widening(ql, theta, calm, theta, cov, [], lower, upper, scale) is ql


def test_a_widening_without_shift_keeps_the_curvature_elsewhere():
    # shift=False: no 1 + 1/n flattening, only the widened parameter's sd grows
    rng = np.random.default_rng(5)
    theta = np.array([1.0, 2.0])
    ql = quasi_likelihood([_moments(theta, rng)], n_params=2)
    w = shifted(ql, np.zeros(2), np.zeros(2, dtype=bool), 8, centre=theta,
                widen=np.array([2.0, 1.0]), shift=False)  # fmt: skip
    sd, sd_w = (np.sqrt(np.diag(q.laplace(theta, np.ones(2)))) for q in (ql, w))
    np.testing.assert_allclose(sd_w, sd * [2.0, 1.0], rtol=1e-6)
    assert "sampling_bias" not in w.info and w.info["simulated_spread"]["simulations"] == 8
