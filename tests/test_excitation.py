"""Band-limited and coloured excitation: input-power integrals, the excitation's shape and
restoration, the simulator and the default model of a band-limited record."""

import math

import numpy as np
import pytest
from scipy import integrate

from hosid.components.excitation import Excitation, input_power
from hosid.inference import estimate
from hosid.model import Model, simulate
from hosid.model.simulate import band_limited_force
from hosid.record import Record
from hosid.state import velocity_deficit

LINEAR = {"a1": 1.0, "a2": 25.0, "S0": 10.0}


def _quad(f, top, peak=5.0):
    """(2 / pi) int_0^top f, in two pieces around the resonance ``peak``."""
    cut = min(top, 20.0 * peak)
    head = integrate.quad(f, 0.0, cut, limit=500, points=[peak] if peak < cut else None)[0]
    tail = integrate.quad(f, cut, top, limit=500)[0] if top > cut else 0.0
    return 2.0 / math.pi * (head + tail)


# ------------------------------------------------------------------ input power
@pytest.mark.parametrize(("c", "k"), [(1.0, 25.0), (42.0, 1.9e5), (12.0, 25.0), (10.0, 25.0)])
@pytest.mark.parametrize("wc", [None, 7.0, 2000.0])
@pytest.mark.parametrize("wb", [None, 8.0, 1257.0])
def test_input_power_is_the_integral_of_the_linear_response(c, k, wc, wb):
    # rho = (1/pi) int Re[i w H] L, rho_x = (1/pi) int Re[H] L over |w| <= wb (quadrature)
    def L(w):
        return 1.0 if wc is None else wc**2 / (wc**2 + w**2)

    def fv(w):
        return c * w**2 / ((k - w**2) ** 2 + (c * w) ** 2) * L(w)

    def fx(w):
        return (k - w**2) / ((k - w**2) ** 2 + (c * w) ** 2) * L(w)

    rho, rho_x = input_power(c, k, corners=() if wc is None else (wc,), wb=wb)
    top = np.inf if wb is None else wb
    peak = math.sqrt(k)
    # quadrature is good to about 1e-7 here
    assert rho == pytest.approx(_quad(fv, top, peak), rel=1e-6, abs=1e-9)
    assert rho_x * k == pytest.approx(_quad(fx, top, peak) * k, rel=1e-6, abs=1e-9)
    if wc is not None and wb is None:  # the closed forms of the low-pass (Lyapunov)
        assert rho == pytest.approx(wc**2 / (wc**2 + c * wc + k), rel=1e-9)
        assert rho_x == pytest.approx(wc / (wc**2 + c * wc + k), rel=1e-9)
    if wc is None and wb is None:
        assert (rho, rho_x) == pytest.approx((1.0, 0.0), abs=1e-10)  # 2e-12 at critical


def test_input_power_broadcasts_and_the_band_limit_asymptotes():
    wb = np.array([1257.0, 2500.0, np.inf])
    rho, rho_x = input_power(42.0, 1.9e5, wb=wb)
    assert rho.shape == rho_x.shape == (3,)
    # far above resonance: 1 - 2c/(pi wb) and 2/(pi wb), to O(k / wb^2)
    np.testing.assert_allclose(rho[:2], 1 - 2 * 42.0 / (math.pi * wb[:2]), rtol=5e-3)
    np.testing.assert_allclose(rho_x[:2], 2 / (math.pi * wb[:2]), rtol=0.1)
    assert rho[2] == pytest.approx(1.0) and rho_x[2] == pytest.approx(0.0, abs=1e-12)


