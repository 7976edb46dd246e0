"""Derivatives, block spectra and trispectral domains against exact oracles."""

import itertools

import numpy as np
import pytest

from hosid import costs as C
from hosid.errors import HosidInputError
from hosid.records import Record
from hosid.spectra import block_spectra, derivatives, features, trispectral_domain


# ------------------------------------------------------------------ derivatives
def _fourier_signal(n, dt, ks, shift):
    """Sum of cosines at Fourier bins ks, with phase origin t = -shift; returns x, v, a."""
    T = n * dt
    t = np.arange(n) * dt + shift
    w = 2 * np.pi * np.asarray(ks)[:, None] / T
    amp = 1.0 / (1.0 + np.arange(len(ks)))[:, None]
    x = np.sum(amp * np.cos(w * t), axis=0)
    v = np.sum(-amp * w * np.sin(w * t), axis=0)
    a = np.sum(-amp * w**2 * np.cos(w * t), axis=0)
    return x, v, a


def test_spectral_derivative_exact_when_end_points_agree():
    n, dt = 1000, 0.01
    # phase origin half a step before t0: x is even about -dt/2, so x[0] == x[-1] and the
    # end-point line removed by derivatives() is flat
    x, v, a = _fourier_signal(n, dt, [3, 17, 40, 101], shift=dt / 2)
    vs, as_ = derivatives(x, dt)
    # round-off of an FFT of length 1e3 times |omega| <= 63 rad/s (|a| ~ 4e3)
    np.testing.assert_allclose(vs, v, atol=1e-8 * np.abs(v).max())
    np.testing.assert_allclose(as_, a, atol=1e-8 * np.abs(a).max())


def test_spectral_derivative_exact_for_general_periodic_signal():
    n, dt = 1000, 0.01
    x, v, a = _fourier_signal(n, dt, [3, 17, 40, 101], shift=0.123)
    vs, as_ = derivatives(x, dt, detrend=False)
    np.testing.assert_allclose(vs, v, atol=1e-8 * np.abs(v).max())
    np.testing.assert_allclose(as_, a, atol=1e-8 * np.abs(a).max())


def test_spectral_velocity_variance_on_paper_record(paper_run):
    rec, v_true = paper_run
    ev2 = np.mean(v_true**2)
    v_spec, _ = derivatives(rec.x, rec.dt, "spectral")
    v_cent, _ = derivatives(rec.x, rec.dt, "central")
    err_spec = np.mean(v_spec**2) / ev2 - 1
    err_cent = np.mean(v_cent**2) / ev2 - 1
    # measured on this record: spectral -2.0 % (power above Nyquist is lost),
    # central differences -7.9 %
    assert abs(err_spec) < 0.03
    assert abs(err_spec) < abs(err_cent)


def test_unknown_derivative_method_raises():
    with pytest.raises(ValueError, match="derivative method"):
        derivatives(np.zeros(32), 0.1, "fd4")


def test_features_order(linear_record):
    F = features(linear_record)
    x = linear_record.x
    assert F.shape == (5, x.size)
    np.testing.assert_array_equal(F[3], x)
    np.testing.assert_allclose(F[4], x**3)
    np.testing.assert_allclose(F[2], F[1] * np.abs(F[1]))


# ------------------------------------------------------------------ block spectra
@pytest.fixture(scope="module", params=["boxcar", "hann"])
def linear_spectra(request, linear_record):
    return block_spectra(linear_record, window=request.param)


def _linear_psd(omega, p):
    return p["S0"] / np.abs(p["a2"] - omega**2 + 1j * p["a1"] * omega) ** 2


def test_block_spectra_geometry(linear_spectra, linear_record):
    sp = linear_spectra
    assert sp.M == 1024 and sp.T == pytest.approx(20.48)
    assert sp.n_blocks == linear_record.n // 1024
    assert sp.k_max == int(8.0 * sp.T / (2 * np.pi))  # 26
    assert sp.Y.shape == (5, sp.n_blocks, 3 * sp.k_max + 1)
    assert sp.omega[-1] <= 8.0
    np.testing.assert_allclose(sp.omega, sp.band * 2 * np.pi / sp.T)


def test_linear_displacement_spectrum(linear_spectra, linear_params):
    sp = linear_spectra
    ratio = sp.cross_spectra[3, 3].real / sp.window.k2 / _linear_psd(sp.omega, linear_params)
    # 195 blocks: each bin has sd 1/sqrt(195) = 7 %, the band mean ~2 %; window leakage
    # biases the boxcar up (measured: boxcar +5.5 %, Hann +1.3 %); 10 % covers both
    assert np.mean(ratio) == pytest.approx(1.0, abs=0.10)
    assert np.all((ratio > 0.7) & (ratio < 1.3))  # per bin: within ~4 sd
    # eq (48): auto-spectra are real and the matrix is Hermitian
    U = sp.cross_spectra
    np.testing.assert_allclose(U, np.conj(np.swapaxes(U, 0, 1)), atol=1e-12 * np.abs(U).max())


