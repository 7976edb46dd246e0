"""The model: terms (features, derivatives, priors), parameter layout, priors, eq (65)."""

import doctest
import math

import numpy as np
import pytest
from scipy import integrate

import hosid.model.model
from hosid.errors import HosidInputError
from hosid.model import (
    ALIASES,
    CANDIDATES,
    PAPER_PARAMS,
    TERMS,
    DriftTerm,
    LogNormal,
    LogUniform,
    Model,
    Normal,
    Prior,
    PriorSet,
    Scales,
    Uniform,
    get_term,
    simulate,
)

#: NOTES.md, "Candidate effects (shared vocabulary)", spelled exactly so; issue 29
#: adds the narrow-band and the impulsive excitation (its interface names them so).
#: terms that combine with no other excitation shape (the band-pass: a system's only)
WHITENING_OR_IMPULSES = ("narrowband_excitation", "impulsive_excitation", "bandpass_excitation")

NOTES_CANDIDATES = (
    "quadratic_damping",
    "cubic_stiffness",
    "quadratic_stiffness",
    "coulomb_friction",
    "coloured_excitation",
    "narrowband_excitation",
    "impulsive_excitation",
    "excitation_mean",
    "measurement_noise",
)

#: Scales of the paper oscillator at S0 = 100 (measured on a 2000 s record).
PAPER_SCALES = Scales(sigma_x=1.14, sigma_v=7.2, S0=105.0, dt=0.02)

DRIFT = [n for n, t in TERMS.items() if isinstance(t, DriftTerm)]


# ------------------------------------------------------------------ terms
def test_candidates_are_spelled_as_in_notes():
    assert CANDIDATES == NOTES_CANDIDATES
    assert set(CANDIDATES) <= set(TERMS)


def test_term_kinds_and_parameters():
    kinds = {name: t.kind for name, t in TERMS.items()}
    assert kinds["excitation_level"] == kinds["coloured_excitation"] == "excitation"
    assert kinds["band_limited_excitation"] == kinds["narrowband_excitation"] == "excitation"
    assert kinds["impulsive_excitation"] == "excitation"
    assert kinds["measurement_noise"] == "observation"
    assert set(DRIFT) == {
        "linear_damping",
        "quadratic_damping",
        "linear_stiffness",
        "cubic_stiffness",
        "quadratic_stiffness",
        "coulomb_friction",
        "excitation_mean",
    }
    params = [p for t in TERMS.values() for p in t.params]
    # the low-pass and the band-pass filter share wf and zf
    assert params == [
        "a1", "n1", "a2", "n2", "b2", "mu", "m", "S0", "wc", "wb", "rolloff", "wf", "zf", "wf",
        "zf", "rate", "noise_sd",
    ]  # fmt: skip
    for t in TERMS.values():
        assert t.latex and type(t).__doc__


def test_features_match_their_formulas():
    u = np.array([-2.0, -0.5, 0.0, 0.5, 2.0])
    expected = {
        "linear_damping": u,
        "quadratic_damping": u * np.abs(u),
        "linear_stiffness": u,
        "cubic_stiffness": u**3,
        "quadratic_stiffness": u**2,
        "coulomb_friction": np.sign(u),
        "excitation_mean": -np.ones(5),  # x'' + ... = g + m
    }
    for name, phi in expected.items():
        np.testing.assert_array_equal(get_term(name).phi(u), phi, err_msg=name)
    variables = {n: TERMS[n].variable for n in DRIFT}
    assert variables == {
        "linear_damping": "v",
        "quadratic_damping": "v",
        "coulomb_friction": "v",
        "linear_stiffness": "x",
        "cubic_stiffness": "x",
        "quadratic_stiffness": "x",
        "excitation_mean": "1",
    }


def _fd(f, u, h=1e-5):
    return (f(u + h) - f(u - h)) / (2 * h)


@pytest.mark.parametrize(
    "name", ["linear_stiffness", "cubic_stiffness", "quadratic_stiffness", "linear_damping"]
)
def test_smooth_feature_derivatives_against_finite_differences(name):
    t = get_term(name)
    u = np.linspace(-3.0, 3.0, 61)
    for order in range(4):
        fd = _fd(lambda w, o=order: t.phi(w, o), u)
        # central differences of polynomials of degree <= 3 at h = 1e-5: error h^2 phi'''
        # ~ 1e-9, round-off ~ 1e-16 * 27 / 1e-5 ~ 3e-10
        np.testing.assert_allclose(t.phi(u, order + 1), fd, atol=1e-7, err_msg=f"{order}")
    # exact values
    p = {"linear_stiffness": 1, "quadratic_stiffness": 2, "cubic_stiffness": 3}.get(name, 1)
    np.testing.assert_array_equal(t.phi(u, p), math.factorial(p) * np.ones_like(u))
    np.testing.assert_array_equal(t.phi(u, p + 1), np.zeros_like(u))


