"""The model-terms library: names, layout, simulator mapping, features, priors."""

import doctest

import numpy as np
import pytest

import hosid.terms
from hosid.costs import PARAM_NAMES
from hosid.errors import HosidInputError
from hosid.priors import Prior
from hosid.records import Record
from hosid.simulate import PAPER_PARAMS, simulate
from hosid.spectra import features as spectra_features
from hosid.terms import (
    CANDIDATES,
    TERMS,
    Model,
    RecordScales,
    drift_from_params,
    get_term,
)

#: NOTES.md, "Candidate effects (shared vocabulary)", spelled exactly so.
NOTES_CANDIDATES = (
    "quadratic_damping",
    "cubic_stiffness",
    "quadratic_stiffness",
    "coulomb_friction",
    "coloured_excitation",
    "excitation_mean",
    "measurement_noise",
)

#: Every parameter of every term, at a value inside the default priors.
ALL_VALUES = {
    "a1": 0.5,
    "n1": 0.5,
    "a2": 25.0,
    "n2": 5.0,
    "b2": 2.0,
    "mu": 3.0,
    "S0": 100.0,
    "wc": 20.0,
    "m": 5.0,
    "noise_sd": 0.01,
}


def _welch(y, dt, M=1024):
    """Two-sided Hann-block PSD and its frequencies (rad/s)."""
    N = y.size // M
    win = 0.5 * (1 - np.cos(2 * np.pi * np.arange(M) / M))
    Y = np.fft.rfft(y[: N * M].reshape(N, M) * win, axis=1) * dt
    P = np.mean(np.abs(Y) ** 2, axis=0) / (2 * np.pi * M * dt * 0.375)
    return 2 * np.pi * np.fft.rfftfreq(M, dt), P


def test_candidates_are_spelled_as_in_notes():
    assert CANDIDATES == NOTES_CANDIDATES
    assert set(CANDIDATES) <= set(TERMS)


def test_term_kinds_and_parameters():
    kinds = {name: t.kind for name, t in TERMS.items()}
    assert kinds["coloured_excitation"] == kinds["excitation_mean"] == "excitation"
    assert kinds["excitation_level"] == "excitation"
    assert kinds["measurement_noise"] == "observation"
    drift = {n for n, k in kinds.items() if k == "drift"}
    assert drift == {
        "linear_damping",
        "quadratic_damping",
        "linear_stiffness",
        "cubic_stiffness",
        "quadratic_stiffness",
        "coulomb_friction",
    }
    params = [p for t in TERMS.values() for p in t.params]
    assert sorted(params) == sorted(ALL_VALUES)
    for t in TERMS.values():
        assert t.latex and t.__doc__ and ".. math::" in type(t).__doc__


def test_drift_features_match_their_formulas():
    x = np.array([-2.0, -0.5, 0.0, 0.5, 2.0])
    v = np.array([1.5, -3.0, 0.0, 2.0, -0.25])
    expected = {
        "linear_damping": v,
        "quadratic_damping": v * np.abs(v),
        "linear_stiffness": x,
        "cubic_stiffness": x**3,
        "quadratic_stiffness": x**2,
        "coulomb_friction": np.sign(v),
    }
    for name, phi in expected.items():
        np.testing.assert_array_equal(get_term(name).feature(x, v), phi)


@pytest.mark.parametrize("name", ["excitation_level", *CANDIDATES[4:]])
def test_non_drift_terms_have_no_feature(name):
    with pytest.raises(TypeError, match="no drift feature"):
        get_term(name).feature(np.zeros(3), np.zeros(3))


def test_linear_and_paper_specs():
    lin = Model.from_spec("linear")
    assert lin.names == ("linear_damping", "linear_stiffness", "excitation_level")
    assert lin.param_names == ("a1", "a2", "S0")
    paper = Model.from_spec("paper")
    assert paper.param_names == PARAM_NAMES  # the costs' layout (eq 45)
    assert paper.drift_params == ("a1", "n1", "a2", "n2")
    assert paper.candidates == tuple(c for c in CANDIDATES if c not in paper.names)


