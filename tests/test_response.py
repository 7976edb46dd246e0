"""What the record's response spectrum says before a fit (resonance, bandwidth, excitation
edge, noise floor), the block layout and band it sets, and segments that repeat."""

import math

import numpy as np
import pytest

from hosid.components.spectral import default_band
from hosid.errors import HosidInputError
from hosid.model import simulate
from hosid.record import Record
from hosid.spectra.blocks import BINS_PER_BANDWIDTH, choose_layout, distinct_bounds, repeat_lag
from hosid.spectra.response import response_spectrum
from hosid.state import RecordState

LINEAR = {"a1": 1.0, "a2": 25.0, "S0": 10.0}


def _lowpass(record: Record, edge: float) -> Record:
    """The record with everything above ``edge`` rad/s removed (a brick-wall filter): for
    a linear system, the response to an excitation that stops at ``edge``.
    """
    X = np.fft.rfft(record.x)
    X[2 * math.pi * np.fft.rfftfreq(record.n, record.dt) > edge] = 0.0
    return Record(np.fft.irfft(X, record.n), record.dt)


def test_the_edge_of_a_band_limited_response(linear_record):
    cut = _lowpass(linear_record, 20.0)  # w_N = 157 rad/s, resonance 5 rad/s
    st = RecordState.from_record(cut)
    sp = st.spectrum
    assert sp.band_limited and sp.edge[0] <= 20.0 <= sp.edge[1] + 0.1
    assert sp.edge[1] - sp.edge[0] < 2.0
    assert st.scales.band_edge == sp.edge
    assert "band-limited" in sp.summary() and st.describe()["excitation_edge_rad_s"]
    # the J2 band stays below 0.9 of the edge
    assert default_band(st)[1] == pytest.approx(min(6 * st.scales.omega_n, 0.9 * sp.edge[0]))
    white = RecordState.from_record(linear_record).spectrum
    assert not white.band_limited and white.edge is None
    with pytest.raises(HosidInputError, match="holds 16 samples"):
        response_spectrum(np.sin(np.arange(10.0)), 0.1, sigma_v=1.0)


def test_bandwidth_and_resonance_of_a_linear_oscillator(linear_record):
    sp = RecordState.from_record(linear_record).spectrum
    # sigma_x^2 / (pi max S_x) = c for light damping; Welch and smoothing blur the peak:
    # measured 1.16 for c = 1 on this record
    assert sp.bandwidth == pytest.approx(LINEAR["a1"], rel=0.3)
    assert sp.peak == pytest.approx(math.sqrt(LINEAR["a2"]), rel=0.05)
    assert sp.floor_edge > 10 * sp.peak  # no noise: no floor near the band


def test_noise_floor_and_where_the_response_meets_it():
    noisy = simulate({**LINEAR, "noise_sd": 0.05}, duration=2000.0,
                     rng=np.random.default_rng(4))  # fmt: skip
    st = RecordState.from_record(noisy)
    sp = st.spectrum
    floor = 0.05**2 * noisy.dt / (2 * math.pi)  # white noise of sd 0.05, two-sided
    assert sp.floor == pytest.approx(floor, rel=0.3)  # measured -8 %
    assert sp.floor_edge == pytest.approx((sp.level / sp.floor) ** 0.25)
    # the force level A (about 1.6 S0 on [1.5, 2.5] w_n) over w^4 meets the floor near
    # (16 / 8e-6)^(1/4) = 38 rad/s; the J2 band stops at half of it, below 6 w_n = 30
    assert 30.0 < sp.floor_edge < 45.0
    assert default_band(st)[1] == pytest.approx(0.5 * sp.floor_edge)
    assert "noise floor" in sp.summary()


def test_blocks_resolve_the_resonance_bandwidth():
    # 16 periods of 5 rad/s are 20 s; 4 bins across a bandwidth of 0.1 rad/s need 251 s
    dt = 0.05
    short = choose_layout(200_000, dt, 5.0, bandwidth=10.0)
    assert short.M == 2 ** round(math.log2(16 * 2 * math.pi / 5.0 / dt))
    narrow = choose_layout(200_000, dt, 5.0, bandwidth=0.1)
    target = BINS_PER_BANDWIDTH * 2 * math.pi / 0.1 / dt
    assert narrow.M == 2 ** round(math.log2(target))
    assert choose_layout(30_000, dt, 5.0, bandwidth=0.1).B >= 24  # halved for 24 blocks


def test_repeating_segments_keep_their_first_copy_only():
    rng = np.random.default_rng(2)
    y = rng.standard_normal(400)
    odd = np.concatenate([y, -y])  # an antiperiodic segment (odd multisine response)
    lag, r = repeat_lag(odd)
    assert lag == 400 and r == pytest.approx(-1.0, abs=1e-12)
    three = np.concatenate([y[:300]] * 3)  # periodic, three periods: the first copy
    assert repeat_lag(three)[0] == 300 and repeat_lag(three)[1] == pytest.approx(1.0)
    x = np.concatenate([odd, rng.standard_normal(700), three])
    bounds, found = distinct_bounds(x, [(0, 800), (800, 1500), (1500, 2400)])
    assert bounds == [(0, 400), (800, 1500), (1500, 1800)]
    assert found[1] is None and found[0][0] == 400
    assert abs(repeat_lag(rng.standard_normal(5000))[1]) < 0.2  # noise does not repeat


def test_a_state_of_repeating_segments_blocks_the_first_copies(linear_record):
    piece = linear_record.x[:20_000] - linear_record.x[:20_000].mean()
    rec = Record.from_segments([np.concatenate([p, -p]) for p in np.split(piece, 4)], 0.02)
    st = RecordState.from_record(rec, block_seconds=10.24)
    assert st.layout.B == 4 * (5000 // 512)  # 9 blocks in each segment's first half
    assert np.all(st.layout.offsets % 10_000 + 512 <= 5000)
    assert "4 of 4 segments repeat themselves after 5000 samples" in st.repeat_note()
    assert st.describe()["repeating_segments"] == st.repeat_note()
    assert RecordState.from_record(linear_record).repeat_note() is None
