"""The modal view of a system (:mod:`hosid.model.modal`).

Oracles: the two-spring chain's modes by hand (a linear system: both linearisations are
the system, 1e-12), the single oscillator's :math:`\\omega = \\sqrt{k/m}`, :math:`\\zeta =
c/2\\sqrt{km}`, the least-squares slopes :math:`\\overline{r^4}/\\overline{r^2}` of the
cubic stiffness and :math:`\\overline{|\\dot r|^3}/\\overline{\\dot r^2}` of the quadratic
damping, and the summary's quantiles against numpy's over the same draws.
"""

import math

import numpy as np
import pytest

from hosid.model.linear_chain import modes
from hosid.model.modal import (
    MAX_DRAWS,
    estimate_modes,
    modal_draws,
    response_slopes,
    small_slopes,
    summarize_modes,
)
from hosid.model.system import System

K, ALPHA = 10.0, 0.05
TWO = System(("x1", "x2"), [(("ground", "x1"), ("linear",)), (("x1", "x2"), ("linear",))])
THETA2 = np.array([ALPHA * K, K, ALPHA * K, K, 1.0, 1.0, 1.0])
NONLINEAR = System(
    ("x1", "x2"),
    [(("ground", "x1"), ("linear_damping", "quadratic_damping", "linear_stiffness",
                         "cubic_stiffness")),
     (("x1", "x2"), ("linear_damping", "linear_stiffness"))],
)  # fmt: skip


def test_linear_chain_modes_are_the_linear_parts():
    m = modes(TWO, THETA2)
    u = np.random.default_rng(2).normal(size=(2, 10))
    for slopes in (small_slopes(TWO), response_slopes(TWO, u, 2 * u)):
        omega, zeta, shapes = modal_draws(TWO, THETA2, slopes)
        np.testing.assert_allclose(omega[0], m.omega, rtol=1e-12)
        np.testing.assert_allclose(zeta[0], m.zeta, rtol=1e-10)
        np.testing.assert_allclose(shapes[0], m.shapes.real, atol=1e-12)
    golden = (1 + math.sqrt(5)) / 2
    (first, second) = summarize_modes(TWO, THETA2[None, None], small_slopes(TWO))
    np.testing.assert_allclose(first["shape"], [1 / golden, 1.0], atol=1e-12)
    np.testing.assert_allclose(second["shape"], [1.0, -1 / golden], atol=1e-12)


def test_single_oscillator_frequency_and_damping_ratio():
    s = System(("x",), [(("ground", "x"), ("linear",))], single_names=True)
    c, k = 0.4, 25.0
    omega, zeta, shapes = modal_draws(s, [c, k, 1.0], small_slopes(s))
    assert omega[0, 0] == pytest.approx(math.sqrt(k), rel=1e-12)
    assert zeta[0, 0] == pytest.approx(c / (2 * math.sqrt(k)), rel=1e-12)
    assert shapes[0, 0, 0] == 1.0


def test_response_slopes_of_the_nonlinear_terms():
    rng = np.random.default_rng(3)
    r = rng.normal(0.0, [[0.7], [0.2]], size=(2, 5000))
    rd = rng.uniform(-1.0, 1.0, size=(2, 5000))
    gamma = response_slopes(NONLINEAR, r, rd)
    names = [t.name for _, t in NONLINEAR.columns]
    expect = {
        "linear_damping": 1.0,
        "quadratic_damping": np.mean(np.abs(rd[0]) ** 3) / np.mean(rd[0] ** 2),
        "linear_stiffness": 1.0,
        "cubic_stiffness": np.mean(r[0] ** 4) / np.mean(r[0] ** 2),
    }
    np.testing.assert_allclose(gamma, [expect[n] for n in names], rtol=1e-12)
    np.testing.assert_array_equal(small_slopes(NONLINEAR), [1, 0, 1, 0, 1, 1])