def test_spec_lists_strings_aliases_and_canonical_order():
    a = Model.from_spec("measurement_noise, linear_stiffness,linear_damping")
    b = Model.from_spec(["linear_damping", "linear_stiffness", "measurement_noise"])
    assert a == b
    assert a.param_names == ("a1", "a2", "S0", "noise_sd")
    c = Model.from_spec("paper,quadratic_stiffness,paper")  # aliases expand, duplicates drop
    assert c.param_names == ("a1", "n1", "a2", "n2", "b2", "S0")
    assert Model.from_spec("excitation_mean,linear") == Model.from_spec("linear").with_term(
        "excitation_mean"
    )


@pytest.mark.parametrize("spec", ["quadratic_dampnig", "linear,friction", ["paper", "cubic"]])
def test_unknown_term_is_a_one_line_error_listing_valid_names(spec):
    with pytest.raises(HosidInputError) as info:
        Model.from_spec(spec)
    message = str(info.value)
    assert "\n" not in message and "unknown model term" in message
    for name in ("linear", "paper", *CANDIDATES):
        assert name in message


@pytest.mark.parametrize("spec", ["", " , ", []])
def test_empty_spec_is_an_error(spec):
    with pytest.raises(HosidInputError, match="empty model spec"):
        Model.from_spec(spec)


def test_with_term_returns_a_new_model_and_rejects_duplicates():
    lin = Model.from_spec("linear")
    bigger = lin.with_term("coulomb_friction")
    assert "coulomb_friction" in bigger.names and "coulomb_friction" not in lin.names
    assert bigger.param_names == ("a1", "a2", "mu", "S0")
    with pytest.raises(HosidInputError, match="already has linear_damping"):
        lin.with_term("linear_damping")
    with pytest.raises(HosidInputError, match="valid terms: linear_damping"):
        lin.with_term("stiction")


def test_params_from_mapping_and_vector_and_their_errors():
    paper = Model.from_spec("paper")
    assert paper.params(PAPER_PARAMS) == PAPER_PARAMS
    assert paper.params([0.5, 0.5, 25, 5, 100]) == PAPER_PARAMS
    with pytest.raises(HosidInputError, match=r"missing \['S0'\]"):
        paper.params({k: v for k, v in PAPER_PARAMS.items() if k != "S0"})
    with pytest.raises(HosidInputError, match=r"unknown \['b2'\]"):
        paper.params({**PAPER_PARAMS, "b2": 1.0})
    with pytest.raises(HosidInputError, match="expected \\(5,\\)"):
        paper.params([1.0, 2.0])


def test_model_simulation_is_the_simulator_with_the_mapped_parameters():
    model = Model(tuple(TERMS.values()))
    assert set(model.simulator_params(ALL_VALUES)) == set(ALL_VALUES)
    kw = {"duration": 30.0, "dt": 0.02}
    a = model.simulate(ALL_VALUES, rng=np.random.default_rng(3), **kw)
    b = simulate(ALL_VALUES, rng=np.random.default_rng(3), **kw)
    np.testing.assert_array_equal(a.x, b.x)


def test_paper_features_are_the_spectral_features_of_eq45(paper_record):
    F = Model.from_spec("paper").features(paper_record)
    np.testing.assert_array_equal(F, spectra_features(paper_record))


def test_drift_and_inferred_force_agree_with_the_features(paper_record):
    model = Model.from_spec("paper").with_term("quadratic_stiffness").with_term("excitation_mean")
    theta = {**PAPER_PARAMS, "b2": 1.5, "m": 2.0}
    F = model.features(paper_record)
    x = paper_record.x
    v = F[1]
    expected = 0.5 * v + 0.5 * v * np.abs(v) + 25 * x + 5 * x**3 + 1.5 * x**2
    np.testing.assert_allclose(model.drift(theta)(x, v), expected, rtol=1e-12)
    np.testing.assert_allclose(drift_from_params(theta)(x, v), expected, rtol=1e-12)
    f = model.inferred_force(paper_record, theta)
    lam = np.array([1.0, 0.5, 0.5, 25.0, 5.0, 1.5])
    np.testing.assert_allclose(f, lam @ F, rtol=1e-12, atol=1e-9)
    # vectorized over parameter sets: shape (2, 3, p) -> (2, 3, n)
    vec = np.array([model.params(theta)[p] for p in model.param_names])
    many = model.inferred_force(paper_record, np.broadcast_to(vec, (2, 3, vec.size)))
    assert many.shape == (2, 3, paper_record.n)
    np.testing.assert_allclose(many[1, 2], f, rtol=1e-12, atol=1e-9)


