"""The System of n degrees of freedom: names, equations, linear part, files.

Oracles: the single oscillator's drift (hosid.model.Model's terms), the equations of a
2-dof chain written out by hand, the modes of the two-spring chain derived by hand, the
Lyapunov covariance of the single oscillator (pi S0 / (a1 a2), pi S0 / a1).  Exact
identities are checked to 1e-12 relative.
"""

import math

import numpy as np
import pytest

from hosid.errors import HosidInputError
from hosid.model import Model
from hosid.model.linear_chain import linearize, modes, stationary_covariance
from hosid.model.system import System
from hosid.model.system_file import read_system

ISSUE_FILE = """
dofs = ["x1", "x2"]
[[element]]
between = ["ground", "x1"]
terms = ["linear_damping", "quadratic_damping", "linear_stiffness", "cubic_stiffness"]
[[element]]
between = ["x1", "x2"]
terms = ["linear_damping", "linear_stiffness"]
"""


def _file(tmp_path, text, name="system.toml"):
    path = tmp_path / name
    path.write_text(text)
    return path


def _model_drift(model, theta, x, v):
    """The single oscillator's drift sum_k theta_k phi_k from the Model's terms."""
    return sum(
        th * t.phi(v if t.variable == "v" else x)
        for th, t in zip(theta, model.drift_terms, strict=False)
    )


@pytest.mark.parametrize(
    "spec",
    ["paper", "linear", "paper,quadratic_stiffness,coulomb_friction,excitation_mean"],
)
def test_one_element_chain_is_the_single_oscillator(spec, tmp_path):
    model = Model.from_spec(spec)
    system = System.single(model)
    assert system.param_names == model.param_names
    rng = np.random.default_rng(1)
    x, v = rng.normal(size=(2, 50))
    theta = rng.uniform(0.2, 3.0, size=len(model.param_names))
    got = system.drift_force(x[:, None], v[:, None], theta)[:, 0]
    np.testing.assert_allclose(got, _model_drift(model, theta, x, v), rtol=1e-12, atol=1e-12)
    # the same chain from a file, named with brackets, either end order for odd terms
    for between in ('["ground", "x"]', '["x", "ground"]'):
        text = f'dofs = ["x"]\n[[element]]\nbetween = {between}\nterms = ["paper"]\n'
        s = System.from_toml(_file(tmp_path, text))
        assert s.param_names == ("a1[ground-x]", "n1[ground-x]", "a2[ground-x]",
                                 "n2[ground-x]", "S0[x]")  # fmt: skip
        paper = Model.from_spec("paper")
        th = np.array([0.5, 0.5, 25.0, 5.0, 100.0])
        np.testing.assert_allclose(
            s.drift_force(x[:, None], v[:, None], th)[:, 0], _model_drift(paper, th, x, v),
            rtol=1e-12,
        )  # fmt: skip


def test_two_dof_drift_as_written_by_hand():
    s = System(
        ("x1", "x2"),
        [(("ground", "x1"), ("paper",)), (("x1", "x2"), ("linear", "cubic_stiffness"))],
    )
    assert s.param_names == (
        "a1[ground-x1]", "n1[ground-x1]", "a2[ground-x1]", "n2[ground-x1]",
        "a1[x1-x2]", "a2[x1-x2]", "n2[x1-x2]", "mass[x2]", "S0[x1]", "S0[x2]",
    )  # fmt: skip
    a1, n1, a2, n2, c, k, g, m2 = 0.5, 0.4, 25.0, 5.0, 0.3, 15.0, 2.0, 0.7
    theta = [a1, n1, a2, n2, c, k, g, m2, 1.0, 2.0]
    rng = np.random.default_rng(2)
    q, qd = rng.normal(size=(2, 40, 2))
    r, rd = q[:, 1] - q[:, 0], qd[:, 1] - qd[:, 0]
    coupling = c * rd + k * r + g * r**3
    f1 = a1 * qd[:, 0] + n1 * qd[:, 0] * abs(qd[:, 0]) + a2 * q[:, 0] + n2 * q[:, 0] ** 3
    expected = np.stack([f1 - coupling, coupling], axis=-1)
    np.testing.assert_allclose(s.drift_force(q, qd, theta), expected, rtol=1e-12)
    # the linear form M q'' + Phi theta = F, and the force a response implies
    Phi = s.features(q, qd)
    assert Phi.shape == (40, 2, s.n_drift)
    np.testing.assert_allclose(Phi @ np.array(theta[: s.n_drift]), expected, rtol=1e-12)
    F = rng.normal(size=(40, 2))
    acc = s.acceleration(q, qd, theta, F)
    np.testing.assert_allclose(acc[:, 1], (F[:, 1] - coupling) / m2, rtol=1e-12)
    np.testing.assert_allclose(s.inferred_force(q, qd, acc, theta), F, rtol=1e-10, atol=1e-12)
    # vectorised over parameter sets: theta (k, p) against states (k, n)
    thetas = np.array([theta, [2 * t for t in theta]])
    both = s.drift_force(q[:2], qd[:2], thetas)
    np.testing.assert_allclose(both[1], 2 * expected[1], rtol=1e-12)
    # masses and levels
    np.testing.assert_allclose(s.mass_vector(theta), [1.0, m2])
    np.testing.assert_allclose(s.levels(theta), [1.0, 2.0])


