"""Block layout, block transforms and the higher-order spectral domains (eqs 39, 64)."""

import itertools
import math

import numpy as np
import pytest

from hosid.errors import HosidInputError
from hosid.spectra import (
    BlockLayout,
    bispectral_domain,
    block_fft,
    block_means,
    choose_layout,
    get_window,
    trispectral_domain,
)
from hosid.spectra.blocks import MIN_BLOCKS, MIN_PERIODS, PERIODS
from hosid.state import RecordState

DT = 0.02
OMEGA_PAPER = 6.26  # sigma_v / sigma_x of the paper oscillator at S0 = 100


# ------------------------------------------------------------------ layout
def test_paper_record_gets_the_papers_blocks(paper_record):
    # 16 periods of ~6.3 rad/s = 16 s -> 2^round(log2(800)) = 1024 samples = 20.48 s
    lay = RecordState.from_record(paper_record).layout
    assert (lay.M, lay.B) == (1024, 97)
    assert lay.T == pytest.approx(20.48)
    assert choose_layout(100_000, DT, OMEGA_PAPER) == BlockLayout(1024, 97, DT)


def test_short_record_halves_the_blocks_to_keep_24():
    # 500 s = 25 000 samples still holds 24 blocks of 1024 (24 576 samples); 480 s does not
    assert choose_layout(25_000, DT, OMEGA_PAPER) == BlockLayout(1024, 24, DT)
    assert choose_layout(24_000, DT, OMEGA_PAPER) == BlockLayout(512, 46, DT)
    assert MIN_BLOCKS == 24


def test_target_blocks_halve_the_blocks_down_to_four_periods():
    # a system's many equations ask for more blocks: 150 -> 512 samples (195 blocks); 1000
    # -> 256 samples (5.12 s, 5.1 periods of 6.3 rad/s), as 128 would hold 2.6 periods
    assert choose_layout(100_000, DT, OMEGA_PAPER, target_blocks=150) == BlockLayout(512, 195, DT)
    assert choose_layout(100_000, DT, OMEGA_PAPER, target_blocks=1000).M == 256
    assert choose_layout(100_000, DT, OMEGA_PAPER, target_blocks=97).M == 1024


def test_block_length_follows_the_resonance():
    # 16 periods rounded to a power of two (in log2)
    for omega in (2.0, 5.0, 20.0):
        M = choose_layout(1_000_000, DT, omega).M
        target = PERIODS * 2 * math.pi / omega / DT
        assert M == 2 ** round(math.log2(target))


def test_short_block_seconds_and_short_records_are_rejected():
    with pytest.raises(HosidInputError) as err:
        choose_layout(2500, DT, OMEGA_PAPER)  # 50 s: 24 blocks of 256 samples need 122.88 s
    msg = str(err.value)
    assert "\n" not in msg
    assert "record of 50 s is too short" in msg
    assert f"{MIN_BLOCKS} blocks of at least {MIN_PERIODS:.0f} periods (256 samples)" in msg
    assert "need 122.88 s" in msg
    with pytest.raises(HosidInputError, match="use longer blocks"):
        choose_layout(100_000, DT, OMEGA_PAPER, block_seconds=0.2)
    with pytest.raises(HosidInputError, match="too short for 24 blocks of 4096 samples"):
        choose_layout(90_000, DT, OMEGA_PAPER, block_seconds=81.92)


def test_explicit_block_seconds():
    assert choose_layout(100_000, DT, OMEGA_PAPER, block_seconds=10.24) == BlockLayout(
        512, 195, DT
    )
    # no power-of-two rounding when the length is given
    assert choose_layout(100_000, DT, OMEGA_PAPER, block_seconds=10.0).M == 500


def test_layout_properties_and_bins():
    lay = BlockLayout(M=1024, B=97, dt=DT)
    assert lay.T == pytest.approx(20.48)
    assert lay.d_omega == pytest.approx(2 * math.pi / 20.48)
    assert lay.n_used == 1024 * 97
    assert lay.as_dict() == {"block_samples": 1024, "blocks": 97, "block_seconds": lay.T}
    k = lay.bins(0.0, 8.0)
    np.testing.assert_array_equal(k, np.arange(1, 27))  # paper band: 26 bins up to 8 rad/s
    np.testing.assert_array_equal(lay.bins(0.0, 8.0, k_min=2), np.arange(2, 27))
    assert lay.bins(0.0, 1e9)[-1] == 511  # below the Nyquist bin
    # a bin on the edge is kept (tolerance 1e-12)
    assert lay.bins(lay.d_omega * 3, lay.d_omega * 3).tolist() == [3]