def test_summary_over_draws():
    """A stiffer ground spring in some draws: the summary's statistics are numpy's over
    the draws' frequencies; more draws than MAX_DRAWS are thinned evenly."""
    rng = np.random.default_rng(5)
    theta = np.tile(THETA2, (3, 3000, 1))
    theta[..., 1] *= rng.uniform(0.9, 1.1, size=(3, 3000))
    (first, _) = summarize_modes(TWO, theta, small_slopes(TWO))
    omega, _, _ = modal_draws(TWO, theta, small_slopes(TWO))
    assert omega.shape[0] == first["draws"] == MAX_DRAWS
    f = omega[:, 0] / (2 * math.pi)
    got = first["frequency_hz"]
    assert got["mean"] == pytest.approx(f.mean(), rel=1e-12)
    assert got["sd"] == pytest.approx(f.std(ddof=1), rel=1e-12)
    assert [got[k] for k in ("q05", "q50", "q95")] == pytest.approx(
        np.quantile(f, [0.05, 0.5, 0.95]).tolist(), rel=1e-12
    )
    assert max(abs(v) for v in first["shape"]) == pytest.approx(1.0)


def test_overdamped_draws_are_left_out():
    """Draws with fewer underdamped modes than most are left out; where every draw has an
    overdamped mode, the others are summarised (the building's top storey)."""
    over = THETA2 * [100, 1, 1, 1, 1, 1, 1]  # its first mode overdamped
    assert modes(TWO, over).omega.size == 1
    omega, _, _ = modal_draws(TWO, np.stack([THETA2, over, THETA2]), small_slopes(TWO))
    assert omega.shape == (2, 2)
    (one,) = summarize_modes(TWO, np.stack([over, over]), small_slopes(TWO))
    mode = modes(TWO, over)
    assert one["frequency_hz"]["mean"] == pytest.approx(mode.omega[0] / (2 * math.pi))
    assert one["draws"] == 2


def test_estimate_modes_by_the_delta_method():
    """One dof of unit mass: f = sqrt(a2) / 2 pi, zeta = a1 / 2 sqrt(a2), whose gradients
    give the sds exactly (to the differences' rounding, 1e-6); and on a two-dof chain the
    delta method's sds agree with those of 4000 normal draws of the estimate to 10 %."""
    one = System(("x",), [(("ground", "x"), ("linear",))])
    th, cov = np.array([0.4, 25.0, 1.0]), np.diag([0.01, 0.25, 0.01])
    (m,) = estimate_modes(one, th, cov, small_slopes(one))
    f_sd = math.sqrt(0.25) / (4 * math.pi * 5.0)
    z_sd = math.hypot(0.1 / 10.0, 0.5 * 0.4 / (4 * 125.0))
    assert m["frequency_hz"]["mean"] == pytest.approx(5.0 / (2 * math.pi), rel=1e-12)
    assert m["frequency_hz"]["sd"] == pytest.approx(f_sd, rel=1e-6)
    assert m["damping_ratio"]["sd"] == pytest.approx(z_sd, rel=1e-6)
    upper = m["damping_ratio"]["q95"] - m["damping_ratio"]["mean"]
    assert upper == pytest.approx(1.6448536 * z_sd)
    two = System(("x1", "x2"), [(("ground", "x1"), ("linear",)), (("x1", "x2"), ("linear",))])
    th = np.array([0.3, 20.0, 0.2, 10.0, 0.8, 1.0, 1.0])
    cov = np.diag((0.01 * th) ** 2)
    draws = np.random.default_rng(0).multivariate_normal(th, cov, 4000)
    got, ref = (
        estimate_modes(two, th, cov, small_slopes(two)),
        summarize_modes(two, draws, small_slopes(two)),
    )
    for a, b in zip(got, ref, strict=True):
        for key in ("frequency_hz", "damping_ratio"):
            assert a[key]["sd"] == pytest.approx(b[key]["sd"], rel=0.1)
        np.testing.assert_allclose(a["shape"], b["shape"], atol=1e-3)
