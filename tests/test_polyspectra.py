"""Generic polyspectral costs (hosid.polyspectra) against exact oracles.

* J2W / J4W with the five standard features equal hosid.costs J2W / J4AW.
* J3W of a Gaussian white force: mean 0 and the spread predicted exactly by Isserlis'
  theorem over pairs of bispectral ordinates (computed here independently).
* A skewed white force: the normalized bispectrum has the flat analytic mean
  kappa3 dt^3 sum D^3 / (2 pi T k2 S0)^(3/2) and E J3W = N sum |E h|^2 / v.
* A force mean does not reach J3W (Hann window, k >= 2).
* A coloured force is centred by the right spectral shape.

Replicate series are batched as feature rows with ``lam = identity``, so one call
evaluates the cost of every replicate.  All draws use fixed seeds.
"""

import numpy as np
import pytest

from hosid import costs as C
from hosid import polyspectra as P
from hosid.errors import HosidInputError
from hosid.simulate import simulate
from hosid.spectra import block_spectra, features
from hosid.windows import get_window

# white-force oracle set-up: M = 128, T = 6.4 s, band bins 1..24, 64 blocks per series
DT, M, K_MAX, N_BLOCKS, S0 = 0.05, 128, 24, 64, 1.0
T = M * DT
OMEGA_MAX = (K_MAX + 0.5) * 2 * np.pi / T
SIGMA = np.sqrt(2 * np.pi * S0 / DT)  # per-sample sd of a white force of level S0
R = 200  # replicate series


def _spectra(F) -> P.FeatureSpectra:
    return P.feature_spectra(F, DT, block_seconds=T, omega_max=OMEGA_MAX)


def _replicates(draw, seed: int, mean: float = 0.0) -> P.FeatureSpectra:
    """R independent white series of variance SIGMA^2 as R feature rows."""
    rng = np.random.default_rng(seed)
    return _spectra(draw(rng, (R, N_BLOCKS * M)) * SIGMA + mean)


def _gauss(rng, size):
    return rng.standard_normal(size)


def _exponential(rng, size):
    return rng.exponential(size=size) - 1.0  # unit variance, third cumulant 2


@pytest.fixture(scope="module")
def gauss_fs():
    return _replicates(_gauss, seed=11)


@pytest.fixture(scope="module")
def gauss_j3(gauss_fs):
    return P.j3w(gauss_fs, np.eye(R), S0)


def _rho() -> np.ndarray:
    d2 = get_window("hann").samples(M) ** 2
    return np.fft.fft(d2).real / d2.sum()


def _sixth_moment(s: np.ndarray, rho: np.ndarray) -> np.ndarray:
    """E of the product of six ordinates z(s_i) on signed bins (Isserlis, 15 pairings)."""

    def pairings(items):
        if not items:
            yield []
            return
        for i in range(1, len(items)):
            for rest in pairings(items[1:i] + items[i + 1 :]):
                yield [(items[0], items[i]), *rest]

    total = 0.0
    for m in pairings(list(range(6))):
        term = 1.0
        for a, b in m:
            term = term * rho[(s[..., a] + s[..., b]) % M]
        total = total + term
    return total


# ------------------------------------------------------------------ equality with costs
def test_j2w_j4w_equal_costs_for_the_five_features():
    rec = simulate(
        {"a1": 0.5, "n1": 0.5, "a2": 25.0, "n2": 5.0, "S0": 100.0},
        duration=600,
        dt=0.02,
        rng=np.random.default_rng(1),
    )
    data = C.prepare(block_spectra(rec, block_seconds=20.48, omega_max=8.0))
    fs = P.feature_spectra(features(rec), rec.dt, block_seconds=20.48, omega_max=8.0)
    assert fs.Y.shape == data.spectra.Y.shape
    theta = np.array([0.5, 0.5, 25.0, 5.0, 100.0]) * np.random.default_rng(0).uniform(
        0.7, 1.3, size=(6, 5)
    )
    lam = np.concatenate([np.ones((6, 1)), theta[:, :4]], axis=1)
    np.testing.assert_array_equal(P.trispectral_domain_k(fs), data.domain.k)
    for name, cost in (("J2W", P.j2w), ("J4AW", P.j4w)):
        ref = C.evaluate_cost(name, theta, data)
        np.testing.assert_allclose(cost(fs, lam, theta[:, 4]), ref, rtol=1e-10, err_msg=name)
        # one force at a time (the single-force trispectrum kernel)
        np.testing.assert_allclose(cost(fs, lam[2], theta[2, 4]), ref[2], rtol=1e-10)
    np.testing.assert_allclose(
        P.combined(fs, lam, theta[:, 4], orders=(2, 4), weights=(2.0, 0.5)),
        2 * C.J2W(theta, data) + 0.5 * C.J4AW(theta, data),
        rtol=1e-10,
    )


