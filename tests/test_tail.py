"""The spectral-tail component against Gaussian records of exactly known spectrum.

Oracle: records synthesized in the frequency domain with the sampled spectrum of the
linear oscillator (aliased, 200 folds), a low-pass force and a noise floor; the score's
z at the truth must be N(0, 1) and its mean under an effect equal to the effect over
the Whittle standard deviation of the band with a free level (computed here by
quadrature, independently of the component).
"""

import functools
import math

import numpy as np
import pytest
from scipy import optimize

from hosid.components.tail import LOW, Tail
from hosid.model.model import Model
from hosid.record import Record
from hosid.state import RecordState

C, K, S0, DT, T = 6.32, 25.0, 100.0, 0.02, 2000.0
N = round(T / DT)
WN = math.pi / DT


@functools.cache
def _rfft_spectrum(eta=0.0, noise_var=0.0):
    w = 2.0 * math.pi * np.fft.rfftfreq(N, DT)
    return spectrum(np.maximum(w, 1e-9), eta, noise_var)


def spectrum(w, eta=0.0, noise_var=0.0, n_alias=200):
    W = w[None, :] + 2.0 * WN * np.arange(-n_alias, n_alias + 1)[:, None]
    S = (S0 / (1.0 + eta * W**2) / ((K - W**2) ** 2 + (C * W) ** 2)).sum(axis=0)
    return S + noise_var * DT / (2.0 * math.pi)


def synthesize(rng, eta=0.0, noise_var=0.0):
    """A stationary Gaussian record of two-sided spectrum ``spectrum`` (periodic)."""
    S = _rfft_spectrum(eta, noise_var)
    var = N * 2.0 * math.pi * S / DT  # E|X_k|^2
    X = np.sqrt(var / 2.0) * (rng.standard_normal(S.size) + 1j * rng.standard_normal(S.size))
    X[0] = 0.0
    X[-1] = np.sqrt(var[-1]) * rng.standard_normal()
    return Record(np.fft.irfft(X, N), DT)


def band_sd(which, lo, hi, B, M):
    """Whittle sd of eta or of the noise variance from B blocks' bins in [lo, hi), the
    level free: the second difference's flat spectrum makes the bins independent.
    """
    w = 2.0 * math.pi * np.fft.rfftfreq(M - 2, DT)
    w = w[(w >= lo) & (w < hi)]
    W = w[None, :] + 2.0 * WN * np.arange(-200, 201)[:, None]
    resp = (S0 / ((K - W**2) ** 2 + (C * W) ** 2)).sum(axis=0)
    d = {"eta": -(S0 * W**2 / ((K - W**2) ** 2 + (C * W) ** 2)).sum(axis=0),
         "noise": np.full_like(w, DT / (2.0 * math.pi))}  # fmt: skip
    X = np.stack([resp / resp, d[which] / resp])
    info = B * X @ X.T
    return 1.0 / math.sqrt(info[1, 1] - info[0, 1] ** 2 / info[0, 0])


def score_z(record, model, theta):
    state = RecordState.from_record(record)
    m = Tail().prepare(state, model, theta)
    sd = m.influence.std(axis=0, ddof=1) / math.sqrt(m.influence.shape[0])
    return m.mean(theta) / sd, state


@pytest.fixture(scope="module")
def white_records():
    rng = np.random.default_rng(2024)
    return [synthesize(rng) for _ in range(120)]


def _theta(model, **kw):
    return model.vector({"a1": C, "a2": K, "S0": S0, **kw})


def test_score_is_standard_normal_at_the_truth(white_records):
    """120 records: mean within 3 se (0.27), sd within 0.15 of 1."""
    for effect, kw in (("coloured_excitation", {"wc": 1e7}), ("measurement_noise",
                                                             {"noise_sd": 0.0})):  # fmt: skip
        model = Model.from_spec(f"linear,{effect}")
        z = np.array([score_z(r, model, _theta(model, **kw))[0][0] for r in white_records])
        assert abs(z.mean()) < 3.0 / math.sqrt(z.size)
        assert z.std(ddof=1) == pytest.approx(1.0, abs=0.15)


@pytest.mark.parametrize(
    ("effect", "which", "param"),
    [("coloured_excitation", "eta", "wc"), ("measurement_noise", "noise", "noise_sd")],
)
def test_estimate_reaches_the_whittle_bound_of_its_band(effect, which, param):
    """50 records with the effect at 4 band-sd: the root of the equation (weights frozen
    at the null) is unbiased within 3 se (0.42 band-sd) and its sd is the band's Whittle
    sd within 25 % (the sd of an sd from 50 records is 10 %).  The score at the null is
    linear in the effect only near it (the aliases far above w_N saturate), so the test
    is on the estimate, which follows the mean function.
    """
    rng = np.random.default_rng(7)
    model = Model.from_spec(f"linear,{effect}")
    state = RecordState.from_record(synthesize(rng))
    L = state.layout
    sd = band_sd(which, LOW * state.scales.omega_n, WN, L.B, L.M)
    value = 4.0 * sd
    kw = {"eta": value} if which == "eta" else {"noise_var": value}
    null = _theta(model, **{param: 1e7 if param == "wc" else 0.0})

    def at(u):  # the model's parameter at the effect's coordinate u
        th = null.copy()
        th[model.index(param)] = max(u, 1e-30) ** -0.5 if param == "wc" else math.sqrt(u)
        return th

    est = []
    for _ in range(50):
        m = Tail().prepare(RecordState.from_record(synthesize(rng, **kw)), model, null)
        est.append(optimize.brentq(lambda u, m=m: m.mean(at(u))[0], 1e-6 * sd, 40.0 * sd))
    est = np.array(est) / sd
    assert est.mean() == pytest.approx(4.0, abs=3.0 / math.sqrt(est.size))
    assert est.std(ddof=1) == pytest.approx(1.0, rel=0.25)


def test_tail_component_layout(white_records):
    model = Model.from_spec("paper,coloured_excitation,measurement_noise")
    theta = model.vector({"a1": C, "n1": 0.0, "a2": K, "n2": 0.0, "S0": S0, "wc": 500.0,
                          "noise_sd": 0.001})  # fmt: skip
    state = RecordState.from_record(white_records[0])
    m = Tail().prepare(state, model, theta)
    assert m.labels == ("tail eta", "tail noise")
    assert m.influence.shape == (state.layout.B, 2)
    assert m.mean(np.stack([theta, theta, theta])).shape == (3, 2)
    lo, hi = m.info["tail_rad_s"]
    assert lo >= LOW * state.scales.omega_n and hi < WN
    with pytest.raises(ValueError, match="needs wc or noise_sd"):
        Tail().prepare(state, Model.from_spec("paper"), theta[:5])