def test_quadratic_damping_derivatives_against_finite_differences():
    t = get_term("quadratic_damping")
    u = np.concatenate([np.linspace(-4, -0.1, 40), np.linspace(0.1, 4, 40)])  # away from 0
    np.testing.assert_allclose(t.phi(u, 1), _fd(t.phi, u), rtol=1e-8)
    np.testing.assert_allclose(t.phi(u, 2), _fd(lambda w: t.phi(w, 1), u), rtol=1e-8)
    # the jump of 2 sign(v) at 0 is 4 delta(v): the regularized delta integrates to 4
    eps = 0.05
    w = np.linspace(-1, 1, 20001)
    assert np.trapezoid(t.phi(w, 3, eps), w) == pytest.approx(4.0, rel=1e-10)
    assert t.phi(np.array([0.0]), 3, eps)[0] == pytest.approx(4 / (eps * math.sqrt(2 * math.pi)))


def test_coulomb_regularized_delta_and_its_derivatives():
    t = get_term("coulomb_friction")
    eps = 0.1
    w = np.linspace(-2, 2, 40001)
    d = t.phi(w, 1, eps)  # 2 delta_eps
    # the regularized delta integrates to 1 (Gaussian of sd eps; |w| <= 20 eps)
    assert np.trapezoid(d / 2, w) == pytest.approx(1.0, rel=1e-10)
    assert np.trapezoid(w**2 * d / 2, w) == pytest.approx(eps**2, rel=1e-8)  # its variance
    assert np.trapezoid(t.phi(w, 2, eps), w) == pytest.approx(0.0, abs=1e-10)
    u = np.linspace(-0.5, 0.5, 101)
    np.testing.assert_allclose(
        t.phi(u, 2, eps), _fd(lambda v: t.phi(v, 1, eps), u, 1e-6), rtol=1e-6, atol=1e-6
    )
    np.testing.assert_allclose(
        t.phi(u, 3, eps), _fd(lambda v: t.phi(v, 2, eps), u, 1e-6), rtol=1e-6, atol=1e-4
    )


@pytest.mark.parametrize("name", ["linear_damping", "quadratic_damping", "coulomb_friction"])
def test_antiderivative_is_the_generators_test_function(name):
    t = get_term(name)
    u = np.concatenate([np.linspace(-3, -0.1, 30), np.linspace(0.1, 3, 30)])
    np.testing.assert_allclose(_fd(t.antiderivative, u), t.phi(u), rtol=1e-8)
    assert t.antiderivative(np.array([0.0]))[0] == 0.0


@pytest.mark.parametrize(
    ("name", "c"),
    [
        ("linear_damping", lambda s: 1.0),
        ("quadratic_damping", lambda s: math.sqrt(8 / math.pi) * s),  # eq (65)
        ("coulomb_friction", lambda s: math.sqrt(2 / math.pi) / s),
        ("linear_stiffness", lambda s: 0.0),
    ],
)
def test_damping_factor_is_statistical_linearization(name, c):
    """c = E[v phi(v)] / E[v^2] for a Gaussian velocity of sd s (quadrature)."""
    t = get_term(name)
    s = 7.2
    assert t.damping_factor(s) == pytest.approx(c(s), rel=1e-14, abs=0)
    if t.variable == "v":

        def density(v):
            return math.exp(-0.5 * (v / s) ** 2) / (s * math.sqrt(2 * math.pi))

        num = integrate.quad(lambda v: v * float(t.phi(np.array(v))) * density(v), -12 * s, 12 * s)
        assert num[0] / s**2 == pytest.approx(t.damping_factor(s), rel=1e-8)


