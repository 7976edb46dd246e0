r"""Velocity and displacement integrated from an acceleration channel in its band.

Oracles:

- a sum of sinusoids on the Fourier grid of each segment integrates exactly (to 1e-9
  relative) above the band edge and vanishes below it, from point samples
  (``boxcar=False``) and from interval averages (``boxcar=True``, the exact boxcar of the
  sinusoids); without the correction an interval average's displacement is short by
  exactly :math:`\mathrm{sinc}(\omega\Delta t/2)`;
- a linear oscillator simulated with :func:`hosid.model.chain.simulate_chain` gives its
  interval-averaged acceleration and its displacement and velocity at the sample times
  from one run (``return_state=True``): the integral matches them, band-passed alike,
  away from the segment's ends, to twice what the samples cannot give (the module
  docstring of :mod:`hosid.spectra.integrate`: a random walk of spectrum
  :math:`S_0\Delta t^2/(12\omega^2)` in the displacement and a white
  :math:`S_0\Delta t^2/4` in the velocity);
- an added white noise or random-walk drift moves the band edge above the frequency where
  it equals the response's acceleration, and the displacement in that band stays within
  what the floor allows (and 10 %) of the noise-free record's.
"""

import math
import re

import numpy as np
import pytest

from hosid.errors import HosidInputError
from hosid.model.chain import simulate_chain
from hosid.model.system import System
from hosid.spectra.integrate import (
    BAND_RISE,
    acceleration_band,
    integrate_acceleration,
    integrate_in_time,
)

DT = 0.02
A1, A2, S0 = 1.0, 25.0, 10.0


def _s_acc(w):
    """The linear oscillator's acceleration spectrum, w^4 S0 / |A2 - w^2 + i A1 w|^2."""
    return w**4 * S0 / ((A2 - w**2) ** 2 + (A1 * w) ** 2)


@pytest.fixture(scope="module")
def run():
    """400 s of the linear oscillator: (acceleration, displacement, velocity)."""
    system = System.single("linear", {"a1": A1, "a2": A2, "S0": S0})
    rec, q, v = simulate_chain(system, duration=400.0, dt=DT, rng=np.random.default_rng(1),
                               measured="acceleration", return_state=True)  # fmt: skip
    return rec.x, q[:, 0], v[:, 0]


def _bandpass(y, lo, hi):
    w = 2.0 * np.pi * np.fft.rfftfreq(y.size, DT)
    F = np.fft.rfft(y)
    F[(w < lo) | (w > hi)] = 0.0
    return np.fft.irfft(F, y.size)


# ----------------------------------------------------------------------- sinusoids
def _tones(n, ks, amps, phases, dt=DT):
    """Displacement, velocity, point acceleration and interval-averaged acceleration of
    a sum of sinusoids at bins ``ks`` of ``n`` samples.
    """
    t = dt * np.arange(n)
    w = 2.0 * np.pi * np.asarray(ks) / (n * dt)
    arg = np.outer(t, w) + phases
    x = np.cos(arg) @ amps
    v = -np.sin(arg) @ (amps * w)
    a = -np.cos(arg) @ (amps * w**2)
    vel = lambda s: -np.sin(np.outer(s, w) + phases) @ (amps * w)  # noqa: E731
    boxcar = (vel(t + dt / 2) - vel(t - dt / 2)) / dt
    return w, x, v, a, boxcar


@pytest.mark.parametrize("boxcar", [False, True])
def test_sinusoids_integrate_exactly_above_the_edge(boxcar):
    n = 4096
    ks = np.array([3, 40, 300, 1024, 1900])  # 0.23 ... 146 rad/s; the first below the edge
    amps = np.array([5.0, 1.0, 0.1, 0.01, 0.002])
    w, _, _, a, box = _tones(n, ks, amps, np.array([0.3, 1.1, 2.0, -0.7, 0.4]))
    keep = w > 1.0
    out = integrate_acceleration(box if boxcar else a, DT, omega_low=1.0, boxcar=boxcar)
    _, x_in, v_in, a_in, _ = _tones(n, ks[keep], amps[keep], np.array([1.1, 2.0, -0.7, 0.4]))
    np.testing.assert_allclose(out.displacement, x_in, rtol=0, atol=1e-9 * np.abs(x_in).max())
    np.testing.assert_allclose(out.velocity, v_in, rtol=0, atol=1e-9 * np.abs(v_in).max())
    if not boxcar:
        np.testing.assert_allclose(out.acceleration, a_in, rtol=0, atol=1e-9 * np.abs(a).max())
    assert out.omega_low == 1.0 and out.boxcar is boxcar