def test_drift_from_params_rejects_unknown_keys():
    with pytest.raises(HosidInputError, match="unknown parameter"):
        drift_from_params({"a1": 1.0, "k3": 2.0})


def test_inferred_force_of_a_linear_record_is_white_at_level_S0(linear_record, linear_params):
    # Oracle: with the true drift, f = x'' + a1 x' + a2 x is the simulated white force,
    # two-sided level S0 = 10.  195 blocks x ~26 bins per band: sd of a band mean ~1.5 %;
    # the spectral derivative loses nothing below 0.5 w_N.  Measured: within 2 %.
    model = Model.from_spec("linear")
    f = model.inferred_force(linear_record, {k: linear_params[k] for k in ("a1", "a2", "S0")})
    w, P = _welch(f, linear_record.dt)
    for lo, hi in [(1.0, 10.0), (10.0, 20.0), (20.0, 40.0), (40.0, 75.0)]:
        band = (w >= lo) & (w < hi)
        assert np.mean(P[band]) == pytest.approx(10.0, rel=0.06)


def test_coloured_excitation_shapes_the_inferred_force():
    # Oracle: the force is white noise through g' = wc (w - g), S_g = S0 wc^2 / (wc^2 + w^2).
    model = Model.from_spec("linear").with_term("coloured_excitation")
    theta = {"a1": 1.0, "a2": 25.0, "S0": 10.0, "wc": 8.0}
    rec = model.simulate(theta, duration=1000.0, dt=0.02, rng=np.random.default_rng(8))
    w, P = _welch(model.inferred_force(rec, theta), rec.dt)
    for lo, hi in [(1.0, 4.0), (6.0, 10.0), (14.0, 20.0), (30.0, 40.0)]:
        band = (w >= lo) & (w < hi)
        expected = np.mean(10.0 * 64.0 / (64.0 + w[band] ** 2))
        # 48 blocks x >= 10 bins: sd ~5 %; measured within 4 %
        assert np.mean(P[band]) == pytest.approx(expected, rel=0.12)


def test_record_scales_of_the_paper_oscillator(paper_record):
    s = RecordScales.from_record(paper_record)
    assert s.dt == 0.02 and s.omega_nyquist == pytest.approx(np.pi / 0.02)
    assert s.omega_n == pytest.approx(s.sigma_v / s.sigma_x)
    assert 5.0 < s.omega_n < 7.5  # linear-equivalent stiffness a2 + 3 n2 sigma_x^2 ~ 40
    # the acceleration plateau is a rough level: measured 1.10 S0 on this record
    assert 0.7 * 100.0 < s.S0 < 1.5 * 100.0


def test_default_priors_hold_the_paper_values_and_the_null_effects(paper_record):
    model = Model(tuple(TERMS.values()))
    priors = model.default_priors(paper_record)
    assert tuple(priors) == model.param_names
    assert all(isinstance(p, Prior) for p in priors.values())
    truth = {**PAPER_PARAMS, "b2": 0.0, "mu": 0.0, "m": 0.0, "noise_sd": 0.0, "wc": 3.0}
    for name, value in truth.items():
        assert np.isfinite(priors[name].ln_prob(value)), name
    rng = np.random.default_rng(0)
    for name, prior in priors.items():
        draws = prior.sample(rng, 200)
        assert np.all(np.isfinite(prior.ln_prob(draws))), name
    assert priors["mu"].lower == 0.0 and priors["noise_sd"].lower == 0.0  # physical signs


def test_record_scales_reject_a_constant_record():
    with pytest.raises(HosidInputError, match="constant"):
        RecordScales.from_record(Record(np.ones(5000), 0.02))
    with pytest.raises(HosidInputError, match="sigma_x"):
        RecordScales(sigma_x=0.0, sigma_v=1.0, S0=1.0, dt=0.02)


def test_model_latex_and_repr():
    model = Model.from_spec("linear").with_term("excitation_mean")
    assert model.latex() == r"\ddot x + a_1\,\dot x + a_2\,x = g(t) + m"
    assert repr(model) == (
        "Model(linear_damping + linear_stiffness + excitation_level + excitation_mean)"
    )


def test_docstring_examples_run():
    assert doctest.testmod(hosid.terms, raise_on_error=True).attempted >= 2