# ------------------------------------------------------------------ transforms
def test_block_fft_is_the_windowed_dft_of_each_block():
    rng = np.random.default_rng(4)
    lay = BlockLayout(M=64, B=5, dt=0.1)
    y = rng.standard_normal(lay.n_used + 17)  # the tail beyond the blocks is dropped
    Y = block_fft(y, lay, "hann")
    assert Y.shape == (5, 33)
    n = np.arange(64)
    D = 0.5 * (1 - np.cos(2 * np.pi * n / 64))
    for b in (0, 4):
        seg = y[b * 64 : (b + 1) * 64]
        for k in (0, 3, 32):
            ref = 0.1 * np.sum(seg * D * np.exp(-2j * np.pi * k * n / 64))  # eq (46)
            assert Y[b, k] == pytest.approx(ref, rel=1e-12, abs=1e-12)
    bins = np.array([2, 5])
    np.testing.assert_array_equal(block_fft(y, lay, get_window("hann"), bins), Y[:, bins])
    # leading axes broadcast
    both = block_fft(np.stack([y, 2 * y]), lay, "boxcar")
    np.testing.assert_allclose(both[1], 2 * block_fft(y, lay, "boxcar"), rtol=1e-14)


def test_block_means():
    lay = BlockLayout(M=4, B=3, dt=1.0)
    y = np.arange(14.0)
    np.testing.assert_array_equal(block_means(y, lay), [1.5, 5.5, 9.5])
    np.testing.assert_array_equal(block_means(np.stack([y, -y]), lay)[1], [-1.5, -5.5, -9.5])


def test_periodogram_of_white_noise_is_its_level():
    """Hann-windowed block periodogram / (2 pi T k2) of white noise of variance s^2 at dt
    has mean s^2 dt / (2 pi): the two-sided density."""
    rng = np.random.default_rng(5)
    lay = BlockLayout(M=256, B=400, dt=0.05)
    y = rng.standard_normal(lay.n_used)
    Y = block_fft(y, lay, "hann", np.arange(5, 120))
    P = np.mean(np.abs(Y) ** 2, axis=0) / (2 * math.pi * lay.T * 3 / 8)
    # 400 blocks x 115 bins, neighbouring Hann bins correlated: sd of the mean < 0.5 %
    # (measured +0.1 %)
    assert np.mean(P) == pytest.approx(0.05 / (2 * math.pi), rel=0.02)


# ------------------------------------------------------------------ domains
def _brute_force_principal(k_min, k_max):
    rows = []
    r = [k for k in range(-k_max, k_max + 1) if abs(k) >= k_min]
    for k1, k2, k3 in itertools.product(r, r, r):
        k4 = k1 + k2 + k3
        if not k_min <= abs(k4) <= k_max:
            continue
        if (
            k1 >= k2 >= k3
            and k4 >= 0
            and k1 + k2 + 2 * k3 >= 0
            and sum(k < 0 for k in (k1, k2, k3)) == 1
        ):
            rows.append((k1, k2, k3, k4))
    return sorted(rows)


def test_principal_domain_of_the_papers_band_has_3107_triples():
    # 8 rad/s with 20.48 s blocks: k_max = floor(8 * 20.48 / 2 pi) = 26
    assert math.floor(8.0 * 20.48 / (2 * math.pi)) == 26
    assert trispectral_domain(26, "principal").shape == (3107, 4)


@pytest.mark.parametrize(("k_min", "k_max"), [(1, 10), (2, 9)])
def test_principal_domain_eq39_against_brute_force(k_min, k_max):
    k = trispectral_domain(k_max, "principal", k_min=k_min)
    k1, k2, k3, k4 = k.T
    assert np.all(k4 == k1 + k2 + k3)
    assert np.all((k1 >= k2) & (k2 >= k3) & (k4 >= 0) & (k1 + k2 + 2 * k3 >= 0))
    assert np.all(np.sum(k[:, :3] < 0, axis=1) == 1)
    assert np.all((np.abs(k) >= k_min) & (np.abs(k) <= k_max))
    assert sorted(map(tuple, k.tolist())) == _brute_force_principal(k_min, k_max)


@pytest.mark.parametrize("k_max", [10, 26])
def test_reduced_domain_is_the_principal_rows_within_one_bin_of_a_plane(k_max):
    principal = {tuple(r) for r in trispectral_domain(k_max, "principal").tolist()}
    red = trispectral_domain(k_max, "reduced")
    rows = {tuple(r) for r in red.tolist()}
    assert len(rows) == red.shape[0]
    assert 0 < len(rows) < len(principal)
    assert rows <= principal
    near = np.min(np.abs([red[:, 0] + red[:, 1], red[:, 0] + red[:, 2], red[:, 1] + red[:, 2]]), 0)
    assert np.all(near <= 1)
    # eq (64) read as a union: every principal row near some plane is in
    n_near = sum(min(abs(a + b), abs(a + c), abs(b + c)) <= 1 for a, b, c, _ in principal)
    assert len(rows) == n_near