def test_an_uncorrected_interval_average_is_short_by_sinc():
    n = 1024
    w, x, _, _, box = _tones(n, [256], np.array([1.0]), np.array([0.0]))  # half of Nyquist
    out = integrate_acceleration(box, DT, omega_low=1.0, boxcar=False)
    gain = math.sin(w[0] * DT / 2) / (w[0] * DT / 2)
    assert gain == pytest.approx(2 * math.sqrt(2) / math.pi)  # 0.900
    np.testing.assert_allclose(out.displacement, gain * x, rtol=0, atol=1e-10)


def test_segments_are_integrated_each_on_its_own():
    n1, n2 = 2048, 1024
    p1 = _tones(n1, [100, 5], np.array([1.0, 3.0]), np.array([0.2, 0.5]))
    p2 = _tones(n2, [60], np.array([2.0]), np.array([1.3]))
    a = np.concatenate([p1[4], p2[4]])
    out = integrate_acceleration(a, DT, bounds=[(0, n1), (n1, n1 + n2)], omega_low=1.0)
    x1 = _tones(n1, [100], np.array([1.0]), np.array([0.2]))[1]  # bin 5 is below the edge
    np.testing.assert_allclose(out.displacement, np.r_[x1, p2[1]], rtol=0, atol=1e-9)
    assert out.n_segments == 2


# ----------------------------------------------------------------- the oscillator
def test_a_simulated_oscillator_integrates_to_its_displacement(run):
    a, q, v = run
    out = integrate_acceleration(a, DT)
    cut = slice(round(2 * out.margin / DT), a.size - round(2 * out.margin / DT))
    for lo, hi in [(1.0, 20.0), (4.0, 6.0)]:
        ref_x, ref_v = _bandpass(q, lo, hi)[cut], _bandpass(v, lo, hi)[cut]
        err_x = np.std(_bandpass(out.displacement, lo, hi)[cut] - ref_x) / np.std(ref_x)
        err_v = np.std(_bandpass(out.velocity, lo, hi)[cut] - ref_v) / np.std(ref_v)
        # what the samples cannot give, two-sided spectra over [lo, hi] and [-hi, -lo]
        lost_x = 2 * S0 * DT**2 / 12 * (1 / lo - 1 / hi)
        lost_v = 2 * S0 * DT**2 / 4 * (hi - lo)
        assert err_x <= 2 * math.sqrt(lost_x / np.var(ref_x)), (lo, hi, err_x)
        assert err_v <= 2 * math.sqrt(lost_v / np.var(ref_v)), (lo, hi, err_v)
    # measured: 2.7 % (x) and 3.5 % (v) over [1, 20] rad/s, 0.8 % and 1.5 % over [4, 6]


def test_without_noise_the_band_reaches_the_lowest_bins(run):
    band = acceleration_band(run[0], DT)
    lowest = 2 * math.pi / (4096 * DT)  # M = 4096 for 20 000 samples
    assert band.omega[0] == pytest.approx(lowest)
    assert band.omega_floor == pytest.approx(lowest)
    assert band.omega_low < 8 * lowest  # 0.46 rad/s, the resonance at 5
    assert band.omega_peak == pytest.approx(5.0, abs=0.3)
    again = acceleration_band(run[0].copy(), DT)
    assert again.omega_low == band.omega_low and again.floor == band.floor


@pytest.mark.parametrize("sd", [0.3, 3.0])
def test_a_white_sensor_noise_sets_the_floor_and_the_edge(run, sd):
    a = run[0] + sd * np.random.default_rng(5).standard_normal(run[0].size)
    band = acceleration_band(a, DT)
    level = sd**2 * DT / (2 * math.pi)  # two-sided per rad/s
    # the floor is the least of the smoothed ordinates (64 averages, 12 % sd) on the noise
    assert 0.5 * level < band.floor < 1.1 * level
    ws = np.linspace(0.05, 4.0, 4000)  # where the noise equals the response:
    w_even = ws[np.argmax(_s_acc(ws) > level)]
    assert w_even < band.omega_low < 4.0


def test_a_higher_larger_mode_does_not_hide_the_lower_one(run):
    """Two modes, the higher one's peak the larger (a chain's floor that moves most in its
    second mode): the band starts below the lower mode, where its rise from the floor
    begins, not in the valley between the two (the first run above the floor)."""
    system = System.single("linear", {"a1": 2.0, "a2": 400.0, "S0": 4000.0})
    rec = simulate_chain(system, duration=400.0, dt=DT, rng=np.random.default_rng(7),
                         measured="acceleration")  # fmt: skip
    sd = 0.3
    low, high = _bandpass(run[0], 0.0, 8.0), _bandpass(rec.x, 14.0, 60.0)  # a valley between
    a = low + high + sd * np.random.default_rng(5).standard_normal(low.size)
    band = acceleration_band(a, DT)
    assert band.omega_peak == pytest.approx(20.0, abs=1.0)  # the higher mode's
    level = sd**2 * DT / (2 * math.pi)
    ws = np.linspace(0.05, 4.0, 4000)
    w_even = ws[np.argmax(_s_acc(ws) > level)]
    assert w_even < band.omega_low < 4.0  # as for the lower mode alone


