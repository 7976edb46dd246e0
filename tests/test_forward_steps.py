"""The solver's batched forward differences (:func:`hosid.inference.gmm.forward_steps`)
against scipy's own (``least_squares(jac="2-point")``, :func:`approx_derivative`)."""

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.optimize._numdiff import approx_derivative  # what least_squares calls

from hosid.inference.gmm import forward_steps


def _batched(f, x0, lo, hi):
    Z = x0 + np.diag(forward_steps(x0, lo, hi))
    return ((f(Z) - f(x0)) / (np.diagonal(Z) - x0)[:, None]).T


def _f(x):
    x = np.asarray(x)
    return np.stack([np.sin(x[..., 0]) * x[..., 1], np.exp(0.3 * x[..., 2]) + x[..., 0] ** 3,
                     x[..., 1] * x[..., 2]], axis=-1)  # fmt: skip


bound = st.floats(-50, 50, allow_nan=False)


@settings(max_examples=200, deadline=None)
@given(st.lists(st.tuples(bound, bound, st.floats(0, 1), st.booleans(), st.booleans()),
                min_size=3, max_size=3))  # fmt: skip
def test_same_jacobian_as_scipy(cols):
    """Within any bounds (some infinite, some narrower than a step), the batched Jacobian
    is scipy's (rtol 1e-10), and every shifted point stays in bounds (to rounding)."""
    lo, hi, x0 = [], [], []
    for a, b, u, open_lo, open_hi in cols:
        a, b = min(a, b), max(a, b) + 1e-9
        x0.append(a + u * (b - a))
        lo.append(-np.inf if open_lo else a)
        hi.append(np.inf if open_hi else b)
    lo, hi, x0 = map(np.array, (lo, hi, x0))
    h = forward_steps(x0, lo, hi)
    ulp = 4 * np.finfo(float).eps * np.maximum(1.0, np.abs(x0))  # a bound met by rounding
    assert np.all(h != 0) and np.all(x0 + h >= lo - ulp) and np.all(x0 + h <= hi + ulp)
    want = approx_derivative(_f, x0, method="2-point", bounds=(lo, hi))
    np.testing.assert_allclose(_batched(_f, x0, lo, hi), want, rtol=1e-10, atol=1e-12)


def test_steps_without_bounds():
    """sqrt(eps) max(1, |x|), signed as x, + at 0."""
    x0 = np.array([0.0, -3.0, 0.5, 1e4])
    inf = np.full(4, np.inf)
    np.testing.assert_array_equal(
        forward_steps(x0, -inf, inf), np.sqrt(np.finfo(float).eps) * np.array([1, -3, 1, 1e4])
    )