def test_layout_with_known_masses_and_driven_subset(tmp_path):
    text = 'driven = ["x2"]\nmeasured = {x1 = "acceleration"}\n' + ISSUE_FILE
    text += '[masses]\nx2 = 0.5\n[values]\n"S0[x2]" = 3.0\n"a1[x1-x2]" = 0.2\n'
    s = System.from_toml(_file(tmp_path, text))
    assert s.param_names == (
        "a1[ground-x1]", "n1[ground-x1]", "a2[ground-x1]", "n2[ground-x1]",
        "a1[x1-x2]", "a2[x1-x2]", "S0[x2]",
    )  # fmt: skip
    assert s.masses == (1.0, 0.5) and s.driven == ("x2",)
    assert s.measured == ("acceleration", None)  # x2 undeclared: the record says
    assert s.declared == {"x1": "acceleration"}
    assert dict(s.values) == {"a1[x1-x2]": 0.2, "S0[x2]": 3.0}
    np.testing.assert_allclose(s.levels(np.arange(7.0)), [0.0, 6.0])
    with pytest.raises(HosidInputError, match="values missing for a1\\[ground-x1\\]"):
        s.vector()


def test_modes_of_the_two_spring_chain():
    # m = 1, springs k between ground-x1 and x1-x2, C = alpha K: w^2 = k (3 -+ sqrt 5) / 2,
    # zeta = alpha w / 2, shapes (phi2 / phi1) = (1 +- sqrt 5) / 2
    k, alpha = 10.0, 0.05
    s = System(("x1", "x2"), [(("ground", "x1"), ("linear",)), (("x1", "x2"), ("linear",))])
    theta = [alpha * k, k, alpha * k, k, 1.0, 1.0, 1.0]
    M, C, K = linearize(s, theta)
    np.testing.assert_allclose(K, [[2 * k, -k], [-k, k]])
    np.testing.assert_allclose(C, alpha * K)
    np.testing.assert_allclose(M, np.eye(2))
    m = modes(s, theta)
    w = np.sqrt(k * np.array([(3 - math.sqrt(5)) / 2, (3 + math.sqrt(5)) / 2]))
    np.testing.assert_allclose(m.omega, w, rtol=1e-12)
    np.testing.assert_allclose(m.zeta, alpha * w / 2, rtol=1e-10)
    golden = (1 + math.sqrt(5)) / 2
    np.testing.assert_allclose(m.shapes, [[1 / golden, 1.0], [1.0, -1 / golden]], atol=1e-12)
    np.testing.assert_allclose(m.frequency_hz, w / (2 * math.pi))


def test_lyapunov_covariance_of_the_single_oscillator():
    a1, a2, S0 = 1.5, 25.0, 10.0
    P = stationary_covariance(System.single("linear"), [a1, a2, S0])
    expected = np.diag([math.pi * S0 / (a1 * a2), math.pi * S0 / a1])
    np.testing.assert_allclose(P, expected, rtol=1e-12, atol=1e-12)
    with pytest.raises(HosidInputError, match="no stationary state"):
        stationary_covariance(System.single("paper"), [0.0, 0.5, 25.0, 5.0, 1.0])