# ------------------------------------------------------------------ Model
def test_paper_and_linear_layouts():
    paper = Model.from_spec("paper")
    assert paper.param_names == ("a1", "n1", "a2", "n2", "S0")  # eq (45) order, then S0
    assert paper.names == (*ALIASES["paper"], "excitation_level")
    assert paper.n_drift == 4
    assert [t.name for t in paper.drift_terms] == list(ALIASES["paper"])
    assert paper.index("S0") == 4 and paper.has("n1") and paper.has("cubic_stiffness")
    assert not paper.has("b2")
    assert paper.candidates == tuple(c for c in CANDIDATES if c not in paper.names)
    lin = Model.from_spec("linear")
    assert lin.param_names == ("a1", "a2", "S0")


def test_a_shaping_filter_candidate_replaces_a_band_edge():
    """A band-limited model keeps the shaping filter among its candidates, and the
    extended model swaps the edge for the filter; other candidates are added.
    """
    band = Model.from_spec("paper,band_limited_excitation")
    assert "narrowband_excitation" in band.candidates
    assert "narrowband_excitation" not in band.with_term("coloured_excitation").candidates
    ext = band.extended("narrowband_excitation")
    assert ext.names == Model.from_spec("paper,narrowband_excitation").names
    assert band.extended("coulomb_friction") == band.with_term("coulomb_friction")
    with pytest.raises(HosidInputError, match="coloured_excitation is not a candidate"):
        band.extended("coloured_excitation")


def test_spec_strings_lists_aliases_and_canonical_order():
    a = Model.from_spec("measurement_noise, linear_stiffness,linear_damping")
    b = Model.from_spec(["linear_damping", "linear_stiffness", "measurement_noise"])
    assert a == b
    assert a.param_names == ("a1", "a2", "S0", "noise_sd")
    c = Model.from_spec("paper,quadratic_stiffness,paper")  # aliases expand, duplicates drop
    assert c.param_names == ("a1", "n1", "a2", "n2", "b2", "S0")
    assert Model.from_spec("excitation_mean,linear") == Model.from_spec("linear").with_term(
        "excitation_mean"
    )
    full = Model.from_spec([t for t in TERMS if t not in WHITENING_OR_IMPULSES])
    assert full.param_names == (
        "a1", "n1", "a2", "n2", "b2", "mu", "m", "S0", "wc", "wb", "rolloff", "noise_sd"
    )  # fmt: skip
    assert Model.from_spec(full) is full
    nb = Model.from_spec("paper,measurement_noise,narrowband_excitation")
    assert nb.param_names == ("a1", "n1", "a2", "n2", "S0", "wf", "zf", "noise_sd")


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


def test_a_model_needs_damping_and_restoring_terms():
    with pytest.raises(HosidInputError, match="restoring term"):
        Model.from_spec("linear_damping")
    with pytest.raises(HosidInputError, match="damping term"):
        Model.from_spec("linear_stiffness,cubic_stiffness")
    with pytest.raises(HosidInputError, match="not a model term"):
        Model((3.5,))


def test_with_term_returns_a_new_model_and_rejects_duplicates():
    lin = Model.from_spec("linear")
    bigger = lin.with_term("coulomb_friction")
    assert "coulomb_friction" in bigger.names and "coulomb_friction" not in lin.names
    assert bigger.param_names == ("a1", "a2", "mu", "S0")
    assert lin.with_term("coloured_excitation").param_names == ("a1", "a2", "S0", "wc")
    with pytest.raises(HosidInputError, match="already has linear_damping"):
        lin.with_term("linear_damping")
    with pytest.raises(HosidInputError, match="valid terms: linear_damping") as err:
        lin.with_term("stiction")
    assert "\n" not in str(err.value)
    nb = Model.from_spec("paper,narrowband_excitation")
    assert nb.without_term("narrowband_excitation").names == Model.from_spec("paper").names
    with pytest.raises(HosidInputError, match="model has no coulomb_friction"):
        lin.without_term("coulomb_friction")


def test_params_and_vector():
    paper = Model.from_spec("paper")
    assert paper.params(PAPER_PARAMS) == PAPER_PARAMS
    assert paper.params([0.5, 0.5, 25, 5, 100]) == PAPER_PARAMS
    assert list(paper.params(PAPER_PARAMS)) == list(paper.param_names)
    np.testing.assert_array_equal(paper.vector(PAPER_PARAMS), [0.5, 0.5, 25, 5, 100])
    with pytest.raises(HosidInputError, match=r"missing \['S0'\]"):
        paper.params({k: v for k, v in PAPER_PARAMS.items() if k != "S0"})
    with pytest.raises(HosidInputError, match=r"unknown \['b2'\]"):
        paper.params({**PAPER_PARAMS, "b2": 1.0})
    with pytest.raises(HosidInputError, match=r"expected \(5,\)"):
        paper.params([1.0, 2.0])