def test_excitation_shape_powers_and_restoration():
    model = Model.from_spec("paper,coloured_excitation,band_limited_excitation")
    assert model.param_names == ("a1", "n1", "a2", "n2", "S0", "wc", "wb", "rolloff")
    theta = np.array([[0.5, 0.5, 25.0, 5.0, 100.0, 20.0, 30.0, 0.0]] * 2)
    theta[1, 6:] = 200.0, 3.0
    exc = Excitation(model, theta[0], sigma_v=7.0, sigma_x=1.2)
    assert not exc.white
    omega = np.array([0.0, 10.0, 25.0, 40.0])
    L = exc.shape(omega, theta)
    np.testing.assert_allclose(L[0], [1.0, 0.8, 400 / 1025, 0.0])
    lp = 400 / (400 + omega**2)
    np.testing.assert_allclose(L[1], lp / (1 + 3.0 * omega**2 / 200.0**2))
    for th, Lt in zip(theta, L, strict=True):  # 1/L as a polynomial in w^2, in the band
        inv = sum(b * a(th) for b, a in exc.inverse_shape(omega[:3]))
        np.testing.assert_allclose(inv, 1 / Lt[:3], rtol=1e-12)
        for i, d in exc.shape_derivatives(omega[:3], th):  # d log L by differences
            up, h = th.copy(), 1e-7 * max(abs(th[i]), 1.0)
            up[i] += h
            num = (np.log(exc.shape(omega[:3], up)) - np.log(Lt[:3])) / h
            np.testing.assert_allclose(d, num, rtol=1e-5, atol=1e-9)
    rho, _ = exc.powers(theta, dt=0.02)
    c, k = exc.linear
    corners = (np.full(2, 20.0), theta[:, 6] / np.sqrt(np.maximum(theta[:, 7], 1e-6)))
    wN = math.pi / 0.02
    # edge 30 below the Nyquist frequency: the shape as it is; edge 200 above it: the shape
    # up to wN, then white at L(wN) up to the edge (the force as the sampled record sees it)
    inside = input_power(c, k, corners=corners, wb=np.minimum(theta[:, 6], wN))[0]
    top = exc.lowpass(np.asarray(wN), theta)
    white_above = input_power(c, k, wb=theta[:, 6])[0] - input_power(c, k, wb=wN)[0]
    np.testing.assert_allclose(rho, inside + np.where(theta[:, 6] > wN, top * white_above, 0.0))
    # a flat band is the limit of a vanishing roll-off (computed at ROLLOFF_FLOOR = 1e-6)
    flat = input_power(c, k, corners=(20.0,), wb=30.0)[0]
    assert rho[0] == pytest.approx(flat, rel=1e-6)  # the floor 1e-6 of the roll-off
    # an edge below the Nyquist frequency leaves nothing to restore above it
    assert exc.deficit(theta[0], dt=0.02) == 0.0
    assert velocity_deficit(100.0, 0.02, lambda w: (np.abs(w) <= 30.0) * 1.0) == 0.0
    white = Excitation(Model.from_spec("paper"), theta[0, :5], 7.0, 1.2)
    assert white.white and white.powers(theta[:, :5], 0.02)[0].tolist() == [1.0, 1.0]


def test_a_corner_above_the_band_moves_what_the_identities_see_by_its_square():
    """A corner far above the Nyquist frequency changes the sampled record by
    O(1/wc^2): so do the input power and the restoration the identities use (the
    continuous input power moves by -c/wc, the order the record cannot see).
    """
    model = Model.from_spec("paper,coloured_excitation")
    dt, wN = 0.02, math.pi / 0.02
    th = np.array([[0.5, 0.5, 25.0, 5.0, 100.0, wc] for wc in (4 * wN, 8 * wN)])
    exc = Excitation(model, th[0], sigma_v=7.0, sigma_x=1.2)
    rho, _ = exc.powers(th, dt)
    assert (1 - rho[1]) / (1 - rho[0]) == pytest.approx(0.25, rel=0.05)
    continuous = input_power(*exc.linear, corners=(th[:, 5],))[0]
    assert (1 - continuous[1]) / (1 - continuous[0]) == pytest.approx(0.5, rel=0.05)
    # above the band the force is white at L(wN) (against the same numeric alias sum:
    # truncated at 60 aliases it is 1 % below the closed form pi^2 S0 / 6 wN)
    white = velocity_deficit(100.0, dt, np.ones_like)
    for t in th:
        top = 1.0 / (1.0 + (wN / t[5]) ** 2)
        assert exc.deficit(t, dt) == pytest.approx(top * white, rel=1e-3)