def test_single_takes_only_a_white_force():
    with pytest.raises(HosidInputError, match="coloured_excitation"):
        System.single("paper,coloured_excitation")
    assert System.single("paper", {"a1": 1, "n1": 0, "a2": 4, "n2": 0, "S0": 1}).vector()[2] == 4


BAD_FILES = [
    (
        ISSUE_FILE.replace('dofs = ["x1", "x2"]', 'dofs = ["x1", "x2", "x3"]'),
        "no element touches degree of freedom 'x3'",
    ),
    (
        ISSUE_FILE.replace('between = ["x1", "x2"]', 'between = ["x1", "x9"]'),
        "unknown degree of freedom 'x9'",
    ),
    (ISSUE_FILE.replace('"ground", "x1"', '"x1", "x1"'), "between 'x1' and itself"),
    (
        ISSUE_FILE.replace('"linear_damping", "linear_stiffness"]', '"springy"]'),
        "element 2 \\(x1-x2\\): unknown model term 'springy'",
    ),
    (
        ISSUE_FILE.replace('"linear_damping", "linear_stiffness"]', '"coloured_excitation"]'),
        "not a drift term",
    ),
    (
        ISSUE_FILE.replace(
            '"linear_damping", "linear_stiffness"]', '"linear_damping", "linear_damping"]'
        ),
        "term linear_damping given twice",
    ),
    (
        ISSUE_FILE + '[[element]]\nbetween = ["x2", "x1"]\nterms = ["linear_damping"]\n',
        "two elements between x2-x1",
    ),
    (
        ISSUE_FILE.replace('dofs = ["x1", "x2"]', 'dofs = ["x1", "x2", "x1"]'),
        "degree of freedom 'x1' given twice",
    ),
    ('dofs = ["ground"]\n', "bad degree of freedom name 'ground'"),
    ('dofs = ["x-1"]\n', "bad degree of freedom name"),
    ("dofs = []\n", "dofs must be a non-empty list"),
    (ISSUE_FILE.replace("dofs", "dof"), "unknown key 'dof'"),
    ('dofs = ["x1"]\n', "give the elements as \\[\\[element\\]\\]"),
    (
        'dofs = ["x1"]\n[element]\nbetween = ["ground", "x1"]\nterms = ["linear"]\n',
        "give the elements as \\[\\[element\\]\\]",
    ),
    (
        ISSUE_FILE.replace('terms = ["linear_damping", "linear_stiffness"]', "stuff = 1"),
        "element 2: unknown key 'stuff'",
    ),
    (
        ISSUE_FILE.replace('terms = ["linear_damping", "linear_stiffness"]', "terms = []"),
        "terms must be a non-empty list",
    ),
    (
        ISSUE_FILE.replace('between = ["x1", "x2"]', 'between = ["x2"]'),
        "between must be two names",
    ),
    (
        'dofs = ["x1", "x2"]\n[[element]]\nbetween = ["ground", "x1"]\nterms = ["paper"]\n'
        '[[element]]\nbetween = ["x2", "x3"]\nterms = ["linear"]\ndofs2 = 1\n',
        "unknown key",
    ),
    (
        'dofs = ["x1", "x2", "x3"]\n[[element]]\nbetween = ["ground", "x1"]\nterms = ["paper"]\n'
        '[[element]]\nbetween = ["x2", "x3"]\nterms = ["linear"]\n',
        "x2, x3 not joined to the ground",
    ),
    (
        'dofs = ["x1"]\n[[element]]\nbetween = ["ground", "x1"]\nterms = ["linear_stiffness"]\n',
        "needs a restoring term and a damping term",
    ),
    (ISSUE_FILE + "[masses]\nx2 = -1\n", "mass of x2 must be finite and positive"),
    (ISSUE_FILE + "[masses]\nx7 = 1\n", "masses: unknown degree of freedom 'x7'"),
    ("masses = [1, 2]\n" + ISSUE_FILE, "masses must be a table"),
    ('driven = ["x5"]\n' + ISSUE_FILE, "driven: unknown degree of freedom 'x5'"),
    ('driven = "x1"\n' + ISSUE_FILE, "driven must be a list"),
    ('driven = ["x1", "x1"]\n' + ISSUE_FILE, "driven lists a degree of freedom twice"),
    ('measured = "velocity"\n' + ISSUE_FILE, "measured must be displacement or acceleration"),
    ('measured = {x4 = "acceleration"}\n' + ISSUE_FILE, "measured: unknown degree of freedom"),
    (ISSUE_FILE + '[values]\n"a1[x1-x3]" = 1.0\n', "values: unknown parameter 'a1\\[x1-x3\\]'"),
    (ISSUE_FILE + '[values]\n"mass[x2]" = "heavy"\n', "values: mass\\[x2\\] must be a finite"),
    (ISSUE_FILE + '[values]\n"S0[x1]" = nan\n', "must be a finite number"),
    (ISSUE_FILE + '[masses]\nx2 = 2\n[values]\n"mass[x2]" = 1\n', "unknown parameter"),
    ('dofs = ["x1"\n', "not a valid TOML file"),
]