def test_equivalent_damping_eq65_vectorizes():
    model = Model.from_spec("paper,coulomb_friction")
    s = 7.2
    th = np.random.default_rng(0).normal(size=(3, 4, len(model.param_names)))
    got = model.equivalent_damping(th, s)
    assert got.shape == (3, 4)
    i = {n: model.index(n) for n in ("a1", "n1", "mu")}
    ref = th[..., i["a1"]] + math.sqrt(8 / math.pi) * s * th[..., i["n1"]]
    ref = ref + math.sqrt(2 / math.pi) / s * th[..., i["mu"]]
    np.testing.assert_allclose(got, ref, rtol=1e-14)
    # the paper point: 0.5 + 0.5 * 1.596 * 7.2 = 6.245
    assert Model.from_spec("paper").equivalent_damping(
        np.array([0.5, 0.5, 25, 5, 100]), s
    ) == pytest.approx(0.5 + 0.5 * 1.5957691216 * 7.2, rel=1e-9)


def test_model_simulate_is_the_simulator():
    model = Model.from_spec("paper")
    kw = {"duration": 30.0, "dt": 0.02}
    a = model.simulate([0.5, 0.5, 25, 5, 100], rng=np.random.default_rng(3), **kw)
    b = simulate(PAPER_PARAMS, rng=np.random.default_rng(3), **kw)
    np.testing.assert_array_equal(a.x, b.x)


def test_latex_and_repr():
    model = Model.from_spec("linear").with_term("excitation_mean")
    assert model.latex() == r"\ddot x + a_1\,\dot x + a_2\,x - m = g(t)"
    assert repr(model) == (
        "Model(linear_damping + linear_stiffness + excitation_mean + excitation_level)"
    )


def test_docstring_examples_run():
    result = doctest.testmod(hosid.model.model, raise_on_error=True)
    assert result.attempted >= 2


# ------------------------------------------------------------------ priors
@pytest.mark.parametrize(
    "prior",
    [
        Uniform(-2.0, 3.0),
        LogUniform(0.1, 50.0),
        Normal(1.0, 2.0),
        LogNormal(1.0, 1.2, 0.01, 50.0),
        LogNormal(2.0, 0.5, 1.5, 3.0),
    ],
)
def test_prior_normalized_and_sampled_by_its_inverse_cdf(prior):
    lo, hi = max(prior.lower, -30.0), min(prior.upper, 60.0)
    pts = (
        [0.1, 1.0, 10.0] if prior.log_scaled and lo < 0.1 else [1.0] if prior.log_scaled else None
    )
    area = integrate.quad(lambda x: math.exp(prior.ln_prob(x)), lo, hi, points=pts, limit=200)
    assert area[0] == pytest.approx(1.0, abs=1e-6)
    x = prior.sample(np.random.default_rng(1), 4000)
    assert x.shape == (4000,)
    assert np.all(np.isfinite(prior.ln_prob(x)))
    # the empirical CDF at the quartiles of rescale (binomial sd <= 0.008 for 4000 draws)
    for u in (0.25, 0.5, 0.75):
        assert np.mean(x <= prior.rescale(u)) == pytest.approx(u, abs=0.03)


def test_prior_support_and_bad_arguments():
    assert Uniform(0.0, 1.0).ln_prob(1.5) == -np.inf
    assert LogUniform(1.0, 2.0).ln_prob(0.5) == -np.inf
    assert LogUniform(1.0, 2.0).ln_prob(-1.0) == -np.inf
    with pytest.raises(ValueError, match="lower < upper"):
        Uniform(1.0, 1.0)
    with pytest.raises(ValueError, match="0 < lower"):
        LogUniform(0.0, 1.0)
    with pytest.raises(ValueError, match="sigma > 0"):
        Normal(0.0, -1.0)
    with pytest.raises(ValueError, match="lower < median < upper"):
        LogNormal(5.0, 1.0, 0.1, 2.0)
    assert LogNormal(1.0, 1.0, 0.1, 10.0).ln_prob(20.0) == -np.inf
    assert LogNormal(1.0, 1.0, 0.1, 10.0).log_scaled and not Uniform(0, 1).log_scaled
    assert str(Uniform(0, 1)) == "U(0, 1)"


