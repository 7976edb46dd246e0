"""The simulator of ``analyses/silverbox_coverage.py`` against exact oracles (no data file
needed): the periodic steady state of the linear circuit is its frequency response times
the input's DFT, and the multisines are odd and seeded.
"""

import importlib
import sys
from pathlib import Path

import numpy as np
import pytest

ANALYSES = Path(__file__).resolve().parents[1] / "analyses"
DT = 1.0 / 610.3515625
CIRCUIT = {"c": 42.0, "k1": 1.854e5, "k2": 0.0, "k3": 0.0, "g": 1.86e5, "b": 0.0}


@pytest.fixture(scope="module")
def cov():
    sys.path.insert(0, str(ANALYSES))
    try:
        yield importlib.import_module("silverbox_coverage")
    finally:
        sys.path.remove(str(ANALYSES))
        for name in ("silverbox_coverage", "silverbox"):
            sys.modules.pop(name, None)


def test_multisine_is_odd_seeded_and_on_its_lines(cov):
    n, lines = 512, np.arange(1, 161, 2)
    amp = np.linspace(1.0, 0.5, lines.size)
    u = cov.multisine(np.random.default_rng(4), lines, amp, n, 3)
    assert u.shape == (3, n)
    np.testing.assert_allclose(u[:, n // 2 :], -u[:, : n // 2], atol=1e-12)  # u(t + P/2) = -u(t)
    np.testing.assert_array_equal(u, cov.multisine(np.random.default_rng(4), lines, amp, n, 3))
    U = np.fft.rfft(u, axis=1)
    np.testing.assert_allclose(np.abs(U[:, lines]), np.broadcast_to(amp, (3, lines.size)),
                               rtol=1e-10)  # fmt: skip
    off = np.setdiff1d(np.arange(U.shape[1]), lines)
    assert np.max(np.abs(U[:, off])) < 1e-10


def test_linear_steady_state_is_the_frequency_response(cov):
    """y = g u / (k1 - w^2 + i c w) line by line: RK4 at dt / 4 is within 5e-4 of it on
    every line (measured 1.7e-4; 1.0e-5 at dt / 8: the fourth order).
    """
    n = 1024
    lines = np.arange(1, 336, 2)  # up to 200 Hz, as the Silverbox's multisines
    u = cov.multisine(np.random.default_rng(7), lines, np.ones(lines.size), n, 2)
    y = cov.simulate(u, DT, CIRCUIT)
    w = 2 * np.pi * np.fft.rfftfreq(n, DT)
    p = CIRCUIT
    exact = p["g"] * np.fft.rfft(u, axis=1) / (p["k1"] - w**2 + 1j * p["c"] * w)
    Y = np.fft.rfft(y, axis=1)
    err = np.abs(Y[:, lines] - exact[:, lines]) / np.abs(exact[:, lines])
    assert np.max(err) < 5e-4
    off = np.setdiff1d(np.arange(w.size), lines)  # nothing where nothing is excited
    assert np.max(np.abs(Y[:, off])) < 1e-6 * np.max(np.abs(exact))


def test_cubic_stiffness_hardens_the_response(cov):
    """The nonlinear circuit: k3 > 0 raises the resonance (the response's spectral centroid
    moves up) and an offset force b shifts the mean by b over the mean's stiffness
    k1 + 3 k3 E[y^2] (to first order in b).
    """
    n = 1024
    lines = np.arange(1, 336, 2)
    u = 0.35 * cov.multisine(np.random.default_rng(8), lines, np.ones(lines.size), n, 2)
    lin = cov.simulate(u, DT, CIRCUIT)
    hard = cov.simulate(u, DT, {**CIRCUIT, "k3": 3e7, "b": 50.0})
    w = 2 * np.pi * np.fft.rfftfreq(n, DT)[1:]

    def centroid(y):
        P = np.abs(np.fft.rfft(y - y.mean(axis=1, keepdims=True), axis=1)[:, 1:]) ** 2
        return np.sum(P * w) / np.sum(P)

    assert centroid(hard) > 1.01 * centroid(lin)
    assert abs(lin.mean()) < 1e-9
    k_mean = CIRCUIT["k1"] + 3 * 3e7 * hard.var()
    assert hard.mean() == pytest.approx(50.0 / k_mean, rel=0.02)