@pytest.mark.parametrize("c", [0.01, 0.1, 1.0])
def test_a_drift_moves_the_edge_above_it(run, c):
    a = run[0]
    drift = c * np.cumsum(np.random.default_rng(6).standard_normal(a.size))  # a random walk
    out = integrate_acceleration(a + drift, DT)
    ws = np.linspace(0.05, 5.0, 5000)
    s_drift = c**2 * DT / (2 * math.pi) / (ws * DT) ** 2  # its spectrum, two-sided per rad/s
    crossing = ws[np.argmax(_s_acc(ws) > s_drift)]
    assert crossing < out.omega_low < 5.0  # above the drift, below the resonance
    clean = integrate_acceleration(a, DT, omega_low=out.omega_low)
    cut = slice(round(2 * out.margin / DT), a.size - round(2 * out.margin / DT))
    diff = out.displacement[cut] - clean.displacement[cut]
    # the drift's spectrum does not grow with frequency and is below the floor F in the
    # band: its displacement's variance there is at most 2 F / (3 omega_low^3)
    assert np.var(diff) < 2 * out.band.floor / (3 * out.omega_low**3)
    assert np.std(diff) / np.std(clean.displacement[cut]) < 0.1  # measured 2.0 %, 2.7 %, 6.6 %


def test_the_description(run):
    out = integrate_acceleration(run[0], DT)
    assert re.fullmatch(
        r"integrated above 0\.46 rad/s, where the acceleration spectrum has risen to 10 times "
        r"its floor \S+ \(reached at 0\.0767 rad/s\), up to the Nyquist frequency 157\.1 rad/s "
        r"\(whole; interval-average gain 1/sinc\(w dt/2\) corrected; the first and last 13\.7 s "
        r"of a segment carry the band edge's ringing\)",
        out.describe(),
    ), out.describe()
    assert BAND_RISE == 10.0


# -------------------------------------------------------------------------- errors
@pytest.mark.parametrize(
    ("a", "kwargs", "message"),
    [
        (np.ones(4096), {}, "the acceleration record is constant: there is nothing to integrate"),
        (np.cumsum(np.random.default_rng(1).standard_normal(4096)), {},
         "the acceleration spectrum is largest at its lowest frequencies (2.45 rad/s and "
         "below): drift, not a response"),
        (np.zeros(100), {},
         "acceleration record too short for its band: longest segment 100 samples"),
        (np.random.default_rng(2).standard_normal(4096), {"omega_low": 200.0},
         "omega_low must be between 0 and the Nyquist frequency 157.1 rad/s, got 200.0"),
    ],
)  # fmt: skip
def test_errors(a, kwargs, message):
    with pytest.raises(HosidInputError) as err:
        integrate_acceleration(a, DT, **kwargs)
    assert str(err.value) == message


def test_in_time_the_trapezoid_gain_is_corrected():
    """Interval averages of tones integrated in time (:func:`integrate_in_time`): the
    velocity at the half steps is exact and the displacement within the residual gain
    :math:`u^4/45` (:math:`u = \\omega\\Delta t/2`) of the exact one, in the record's middle;
    the uncorrected trapezoid sum is short by :math:`u^2/3` (0.16 % at 7 rad/s).
    """
    n = 20000
    ks = np.array([445, 1114])  # 7.0 and 17.5 rad/s
    amps, phases = np.array([1.0, 0.1]), np.array([0.4, -1.0])
    w, _, _, _, box = _tones(n, ks, amps, phases)
    x, v, _ = integrate_in_time(box, DT, omega_low=0.5)
    half = DT * np.arange(n) + DT / 2
    arg = np.outer(half, w) + phases
    x_true, v_true = np.cos(arg) @ amps, -np.sin(arg) @ (amps * w)
    mid = slice(5000, n - 5000)
    u = w * DT / 2
    tol = np.sum(amps * u**4 / 45) + 1e-6
    # measured 2.8e-6: the residual gain 2.6e-6 and the filter
    assert np.max(np.abs(x[mid] - x_true[mid])) < tol
    assert np.max(np.abs(v[mid] - v_true[mid])) < 1e-6 * np.abs(v_true).max()
    trapezoid = x + DT**2 / 12 * (np.cos(arg) @ (-amps * w**2))  # the gain uncorrected
    assert np.max(np.abs(trapezoid[mid] - x_true[mid])) > 0.5 * amps[0] * u[0] ** 2 / 3