def test_default_priors_hold_the_paper_values_and_the_null_effects():
    model = Model.from_spec([t for t in TERMS if t not in WHITENING_OR_IMPULSES])
    priors = model.default_priors(PAPER_SCALES)
    assert priors.names == model.param_names
    assert all(isinstance(priors[n], Prior) for n in priors)
    truth = {**PAPER_PARAMS, "b2": 0.0, "mu": 0.0, "m": 0.0, "noise_sd": 0.0, "wc": 3.0}
    truth["wb"] = math.pi / PAPER_SCALES.dt  # no edge seen: U(w_N / 2, 2 w_N)
    truth["rolloff"] = 0.0  # a flat band
    for name, value in truth.items():
        assert np.isfinite(priors[name].ln_prob(value)), name
    assert np.isfinite(priors.ln_prob(model.vector(truth)))
    assert priors["mu"].lower == 0.0 and priors["noise_sd"].lower == 0.0  # physical signs
    assert isinstance(priors["S0"], LogUniform) and isinstance(priors["wc"], LogUniform)
    assert priors["S0"].lower == pytest.approx(1.05) and priors["S0"].upper == pytest.approx(
        1.05e4
    )
    assert set(priors.describe()) == {*model.param_names, "constraint a1eq"}


def test_default_priors_carry_the_eq65_constraint():
    model = Model.from_spec("paper")
    priors = model.default_priors(PAPER_SCALES)
    s = PAPER_SCALES.sigma_v
    th = np.array([[0.5, 0.5, 25, 5, 100], [-0.5, -0.5, 25, 5, 100], [-3.0, 0.5, 25, 5, 100]])
    lp = priors.ln_prob(th)
    # a1eq = a1 + n1 sqrt(8/pi) 7.2: 6.25 > 0; -6.25 < 0; -3 + 5.74 > 0
    assert np.isfinite(lp[0]) and lp[1] == -np.inf and np.isfinite(lp[2])
    draws = priors.sample(np.random.default_rng(2), 2000)
    assert draws.shape == (2000, 5)
    assert np.all(model.equivalent_damping(draws, s) > 0)
    assert np.all(np.isfinite(priors.ln_prob(draws)))
    # without the constraint about half the box has a1eq < 0 (the box is symmetric)
    free = model.default_priors(PAPER_SCALES, constrained=False)
    assert not free.constraints
    assert np.all(np.isfinite(free.ln_prob(th)))
    frac = np.mean(model.equivalent_damping(free.sample(np.random.default_rng(3), 4000), s) < 0)
    assert frac == pytest.approx(0.5, abs=0.03)  # binomial sd 0.008


def test_priorset_checks_shapes_and_impossible_constraints():
    ps = PriorSet({"a": Uniform(0, 1), "b": Normal(0, 1)}, {"never": lambda th: -np.ones(1)})
    with pytest.raises(ValueError, match="theta has 3 parameters, expected 2"):
        ps.ln_prob(np.zeros(3))
    with pytest.raises(ValueError, match="constraints exclude almost all"):
        ps.sample(np.random.default_rng(0), 5)
    ok = PriorSet({"a": Uniform(0, 1), "b": Normal(0, 1)})
    assert ok.ln_prob(np.zeros((4, 6, 2))).shape == (4, 6)
    assert list(ok) == ["a", "b"] and len(ok) == 2
    np.testing.assert_allclose(
        ok.ln_prob(np.array([0.5, 1.0])), -0.5 - 0.5 * math.log(2 * math.pi), rtol=1e-14
    )


def test_priorset_box_path_equals_the_sum_of_its_priors():
    # uniform and log-uniform priors take one vectorized pass; it must equal the sum of
    # the priors' own log densities, -inf outside any support
    priors = {"a": Uniform(-1.0, 2.0), "s": LogUniform(0.5, 50.0), "b": Uniform(0.0, 4.0)}
    box = PriorSet(priors)
    assert box._box is not None
    th = np.random.default_rng(0).uniform([-1.5, 0.1, -0.5], [2.5, 60.0, 4.5], size=(500, 3))
    expect = sum(p.ln_prob(th[:, i]) for i, p in enumerate(priors.values()))
    got = box.ln_prob(th)
    np.testing.assert_array_equal(np.isfinite(got), np.isfinite(expect))
    ok = np.isfinite(expect)
    assert 50 < ok.sum() < 500
    np.testing.assert_allclose(got[ok], expect[ok], rtol=1e-13)
    assert PriorSet({**priors, "n": Normal(0.0, 1.0)})._box is None  # the general path
