"""Window constants and Delta_T (paper eqs 20, 25-31, A6, App. B)."""

import numpy as np
import pytest

from hosid.windows import Window, get_window

T = 20.48  # block length (s) of the paper's 1024-sample blocks


def _welch(u):
    """Custom window D(u) = 4u(1-u); k4 = 256 B(5, 5) = 0.406349..."""
    u = np.asarray(u, dtype=float)
    return 4.0 * u * (1.0 - u)


WELCH_K4 = 256.0 * 24.0 * 24.0 / 362880.0  # 256 * 4! 4! / 9!


def _hann_callable(u):
    return 0.5 * (1.0 - np.cos(2.0 * np.pi * np.asarray(u, dtype=float)))


def _delta_chunked(win: Window, omega: np.ndarray, T: float) -> np.ndarray:
    """The numeric Delta_T path forms an (n_omega, 4097) array: evaluate in chunks."""
    chunks = np.array_split(omega, max(1, omega.size // 500))
    return np.concatenate([win.delta_T(c, T) for c in chunks])


def test_hann_constants_match_periodic_window_means():
    hann = get_window("hann")
    for m in (64, 1024, 4096):
        d = hann.samples(m)
        # The periodic Hann window's D^2, D^4 are trigonometric polynomials of degree
        # 2 and 4 < m, so their discrete means are exact up to round-off.
        assert np.mean(d**2) == pytest.approx(3 / 8, rel=1e-12)
        assert np.mean(d**4) == pytest.approx(35 / 128, rel=1e-12)
    assert hann.k2 == 3 / 8
    assert hann.k4 == 35 / 128


def test_boxcar_constants():
    box = get_window("boxcar")
    assert box.k2 == 1.0
    assert box.k4 == 1.0
    np.testing.assert_array_equal(box.samples(128), np.ones(128))


def test_custom_window_constants_are_numeric_means():
    w = get_window(_welch)
    # 65536-sample Riemann sum of a smooth function vanishing at both ends: error ~1e-9
    assert w.k2 == pytest.approx(16.0 / 30.0, rel=1e-8)  # 16 B(3, 3)
    assert w.k4 == pytest.approx(WELCH_K4, rel=1e-8)


def test_boxcar_delta_eq26_matches_numeric_path():
    box = get_window("boxcar")
    numeric = get_window(lambda u: np.ones_like(np.asarray(u, dtype=float)))
    assert numeric.name != "boxcar"  # takes the quadrature path
    omega = np.linspace(-12.0, 12.0, 601)
    exact = box.delta_T(omega, T)
    approx = numeric.delta_T(omega, T)
    # trapezoid on 4097 points: O(h^2 Omega^2) ~ 1e-6 relative for |Omega| < 40; the
    # absolute floor (1e-3 of the peak T/2pi) covers the zeros of the sinc^2.
    np.testing.assert_allclose(approx, exact, rtol=1e-3, atol=1e-3 * T / (2 * np.pi))
    assert exact[300] == pytest.approx(T / (2 * np.pi))  # omega = 0


def test_hann_delta_eq29_matches_numeric_path():
    hann = get_window("hann")
    numeric = get_window(_hann_callable)
    assert numeric.name != "hann"
    omega = np.linspace(-12.0, 12.0, 601)
    exact = hann.delta_T(omega, T)
    approx = numeric.delta_T(omega, T)
    np.testing.assert_allclose(approx, exact, rtol=1e-3, atol=1e-6 * exact.max())
    # peak value: |int D^2 dt|^2 / (2 pi T) = (3/8)^2 T / (2 pi)
    assert exact[300] == pytest.approx((3 / 8) ** 2 * T / (2 * np.pi), rel=1e-12)


@pytest.mark.parametrize("name", ["hann", "boxcar"])
def test_analytic_delta_at_bins_equals_discrete(name):
    win = get_window(name)
    m = 1024
    k = np.arange(-40, 41)
    analytic = win.delta_T(2 * np.pi * k / T, T)
    discrete = win.delta_T_bins(k, m, T)
    # D^2 is a trigonometric polynomial of degree <= 2: the DFT is exact.
    np.testing.assert_allclose(analytic, discrete, rtol=1e-10, atol=1e-10 * T)


@pytest.mark.parametrize(
    ("window", "k4"),
    [("boxcar", 1.0), ("hann", 35 / 128), (_welch, WELCH_K4)],
    ids=["boxcar", "hann", "welch"],
)
def test_integral_of_delta_is_k4(window, k4):
    win = get_window(window)
    assert win.k4 == pytest.approx(k4, rel=1e-8)
    if win.name == "boxcar":
        # Delta ~ 1/Omega^2: the tails beyond |Omega| = 2000 hold 2/(2 pi^2 2000) = 5e-5
        Omega = np.linspace(-2000.0, 2000.0, 800_001)
    else:
        # Hann and Welch decay as Omega^-6: |Omega| <= 40 holds all but ~1e-9
        Omega = np.linspace(-40.0, 40.0, 8001)
    omega = 2 * np.pi * Omega / T
    analytic = win.name in ("boxcar", "hann")
    vals = win.delta_T(omega, T) if analytic else _delta_chunked(win, omega, T)
    integral = np.trapezoid(vals, omega)
    # eq (31); tolerance 1e-3: truncated tails (<= 5e-5) and the trapezoid on a grid of
    # 100 (boxcar 200) points per sidelobe
    assert integral == pytest.approx(k4, rel=1e-3)


@pytest.mark.parametrize("window", ["boxcar", "hann", _welch], ids=["boxcar", "hann", "welch"])
@pytest.mark.parametrize("m", [256, 1024])
def test_discrete_parseval_sum_of_delta_bins_is_k4(window, m):
    win = get_window(window)
    k = np.arange(m)
    total = np.sum(win.delta_T_bins(k, m, T)) * 2 * np.pi / T
    # Parseval: sum_k |DFT(D^2)/m|^2 = mean(D_n^4), exact up to round-off
    assert total == pytest.approx(np.mean(win.samples(m) ** 4), rel=1e-12)
    # and the discrete mean equals k4 (exactly for boxcar/Hann, to O(1/m^2) for Welch)
    assert total == pytest.approx(win.k4, rel=1e-12 if win.name in ("boxcar", "hann") else 1e-4)


def test_get_window_accepts_names_windows_and_callables():
    assert get_window("Hanning").name == "hann"
    assert get_window("rect").name == "boxcar"
    w = get_window("hann")
    assert get_window(w) is w
    assert get_window(_welch).name == "_welch"


@pytest.mark.parametrize("bad", ["kaiser", "", 3, None])
def test_bad_window_raises(bad):
    with pytest.raises(ValueError, match="unknown window"):
        get_window(bad)