def test_inferred_force_at_truth_is_white(linear_spectra, linear_params):
    sp = linear_spectra
    data = C.prepare(sp)
    p = linear_params
    theta = np.array([p["a1"], p["n1"], p["a2"], p["n2"], p["S0"]])
    va = data.second_order(theta) / (sp.window.k2 * p["S0"])
    # exact linear combination of the features -> windowed FFT of the force; band mean of
    # 26 bins x 195 blocks has sd ~1.5 % (measured: boxcar +0.5 %, Hann -0.6 %)
    assert np.mean(va) == pytest.approx(1.0, abs=0.05)


# ------------------------------------------------------------------ trispectral domains
@pytest.fixture(scope="module")
def small_spectra():
    rec = Record(np.random.default_rng(3).standard_normal(4096), 0.1)
    sp = block_spectra(rec, window="hann", block_seconds=25.6, omega_max=2.5)
    assert sp.k_max == 10
    return sp


def _brute_force_principal(lo, hi):
    rows = []
    r = [k for k in range(-hi, hi + 1) if abs(k) >= lo]
    for k1, k2, k3 in itertools.product(r, r, r):
        k4 = k1 + k2 + k3
        if not lo <= abs(k4) <= hi:
            continue
        if (
            k1 >= k2 >= k3
            and k4 >= 0
            and k1 + k2 + 2 * k3 >= 0
            and sum(k < 0 for k in (k1, k2, k3)) == 1
        ):
            rows.append((k1, k2, k3, k4))
    return sorted(rows)


def test_principal_domain_eq39(small_spectra):
    dom = trispectral_domain(small_spectra, "principal")
    k = dom.k
    k1, k2, k3, k4 = k.T
    lo, hi = small_spectra.k_min, small_spectra.k_max
    assert np.all(k4 == k1 + k2 + k3)
    assert np.all((k1 >= k2) & (k2 >= k3))
    assert np.all(k4 >= 0)
    assert np.all(k1 + k2 + 2 * k3 >= 0)
    assert np.all(np.sum(k[:, :3] < 0, axis=1) == 1)
    assert np.all((np.abs(k) >= lo) & (np.abs(k) <= hi))
    assert sorted(map(tuple, k.tolist())) == _brute_force_principal(lo, hi)
    assert len({tuple(row) for row in k.tolist()}) == dom.size


def test_reduced_domain_is_near_planes(small_spectra):
    principal = {tuple(r) for r in trispectral_domain(small_spectra, "principal").k.tolist()}
    red = trispectral_domain(small_spectra, "reduced")
    assert 0 < red.size < len(principal)
    assert {tuple(r) for r in red.k.tolist()} <= principal
    k = red.k
    near = np.min(np.abs([k[:, 0] + k[:, 1], k[:, 0] + k[:, 2], k[:, 1] + k[:, 2]]), axis=0)
    assert np.all(near <= 1)
    # and it is every principal row within one bin of a plane (eq 64 as a union)
    n_near = sum(min(abs(a + b), abs(a + c), abs(b + c)) <= 1 for a, b, c, _ in principal)
    assert red.size == n_near


def test_full_domain_is_symmetric(small_spectra):
    full = trispectral_domain(small_spectra, "full")
    rows = {tuple(r) for r in full.k[:, :3].tolist()}
    assert len(rows) == full.size
    for k1, k2, k3 in rows:
        assert (-k1, -k2, -k3) in rows
        assert all(p in rows for p in itertools.permutations((k1, k2, k3)))


def test_domain_gauss_is_delta_of_pair_sums(small_spectra):
    dom = trispectral_domain(small_spectra, "principal")
    k, sp = dom.k, small_spectra
    sums = np.stack([k[:, 0] + k[:, 1], k[:, 0] + k[:, 2], k[:, 1] + k[:, 2]], axis=1)
    expected = sp.window.delta_T_bins(sums, sp.M, sp.T)
    np.testing.assert_allclose(dom.delta, expected, rtol=1e-10, atol=1e-12 * sp.T)
    np.testing.assert_allclose(dom.gauss, expected.sum(axis=1), rtol=1e-10, atol=1e-12 * sp.T)


def test_unknown_domain_raises(small_spectra):
    with pytest.raises(ValueError, match="trispectral domain"):
        trispectral_domain(small_spectra, "octant")


# ------------------------------------------------------------------ validation
def test_too_short_record_raises():
    rec = Record(np.zeros(5000), 0.02)  # 100 s: 4 blocks of 20.48 s
    with pytest.raises(HosidInputError, match="too short"):
        block_spectra(rec)


def test_omega_max_above_nyquist_raises():
    rec = Record(np.zeros(20000), 0.02)  # Nyquist 157 rad/s
    with pytest.raises(HosidInputError, match="Nyquist"):
        block_spectra(rec, omega_max=200.0)


def test_too_few_bins_and_too_short_blocks_raise():
    rec = Record(np.zeros(20000), 0.02)
    with pytest.raises(HosidInputError, match="fewer than 3"):
        block_spectra(rec, omega_max=0.5)
    with pytest.raises(HosidInputError, match="samples"):
        block_spectra(rec, block_seconds=0.1)