@pytest.mark.parametrize(("text", "message"), BAD_FILES)
def test_bad_system_files(tmp_path, text, message):
    path = _file(tmp_path, text)
    with pytest.raises(HosidInputError, match=message) as info:
        read_system(path)
    assert "\n" not in str(info.value) and str(info.value).startswith(str(path))


def test_unreadable_system_files(tmp_path):
    with pytest.raises(HosidInputError, match="no such file"):
        read_system(tmp_path / "missing.toml")
    with pytest.raises(HosidInputError, match="not a file"):
        read_system(tmp_path)
    bad = tmp_path / "latin.toml"
    bad.write_bytes(b'dofs = ["x\xe9"]\n')
    with pytest.raises(HosidInputError, match=r"latin\.toml: not"):
        read_system(bad)


def test_bad_parameter_vectors():
    s = System.single("paper")
    with pytest.raises(HosidInputError, match="expected \\(5,\\)"):
        s.params([1.0, 2.0])
    with pytest.raises(HosidInputError, match="missing \\['S0'\\]"):
        s.params({"a1": 1, "n1": 1, "a2": 1, "n2": 1})
    with pytest.raises(HosidInputError, match="last axis of 1"):
        s.drift_force(np.zeros((3, 2)), np.zeros((3, 2)), np.ones(5))


def test_docstring_examples():
    import doctest

    import hosid.model.system

    result = doctest.testmod(hosid.model.system, raise_on_error=True)
    assert result.attempted >= 2


def test_a_linear_spring_alone_is_constrained_positive_and_a_cubic_ones_is_not():
    """A stationary chain has every element's potential bounded below: an element whose
    only restoring term is a linear spring gets ``stiffness[<element>] > 0`` with the
    constraints, one with a cubic spring beside it none."""
    from hosid.model.system_priors import SystemScales, linear_springs, system_priors
    from hosid.model.terms import Scales

    s = System(("x1", "x2"), [(("ground", "x1"), ("linear_damping", "linear_stiffness",
                                                  "cubic_stiffness")),
                              (("x1", "x2"), ("linear",))])  # fmt: skip
    assert linear_springs(s) == {1: s.index("a2[x1-x2]")}
    sc = Scales(sigma_x=1.0, sigma_v=5.0, S0=10.0, dt=0.02)
    priors = system_priors(s, SystemScales((sc, sc), (10.0, 10.0)))
    assert "constraint stiffness[x1-x2]" in priors.describe()
    assert not any("stiffness[ground-x1]" in k for k in priors.describe())
    th = np.array([0.5, 20.0, 5.0, 0.3, 10.0, 1.0, 10.0, 10.0])
    assert priors.admissible(th)
    th[s.index("a2[x1-x2]")] = -10.0
    assert not priors.admissible(th) and priors.ln_prob(th) == -np.inf
    loose = system_priors(s, SystemScales((sc, sc), (10.0, 10.0)), constrained=False)
    assert not loose.constraints