# ------------------------------------------------------------------ bispectral cost
def test_bispectral_domain():
    fs = _spectra(np.zeros((1, N_BLOCKS * M)))
    k = P.bispectral_domain(fs)
    assert k.shape == (121, 3)  # sum over k2 = 2..12 of (25 - 2 k2)
    assert np.all((k[:, 1] >= 2) & (k[:, 1] <= k[:, 0]) & (k[:, 2] == k[:, 0] + k[:, 1]))
    assert k[:, 2].max() == K_MAX
    assert len({tuple(r) for r in k}) == k.shape[0]


def test_j3w_gaussian_null_is_centred_with_isserlis_spread(gauss_fs, gauss_j3):
    k = P.bispectral_domain(gauss_fs)
    rho = _rho()
    # Var J3W = N/(N-1) sum_{t,u} (|E h_t h_u*|^2 + |E h_t h_u|^2) / (v_t v_u)
    a, b = k[:, None, :], k[None, :, :]

    def signed(*cols):
        return np.stack(np.broadcast_arrays(*cols), axis=-1)

    c = _sixth_moment(
        signed(a[..., 0], a[..., 1], -a[..., 2], -b[..., 0], -b[..., 1], b[..., 2]), rho
    )
    p = _sixth_moment(
        signed(a[..., 0], a[..., 1], -a[..., 2], b[..., 0], b[..., 1], -b[..., 2]), rho
    )
    v = np.diag(c)
    np.testing.assert_allclose(v, gauss_fs._bi[1], rtol=1e-12)
    sd = np.sqrt(N_BLOCKS / (N_BLOCKS - 1) * np.sum((c**2 + p**2) / np.outer(v, v)))
    # measured (seed 11): mean -0.45 (se 1.1), sd 15.5; exact sd 16.0; sqrt(2 n) = 15.6
    J = gauss_j3
    assert abs(J.mean()) < 3 * sd / np.sqrt(R)
    assert J.std(ddof=1) == pytest.approx(sd, rel=0.15)  # sd of a sd of 200 draws ~ 5 %
    assert J.std(ddof=1) == pytest.approx(np.sqrt(2 * k.shape[0]), rel=0.25)


def test_j3w_skewed_force(gauss_fs, gauss_j3):
    fs = _replicates(_exponential, seed=12)
    J = P.j3w(fs, np.eye(R), S0)
    h = P.normalized_bispectrum(fs, np.eye(R), S0)  # (R, n_domain)
    D = fs.window.samples(M)
    kappa3 = 2 * SIGMA**3
    flat = kappa3 * DT**3 * np.sum(D**3) / (2 * np.pi * T * fs.window.k2 * S0) ** 1.5  # 0.241
    # replicate means of h: measured 0.243 = 1.010 flat, se 1.2 % of flat
    per_rep = h.mean(axis=-1)
    assert per_rep.real.mean() == pytest.approx(flat, rel=0.1)
    assert abs(per_rep.imag.mean()) < 0.05 * flat
    # unbiased U-statistic: E J3W = N sum |E h|^2 / v = 413; measured 420 (se 9.8)
    expected = N_BLOCKS * flat**2 * np.sum(1 / fs._bi[1])
    assert J.mean() == pytest.approx(expected, rel=0.1)
    assert J.mean() > 15 * gauss_j3.std(ddof=1)