def test_full_domain_is_closed_under_sign_and_permutation():
    full = trispectral_domain(6, "full")
    rows = {tuple(r) for r in full[:, :3].tolist()}
    assert len(rows) == full.shape[0]
    for k1, k2, k3 in rows:
        assert (-k1, -k2, -k3) in rows
        assert all(p in rows for p in itertools.permutations((k1, k2, k3)))


def test_unknown_domain_raises():
    with pytest.raises(ValueError, match="unknown trispectral domain 'octant'"):
        trispectral_domain(10, "octant")


@pytest.mark.parametrize("k_min", [1, 2, 3])
def test_bispectral_domain(k_min):
    k = bispectral_domain(24, k_min=k_min)
    lo = max(k_min, 2)
    assert np.all(k[:, 1] >= lo)  # the Hann window leaks a constant into bins 0, 1 only
    assert np.all(k[:, 1] >= 2)
    assert np.all((k[:, 1] <= k[:, 0]) & (k[:, 2] == k[:, 0] + k[:, 1]) & (k[:, 2] <= 24))
    assert len({tuple(r) for r in k.tolist()}) == k.shape[0]
    # count: sum over k2 = lo..12 of (24 - 2 k2 + 1)
    assert k.shape[0] == sum(25 - 2 * k2 for k2 in range(lo, 13))
    if k_min <= 2:
        assert k.shape == (121, 3)


def test_blocks_stay_inside_segments():
    # segments of 3000, 500 and 2100 samples hold 2, 0 and 2 blocks of 1024
    bounds = [(0, 3000), (3000, 3500), (3500, 5600)]
    lay = choose_layout(5600, DT, OMEGA_PAPER, block_seconds=20.48, min_blocks=4, bounds=bounds)
    assert (lay.M, lay.B) == (1024, 4)
    np.testing.assert_array_equal(lay.offsets, [0, 1024, 3500, 4524])
    y = np.arange(5600.0)
    blocks = lay.take(y)
    np.testing.assert_array_equal(blocks[:, 0], lay.offsets)
    np.testing.assert_array_equal(block_means(y, lay), lay.offsets + 511.5)
    with pytest.raises(HosidInputError, match="in 3 segments\\) is too short for 5 blocks"):
        choose_layout(5600, DT, OMEGA_PAPER, block_seconds=20.48, min_blocks=5, bounds=bounds)
    # automatic blocks are halved until the segments hold enough of them
    auto = choose_layout(5600, DT, OMEGA_PAPER, min_blocks=10, bounds=bounds)
    assert (auto.M, auto.B) == (256, 20)  # 512 gives 5 + 0 + 4 = 9
    assert choose_layout(5600, DT, OMEGA_PAPER, min_blocks=10).starts is None


def test_a_single_segment_keeps_its_start():
    lay = choose_layout(5600, DT, OMEGA_PAPER, block_seconds=20.48, min_blocks=4,
                        bounds=[(300, 5400)])  # fmt: skip
    np.testing.assert_array_equal(lay.offsets, [300, 1324, 2348, 3372])
    np.testing.assert_array_equal(lay.take(np.arange(5600.0))[:, 0], lay.offsets)


def test_a_smooth_states_blocks_keep_clear_of_the_ends(paper_record):
    """The jerk's end error (hosid.state module docstring): JERK_MARGIN end fits (an
    eighth of a period each) at each end hold no block sample.
    """
    from hosid.state import JERK_MARGIN

    st = RecordState.from_record(paper_record, smooth=True)
    n_fit = max(round(2 * math.pi / st.scales.omega_n / DT / 8), 8)
    first = st.layout.offsets
    assert first[0] >= JERK_MARGIN * n_fit
    assert first[-1] + st.layout.M <= paper_record.x.size - JERK_MARGIN * n_fit
    assert RecordState.from_record(paper_record).layout.offsets[0] == 0


def test_inner_bounds_cut_the_margin_at_each_end_and_drop_short_segments():
    """Each kept segment is its segment less ``margin`` samples at either end; a segment
    of at most two margins is dropped (the smooth state's jerk margin and the integrated
    accelerations' band margin both use it).
    """
    from hosid.spectra.blocks import inner_bounds

    assert inner_bounds([(0, 100), (200, 220), (300, 321)], 10) == [(10, 90), (310, 311)]
    assert inner_bounds([(0, 20)], 10) == []
    assert inner_bounds([(5, 50)], 0) == [(5, 50)]