# ------------------------------------------------------------------ simulator
def test_band_limited_force_has_the_flat_band_spectrum():
    h, S0, wb = 0.01, 3.0, 60.0
    f = band_limited_force(2**18, h, S0, wb, 0.0, np.random.default_rng(1))
    F = np.fft.rfft(f)
    w = 2 * math.pi * np.fft.rfftfreq(f.size, h)
    P = np.abs(F) ** 2 * h / (2 * math.pi * f.size)
    inside = P[(w > 1) & (w < 0.95 * wb)]
    # 2^18 samples: ~7800 periodogram ordinates in the band, each exponential: the mean
    # has 1.1 % sd; 5 % is 4 sd
    assert inside.mean() == pytest.approx(S0, rel=0.05)
    assert P[w > 1.01 * wb].max() < 1e-20 * S0
    assert np.var(f) == pytest.approx(2 * S0 * wb, rel=0.05)  # int of S0 over |w| <= wb


def test_band_limited_linear_oscillator_balances_the_band_power():
    # E[v^2] = pi S0 rho / a1 (energy balance with the band's input power), E[x^2] = int
    # S0 |H|^2 over the band; a 4000 s record: ~2.5 % sampling sd, measured +1.2 %, -0.6 %
    wb = 8.0
    rec, v = simulate({**LINEAR, "wb": wb}, duration=4000.0, rng=np.random.default_rng(3),
                      return_velocity=True)  # fmt: skip
    a1, a2, S0 = LINEAR["a1"], LINEAR["a2"], LINEAR["S0"]
    rho, _ = input_power(a1, a2, wb=wb)
    x2 = S0 * math.pi * _quad(lambda w: 1 / ((a2 - w**2) ** 2 + (a1 * w) ** 2), wb)
    assert np.mean(v**2) == pytest.approx(math.pi * S0 * rho / a1, rel=0.08)
    assert np.mean(rec.x**2) == pytest.approx(x2, rel=0.08)
    assert rho < 0.97  # the band removes 3 % or more of the input power


# ------------------------------------------------------------------ default model
@pytest.fixture(scope="module")
def band_record():
    """Paper oscillator driven up to 25 rad/s (w_N = 157), 1000 s in 4 segments."""
    rec = simulate({"a1": 0.5, "n1": 0.5, "a2": 25.0, "n2": 5.0, "S0": 100.0, "wb": 25.0},
                   duration=1000.0, rng=np.random.default_rng(11))  # fmt: skip
    return Record(rec.x, rec.dt, segments=(0, 12_000, 25_000, 37_500))


def test_estimate_adds_the_band_limited_excitation(band_record):
    est = estimate(band_record, "paper")
    assert est.model.names[-1] == "band_limited_excitation"
    assert est.model.param_names[-2:] == ("wb", "rolloff")
    assert any("band_limited_excitation added" in n for n in est.notes)
    assert est.state.layout.B >= 24 and est.state.layout.starts is not None
    v, sd = est.values, est.sd
    # one 1000 s record: within 3 sd of the truth, measured a2 -0.4 sd, n2 +0.3 sd,
    # a1eq -0.2 sd, S0 -0.9 sd
    truth = {"a2": 25.0, "n2": 5.0, "S0": 100.0}
    for p, t in truth.items():
        assert abs(v[p] - t) < 3 * sd[p], p
    assert est.state.scales.band_edge[0] <= v["wb"] <= est.state.scales.band_edge[1]
    assert v["rolloff"] < 3 * sd["rolloff"]  # a flat band
    plain = estimate(band_record, "paper", settle=False)
    assert plain.model.names == Model.from_spec("paper").names
