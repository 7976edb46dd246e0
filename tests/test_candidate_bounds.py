"""The information limit of every candidate effect: Girsanov bounds of the drift effects
(the NOTES.md floors) and Whittle's bound of the corner and the noise."""

import math

import numpy as np
import pytest

from hosid.model import PAPER_PARAMS
from hosid.model.information import candidate_bound, spectral_bound, whittle_information

LINEAR = {"a1": 1.0, "a2": 25.0, "S0": 10.0}


def test_whittle_reproduces_the_girsanov_bound_of_a_linear_oscillator():
    # for x'' + c x' + k x = f the sampled record's information on (c, k) is the full
    # state's (T / (2 pi S0)) diag(E v^2, E x^2): sd c = sqrt(2 c / T), sd k = sqrt(2 c k / T)
    # (measured: 0.03162278 and 0.1582727, 0.1 % above, the band ending at the Nyquist
    # frequency); the state reveals S0 exactly, the band only to 0.45 %, which costs c 1 %
    c, k, T = 1.0, 25.0, 2000.0
    info = whittle_information(c, k, 10.0, duration=T, dt=0.02, names=("c", "k"))
    sd = np.sqrt(np.diag(np.linalg.inv(info)))
    assert sd[0] == pytest.approx(math.sqrt(2 * c / T), rel=0.002)
    assert sd[1] == pytest.approx(math.sqrt(2 * c * k / T), rel=0.002)
    info = whittle_information(c, k, 10.0, duration=T, dt=0.02, names=("c", "k", "S0"))
    sd = np.sqrt(np.diag(np.linalg.inv(info)))
    assert sd[0] == pytest.approx(1.01 * math.sqrt(2 * c / T), rel=0.002)
    # and it scales as 1 / T exactly
    info2 = whittle_information(c, k, 10.0, duration=2 * T, dt=0.02, names=("c", "k", "S0"))
    assert info2.shape == (3, 3)
    np.testing.assert_allclose(info2, 2 * info, rtol=1e-12)


def test_spectral_bound_of_the_corner_and_the_noise():
    kw = {"duration": 2000.0, "dt": 0.02, "sim_duration": 2000.0}
    both = spectral_bound("linear", LINEAR, rng=np.random.default_rng(3), **kw)
    assert both.names == ("c", "k", "S0", "eta", "noise_var")
    eta = spectral_bound(
        "linear", LINEAR, rng=np.random.default_rng(3), effects=("coloured_excitation",), **kw
    )
    noise = spectral_bound(
        "linear", LINEAR, rng=np.random.default_rng(3), effects=("measurement_noise",), **kw
    )
    # the equivalent linear system of a linear oscillator is itself (2000 s: E v^2 to 3 %,
    # E x^2 to 4 %)
    assert eta.c == pytest.approx(1.0, rel=0.1) and eta.k == pytest.approx(25.0, rel=0.1)
    # a low-pass and a noise floor both act at the top of the band: freeing both widens
    # each one's bound
    assert both.sd["eta"] > 2 * eta.sd["eta"] and both.sd["noise_var"] > 2 * noise.sd["noise_var"]
    noisy = {**LINEAR, "noise_sd": 0.1}
    with pytest.raises(ValueError, match="null"):
        spectral_bound("linear,measurement_noise", noisy, rng=np.random.default_rng(0), **kw)


@pytest.mark.parametrize(
    ("effect", "notes"),
    [("coulomb_friction", 1.37), ("quadratic_stiffness", 0.27), ("excitation_mean", 0.56)],
)
def test_candidate_bound_reproduces_the_notes_floors(effect, notes):
    # NOTES.md, last section: S0 = 100, T = 2000 s, offset known; one 40 000 s simulation
    sd = candidate_bound(
        "paper", PAPER_PARAMS, effect, duration=2000.0, dt=0.02, rng=np.random.default_rng(1)
    )
    assert sd == pytest.approx(notes, rel=0.05)
