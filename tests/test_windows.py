"""Window constants and Delta_T (paper eqs 20, 25-31, A6, App. B): exact oracles."""

import numpy as np
import pytest

from hosid.spectra.windows import WINDOWS, Window, get_window, hann_delta_xy

T = 20.48  # block length (s) of the paper's 1024-sample blocks
M = 1024


def test_hann_constants_are_exact():
    hann = get_window("hann")
    # the periodic Hann window's D^2 and D^4 are trigonometric polynomials of degree 2
    # and 4 < m, so their discrete means are exact up to round-off
    assert hann.k2 == pytest.approx(3 / 8, rel=1e-14)
    assert hann.k4 == pytest.approx(35 / 128, rel=1e-14)
    for m in (64, 1024, 4096):
        d = hann.samples(m)
        assert np.mean(d**2) == pytest.approx(3 / 8, rel=1e-12)
        assert np.mean(d**4) == pytest.approx(35 / 128, rel=1e-12)


def test_hann_samples_are_the_periodic_window():
    n = np.arange(M)
    np.testing.assert_allclose(
        get_window("hann").samples(M), 0.5 * (1 - np.cos(2 * np.pi * n / M)), atol=1e-15
    )


def test_boxcar_constants():
    box = get_window("boxcar")
    assert box.k2 == 1.0
    assert box.k4 == 1.0
    np.testing.assert_array_equal(box.samples(128), np.ones(128))


@pytest.mark.parametrize("name", WINDOWS)
def test_integral_of_delta_is_k4_eq31(name):
    win = get_window(name)
    if name == "boxcar":
        # Delta ~ 1/Omega^2: the tails beyond |Omega| = 2000 hold 1/(pi^2 2000) = 5e-5
        Omega = np.linspace(-2000.0, 2000.0, 800_001)
    else:
        # Hann decays as Omega^-6: |Omega| <= 40 holds all but ~1e-9
        Omega = np.linspace(-40.0, 40.0, 8001)
    omega = 2 * np.pi * Omega / T
    integral = np.trapezoid(win.delta_T(omega, T), omega)
    # tolerance 1e-4: truncated tails (<= 5e-5) and the trapezoid on 100 (boxcar 200)
    # points per sidelobe; measured: Hann 4e-16, boxcar -5.1e-5 relative
    assert integral == pytest.approx(win.k4, rel=1e-4)


def test_delta_peak_values():
    # Delta_T(0) = |int D^2 dt|^2 / (2 pi T) = k2^2 T / (2 pi)
    for name in WINDOWS:
        win = get_window(name)
        assert win.delta_T(np.array([0.0]), T)[0] == pytest.approx(
            win.k2**2 * T / (2 * np.pi), rel=1e-12
        )
    X, Y = hann_delta_xy(np.array([0.0]))
    assert X[0] == pytest.approx(3 * np.pi, rel=1e-14)  # int_0^2pi (1 - cos u)^2 du
    assert Y[0] == 0.0


def test_hann_delta_eq29_matches_quadrature():
    """App. B closed form against a direct quadrature of eq (25)."""
    hann = get_window("hann")
    omega = np.linspace(-12.0, 12.0, 241)
    t = np.linspace(0.0, T, 20001)
    D2 = (0.5 * (1 - np.cos(2 * np.pi * t / T))) ** 2
    F = np.trapezoid(D2[None, :] * np.exp(-1j * omega[:, None] * t[None, :]), t, axis=1)
    numeric = np.abs(F) ** 2 / (2 * np.pi * T)
    exact = hann.delta_T(omega, T)
    # trapezoid on 20 001 points of a periodic smooth integrand: round-off level
    np.testing.assert_allclose(exact, numeric, rtol=1e-9, atol=1e-12 * exact.max())


@pytest.mark.parametrize("name", WINDOWS)
def test_delta_bins_equal_continuous_delta_at_integer_bins(name):
    win = get_window(name)
    k = np.arange(-40, 41)
    continuous = win.delta_T(2 * np.pi * k / T, T)
    discrete = win.delta_bins(k, M, T)
    # D^2 is a trigonometric polynomial of degree <= 2: the DFT is exact; the floor
    # covers the zeros (|k| >= 3 for Hann, k != 0 for the boxcar), where the closed
    # form leaves round-off of sin(2 pi k) / k
    np.testing.assert_allclose(discrete, continuous, rtol=1e-12, atol=1e-12 * continuous.max())
    if name == "hann":
        nz = np.abs(k) <= 2
        np.testing.assert_allclose(discrete[nz], continuous[nz], rtol=1e-12, atol=0)
        assert np.all(discrete[~nz] < 1e-25)


@pytest.mark.parametrize("name", WINDOWS)
def test_discrete_parseval_sum_of_delta_bins_is_k4(name):
    win = get_window(name)
    total = np.sum(win.delta_bins(np.arange(M), M, T)) * 2 * np.pi / T
    # Parseval: sum_k |DFT(D^2)/m|^2 = mean(D_n^4) = k4
    assert total == pytest.approx(win.k4, rel=1e-12)


def test_bin_correlation_is_real_even_and_one_at_zero():
    hann = get_window("hann")
    k = np.arange(-5, 6)
    rho = hann.rho(k, M)
    assert rho[5] == pytest.approx(1.0, rel=1e-14)
    np.testing.assert_allclose(rho, rho[::-1], atol=1e-15)
    # D^2 = 3/8 - cos(u)/2 + cos(2u)/8: DFT coefficients -1/4 and 1/16 over k2 = 3/8
    np.testing.assert_allclose(rho[6:8], [-2 / 3, 1 / 6], rtol=1e-12)
    np.testing.assert_allclose(rho[8:], 0.0, atol=1e-15)
    assert hann.rho(M + 1, M) == pytest.approx(-2 / 3)  # bins are periodic in m


def test_get_window_accepts_names_and_windows():
    assert get_window("Hanning").name == "hann"
    assert get_window("HANN").name == "hann"
    assert get_window("rect").name == "boxcar"
    assert get_window("rectangular").name == "boxcar"
    w = get_window("hann")
    assert get_window(w) is w
    assert isinstance(w, Window)


@pytest.mark.parametrize("bad", ["kaiser", "", 3, None])
def test_bad_window_raises(bad):
    with pytest.raises(ValueError, match="unknown window"):
        get_window(bad)