def test_force_mean_does_not_reach_j3w(gauss_fs, gauss_j3):
    shifted = _replicates(_gauss, seed=11, mean=3 * SIGMA)  # same draws, mean added
    assert not np.allclose(shifted.Y[:, :, :2], gauss_fs.Y[:, :, :2])
    np.testing.assert_allclose(P.j3w(shifted, np.eye(R), S0), gauss_j3, rtol=1e-9, atol=1e-9)


# ------------------------------------------------------------------ coloured excitation
def test_shape_centres_a_coloured_force():
    wc = 5.0

    def lowpass(w):
        return wc**2 / (wc**2 + w**2)

    n = N_BLOCKS * M
    w = np.random.default_rng(13).standard_normal(n) * SIGMA
    omega = 2 * np.pi * np.fft.rfftfreq(n, DT)
    g = np.fft.irfft(np.fft.rfft(w) * wc / (wc + 1j * omega), n)  # |H|^2 = lowpass
    fs = _spectra(g)
    bound = 4 * np.sqrt(2 * fs.band.size)  # 27.7; measured sd over 20 seeds 8.7
    right = P.j2w(fs, [1.0], S0, shape=lowpass)
    wrong = P.j2w(fs, [1.0], S0)
    assert abs(right) < bound
    assert wrong > 20 * bound  # measured: right -13.4, wrong 924
    # fourth order: the shape removes most of J4W too (measured -696 vs 8179;
    # white null sd ~ 215)
    assert abs(P.j4w(fs, [1.0], S0, shape=lowpass)) < 0.2 * P.j4w(fs, [1.0], S0)
    with pytest.raises(HosidInputError, match="positive"):
        P.j2w(fs, [1.0], S0, shape=lambda w: w - 1.0)


# ------------------------------------------------------------------ batches
def test_batch_shapes_equal_the_loop():
    rng = np.random.default_rng(14)
    F = rng.standard_normal((3, N_BLOCKS * M))
    F[1] = F[0] ** 2
    fs = _spectra(F)
    lam = np.concatenate([np.ones((3, 4, 1)), rng.normal(size=(3, 4, 2))], axis=-1)
    S0s = rng.uniform(0.5, 2.0, size=(3, 4))
    X = P.inferred_force(fs, lam)
    assert X.shape == (3, 4, N_BLOCKS, fs.Y.shape[2])
    np.testing.assert_allclose(X[1, 2], np.tensordot(lam[1, 2], fs.Y, axes=1), rtol=1e-12)
    costs = {
        "j2w": P.j2w,
        "j3w": P.j3w,
        "j4w": P.j4w,
        "combined": lambda f, lm, s: P.combined(f, lm, s, weights=(1.0, 2.0, 0.5)),
    }
    for name, cost in costs.items():
        batch = cost(fs, lam, S0s)
        assert batch.shape == (3, 4), name
        loop = np.array([[cost(fs, lam[i, j], S0s[i, j]) for j in range(4)] for i in range(3)])
        np.testing.assert_allclose(batch, loop, rtol=1e-10, err_msg=name)
        assert cost(fs, lam, 1.5).shape == (3, 4)  # scalar S0 broadcasts
    comb = P.combined(fs, lam, S0s, weights=(1.0, 2.0, 0.5))
    parts = P.j2w(fs, lam, S0s) + 2 * P.j3w(fs, lam, S0s) + 0.5 * P.j4w(fs, lam, S0s)
    np.testing.assert_allclose(comb, parts, rtol=1e-10)
    assert P.normalized_bispectrum(fs, lam, S0s).shape == (3, 4, 121)
    with pytest.raises(ValueError, match="lam must have shape"):
        P.j2w(fs, np.ones(4), 1.0)


# ------------------------------------------------------------------ bad input
@pytest.mark.parametrize(
    ("n", "bad", "match"),
    [
        (N_BLOCKS * M, True, "non-finite"),
        (7 * M + 5, False, "too short for 8 blocks"),
    ],
)
def test_bad_input(n, bad, match):
    F = np.random.default_rng(15).standard_normal((2, n))
    if bad:
        F[1, 100] = np.nan
    with pytest.raises(HosidInputError, match=match) as err:
        _spectra(F)
    assert "\n" not in str(err.value)
