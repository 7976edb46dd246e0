"""The engine in n dimensions: a system's state, equations, estimate and fit.

Oracles: the one-element chain's equations, pilot and estimate against the single
oscillator's own components (exactly: the same numbers to the last digit); the generator
identities of a linear 2-dof chain with unknown mass and two levels, evaluated on the
exact Lyapunov moments (zero to 1e-12); the identities at the true parameters on
simulated records (4 standard errors of their block means); the state of acceleration
channels against the simulated velocity (its samples exactly) and the Lyapunov variance
of the displacement; a 2-dof fit within 4 posterior sds of its truth.  Fixed seeds.
"""

import dataclasses
import json

import numpy as np
import pytest

import hosid
from hosid import cli
from hosid.chain_state import ChainState
from hosid.components import J2, ForceKurtosis, Identities, Level
from hosid.components.chain_cumulant import ChainKurtosis
from hosid.components.chain_features import restoration
from hosid.components.chain_identities import ChainIdentities, combine, rows
from hosid.components.chain_spectral import ChainJ2, ChainLevel
from hosid.errors import HosidInputError
from hosid.inference import FitOptions
from hosid.inference.estimate import components_for, estimate, log_params
from hosid.inference.pilot import pilot
from hosid.inference.solutions import solve_rounds
from hosid.model.chain import simulate_chain
from hosid.model.linear_chain import stationary_covariance
from hosid.model.model import Model
from hosid.model.system import System
from hosid.state import RecordState

DT = 0.02
#: A linear 2-dof chain, mass and levels unknown: modes 3.9 and 8.1 rad/s.
LINEAR2 = System(
    ("x1", "x2"),
    [(("ground", "x1"), ("linear",)), (("x1", "x2"), ("linear",))],
    values={
        "a1[ground-x1]": 1.0, "a2[ground-x1]": 25.0, "a1[x1-x2]": 0.5, "a2[x1-x2]": 15.0,
        "mass[x2]": 0.5, "S0[x1]": 10.0, "S0[x2]": 5.0,
    },
)  # fmt: skip
CHAIN_TOML = """dofs = ["x1", "x2"]
[[element]]
between = ["ground", "x1"]
terms = ["linear_damping", "quadratic_damping", "linear_stiffness", "cubic_stiffness"]
[[element]]
between = ["x1", "x2"]
terms = ["linear_damping", "linear_stiffness"]
[values]
"a1[ground-x1]" = 0.3
"n1[ground-x1]" = 0.1
"a2[ground-x1]" = 25.0
"n2[ground-x1]" = 5.0
"a1[x1-x2]" = 0.3
"a2[x1-x2]" = 15.0
"mass[x2]" = 0.8
"S0[x1]" = 2.0
"S0[x2]" = 2.0
"""
PAPER = {"a1": 0.5, "n1": 0.5, "a2": 25.0, "n2": 5.0, "S0": 100.0, "mu": 2.0, "b2": 1.0,
         "m": 3.0}  # fmt: skip


@pytest.fixture(scope="module")
def paper_record():
    return hosid.simulate(hosid.PAPER_PARAMS, duration=2000.0, dt=DT, rng=np.random.default_rng(1))


# ------------------------------------------------------------ the one-element chain
@pytest.mark.parametrize(
    "spec", ["paper", "paper,coulomb_friction", "linear,quadratic_stiffness,excitation_mean"]
)
def test_one_element_chain_has_the_single_oscillators_equations(paper_record, spec):
    model, system = Model.from_spec(spec), System.single(spec)
    centred = not (model.has("b2") or model.has("m"))
    state = RecordState.from_record(paper_record, centred=centred)
    chain = ChainState.from_record(paper_record, centred=centred)
    theta = np.array([PAPER[p] for p in model.param_names])
    thetas = theta + 0.05 * np.random.default_rng(2).standard_normal((3, theta.size))
    pairs = [
        (Identities(), ChainIdentities()),
        (J2(with_level=True), ChainJ2(cross=False)),
        (Level(), ChainLevel()),
        (ForceKurtosis(), ChainKurtosis()),
    ]
    for old, new in pairs:
        a, b = old.prepare(state, model, theta), new.prepare(chain, system, theta)
        assert a.labels == b.labels and a.info == b.info
        np.testing.assert_array_equal(a.mean(thetas), b.mean(thetas))
        np.testing.assert_array_equal(a.influence, b.influence)


def test_single_oscillator_default_estimate_is_the_one_element_chains(paper_record):
    # the single oscillator's own components, solved as estimate() solves them
    model = Model.from_spec("paper")
    state = RecordState.from_record(paper_record)
    theta0 = pilot(state, model)
    support = model.default_priors(state.scales, constrained=False)
    lo = np.array([support[n].lower for n in model.param_names])
    hi = np.array([support[n].upper for n in model.param_names])
    own, _ = solve_rounds(state, model, components_for(), theta0, 2, log_params(model), lo, hi)
    routed = estimate(paper_record, "paper")  # the one-element chain's equations
    as_system = estimate(paper_record, System.single("paper"))
    np.testing.assert_allclose(routed.theta, own, rtol=1e-12)
    np.testing.assert_array_equal(as_system.theta, routed.theta)
    np.testing.assert_array_equal(as_system.cov, routed.cov)
    assert routed.test == as_system.test and routed.sigma_v == as_system.sigma_v


# -------------------------------------------------------------------- identities
def test_identities_of_a_linear_chain_vanish_on_the_lyapunov_moments():
    # every statistic of a linear chain is a second moment of (q, v): with the exact ones
    # the identities hold exactly, whatever the mass and the two levels
    s = LINEAR2
    P = stationary_covariance(s)
    B = s.incidence
    rws = rows(s)

    def vec(e, variable):  # the relative displacement or velocity of element e, in (q, v)
        out = np.zeros(2 * s.n)
        out[(0 if variable == "x" else s.n) : (s.n if variable == "x" else 2 * s.n)] = B[e]
        return out

    feats = [vec(e, t.variable) for e, t in s.columns]
    Pm = np.array([[vec(s.columns[w.col][0], w.kind) @ P @ f for f in feats] for w in rws])
    cm = np.array(
        [0.0 if w.kind == "v" else -(vec(w.element, "v") @ P @ np.r_[0, 0, w.g]) for w in rws]
    )
    em = np.array([1.0 if w.kind == "v" else 0.0 for w in rws])
    got = combine(s, rws, Pm, cm, em)(s.vector())
    assert len(rws) == 5  # the spring between the dofs: one row at each end
    np.testing.assert_allclose(got, 0.0, atol=1e-12 * np.abs(Pm).max())
    # a wrong mass breaks them
    wrong = s.vector().copy()
    wrong[s.index("mass[x2]")] = 0.6
    assert np.abs(combine(s, rws, Pm, cm, em)(wrong)).max() > 1e-3


@pytest.mark.parametrize("measured", ["displacement", "acceleration"])
def test_identities_hold_at_the_truth_on_a_simulated_record(measured):
    system = LINEAR2
    rec = simulate_chain(system, duration=2000.0, dt=DT, rng=np.random.default_rng(5),
                         measured=measured)  # fmt: skip
    state = ChainState.from_record(rec)
    m = ChainIdentities().prepare(state, system, system.vector())
    se = m.influence.std(axis=0, ddof=1) / np.sqrt(m.influence.shape[0])
    z = m.mean(system.vector()) / se
    assert np.all(np.abs(z) < 4.0), dict(zip(m.labels, z.round(2), strict=True))


def test_spectral_equations_are_standardized_alike_in_any_units():
    # the record three times larger, with its levels nine times larger: the cross-spectra
    # of the inferred forces are dimensionless (the same means and block influences), the
    # levels' equations (weighted by d h / d S0) scale by 1/9, means and influences alike.
    # The cross-spectra's influences were once not divided by sqrt(S0_d S0_e): variance
    # 4x too large at S0 = 2, 50x at LINEAR2's levels.
    system = LINEAR2
    rec = simulate_chain(system, duration=600.0, dt=DT, rng=np.random.default_rng(8))
    big = dataclasses.replace(rec, x=3.0 * rec.x)
    theta = system.vector()
    scaled = theta.copy()
    for d in system.dofs:
        scaled[system.index(f"S0[{d}]")] *= 9.0
    a = ChainJ2().prepare(ChainState.from_record(rec), system, theta)
    b = ChainJ2().prepare(ChainState.from_record(big), system, scaled)
    assert a.labels == ("J2 d/dS0[x1]", "J2 d/dS0[x2]", "J2 cross x1-x2 re",
                        "J2 cross x1-x2 im")  # fmt: skip
    units = np.array([1 / 9, 1 / 9, 1.0, 1.0])
    np.testing.assert_allclose(b.mean(scaled), units * a.mean(theta), rtol=1e-9)
    np.testing.assert_allclose(b.influence, units * a.influence, rtol=1e-9, atol=1e-15)


def test_acceleration_channels_hold_the_velocity_samples():
    rec, _, v = simulate_chain(LINEAR2, duration=1000.0, dt=DT, rng=np.random.default_rng(6),
                               measured="acceleration", return_state=True)  # fmt: skip
    state = ChainState.from_record(rec)
    assert [c.kind for c in state.channels] == ["acceleration", "acceleration"]
    first = state.layout.offsets[0]
    assert first * DT >= 2 * np.pi / state.channels[0].omega_low  # the ends left out
    # the state is at the half steps: its velocity differs from the mean of the neighbouring
    # samples' by the Brownian bridge's midpoint, variance 2 pi S0 dt / (4 m^2), and its
    # variance is the Lyapunov one (no restoration above the Nyquist frequency)
    idx = np.arange(first, first + state.layout.B * state.layout.M)
    bridge = (state.v[:, idx] - 0.5 * (v[idx] + v[idx + 1]).T).var(axis=1)
    np.testing.assert_allclose(
        bridge, 2 * np.pi * np.array([10.0, 5.0 / 0.25]) * DT / 4, rtol=0.05
    )
    P = stationary_covariance(LINEAR2)
    np.testing.assert_allclose(state.v[:, idx].var(axis=1), np.diag(P)[2:], rtol=0.08)
    np.testing.assert_allclose(state.q[:, idx].var(axis=1), np.diag(P)[:2], rtol=0.15)
    rest = restoration(state, LINEAR2, LINEAR2.vector())
    assert np.all(rest.s2 == 0.0) and rest.low.shape == (2, 2)


# ----------------------------------------------------------------------------- fit
@pytest.fixture(scope="module")
def chain_file(tmp_path_factory):
    path = tmp_path_factory.mktemp("chain") / "chain.toml"
    path.write_text(CHAIN_TOML)
    return path


def test_fit_of_a_two_dof_chain(chain_file):
    system = System.from_toml(chain_file)
    rec = simulate_chain(system, duration=1500.0, dt=DT, rng=np.random.default_rng(7))
    tree = hosid.fit(rec, system, FitOptions(n_steps=600, seed=1), progress=False)
    post = tree["posterior"]
    assert set(system.param_names) < set(post.data_vars)
    assert "a1eq[ground-x1]" in post.data_vars and "a1eq[x1-x2]" not in post.data_vars
    attrs = json.loads(tree.attrs["system_json"])
    assert attrs["dofs"] == ["x1", "x2"] and attrs["masses"] == {"x1": 1.0, "x2": None}
    for name, true in dict(system.values).items():
        draws = post[name].values
        assert abs(draws.mean() - true) < 4.0 * draws.std(), name
    assert np.all(post["a1eq[ground-x1]"].values > 0)  # eq 65 per element
    assert list(tree["observed_data"].data_vars) == ["Sxx[x1]", "force[x1]", "Sxx[x2]",
                                                     "force[x2]"]  # fmt: skip
    # the modal view: the small-amplitude modes hold the truth's linear part (4 sd)
    from hosid.model.linear_chain import modes
    from hosid.output.results import summarize

    summary = summarize(tree, warn=False)
    truth = modes(system, system.vector())
    assert len(summary["modes"]) == len(summary["modes_small_amplitude"]) == 2
    for m, f, z in zip(summary["modes_small_amplitude"], truth.frequency_hz, truth.zeta,
                       strict=True):  # fmt: skip
        assert abs(m["frequency_hz"]["mean"] - f) < 4 * m["frequency_hz"]["sd"]
        assert abs(m["damping_ratio"]["mean"] - z) < 4 * m["damping_ratio"]["sd"]
    # the hardening ground spring raises the first mode at the response level
    first = summary["modes"][0]["frequency_hz"]["mean"]
    assert first > summary["modes_small_amplitude"][0]["frequency_hz"]["q95"]


def test_a_systems_blocks_are_six_per_equation(chain_file, paper_record):
    """The equations counted from the system are the components' (the prepared
    quasi-likelihood's k); a two-dof chain's record gets at least 6 blocks an equation
    where 4 periods allow it, the single oscillator keeps its 97 blocks of 20.48 s."""
    from hosid.inference.system_estimate import (
        BLOCKS_PER_EQUATION,
        equation_count,
        estimate_system,
        system_state,
    )

    system = System.from_toml(chain_file)
    rec = simulate_chain(system, duration=1500.0, dt=DT, rng=np.random.default_rng(3))
    est = estimate_system(rec, system)
    assert est.ql.k == equation_count(system)
    assert est.ql.B >= BLOCKS_PER_EQUATION * est.ql.k
    assert system_state(rec, system).layout == est.state.layout
    single = System.single(Model.from_spec("paper"))
    assert estimate_system(paper_record, single).ql.B == 97


def test_fit_settings_and_their_errors(chain_file, paper_record):
    system = System.from_toml(chain_file)
    rec = simulate_chain(system, duration=400.0, dt=DT, rng=np.random.default_rng(8))
    with pytest.raises(HosidInputError, match="a system or a model, not both"):
        hosid.fit(rec, system, model="paper")
    with pytest.raises(HosidInputError, match="fitted with the default components"):
        hosid.fit(rec, system, cost="J4A")
    with pytest.raises(TypeError, match="unexpected keyword argument 'walkers'"):
        hosid.fit(rec, system, walkers=40)
    with pytest.raises(HosidInputError, match="has no channel 'x1'"):
        hosid.fit(paper_record, system)
    assert FitOptions.of(None, seed=3) == FitOptions(seed=3)


def test_command_line_simulates_and_fits_a_system(tmp_path, chain_file, capsys):
    rec = tmp_path / "rec.npz"
    argv = ["simulate", "--system", str(chain_file), "--duration", "800", "--seed", "2"]
    assert cli.main([*argv, "--out", str(rec), "--measured", "acceleration"]) == 0
    truths = json.loads(rec.with_suffix(".truths.json").read_text())
    assert truths["mass[x2]"] == 0.8
    out = tmp_path / "fit"
    argv = ["fit", str(rec), "--model", str(chain_file), "--out", str(out)]
    assert cli.main([*argv, "--steps", "200", "--no-progress", "--seed", "1"]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert "n2[ground-x1]" in summary["parameters"] and "S0[x2]" in summary["parameters"]
    report = (out / "report.html").read_text()
    assert "mass[x2] ẍ_x2 + (a1[x1-x2] ṙ + a2[x1-x2] r)(r = x2 - x1) = F_x2" in report
    assert "integrated in time above" in report
    assert '<table id="modes">' in report and len(summary["modes"]) == 2
    assert (out / "mode_shapes.png").read_bytes()[:4] == b"\x89PNG"
    capsys.readouterr()


def _identity_z(state: ChainState, system: System) -> np.ndarray:
    m = ChainIdentities().prepare(state, system, system.vector())
    return m.mean(system.vector()) / (m.influence.std(axis=0) / np.sqrt(len(m.influence)))


@pytest.mark.parametrize("seed", [0, 2])
def test_identities_from_accelerations_extrapolate_the_band_edge(seed):
    """The paper oscillator over 600 s from its accelerations: the identities at the truth
    lie within 1 sd of those of a displacement record of the same motion, and the
    estimate's stiffness law within 2.5 sd of the truth.  Restoring the displacement
    missing below the band as an independent Gaussian part (before 2026-11-27) gave
    a2 = 32.2 +- 1.9 and 33.4 +- 1.7 on these records (truth 25).
    """
    single = System.single("paper", hosid.PAPER_PARAMS)
    kw = {"duration": 600.0, "dt": DT}
    acc = simulate_chain(single, rng=np.random.default_rng(seed), measured="acceleration", **kw)
    disp = simulate_chain(single, rng=np.random.default_rng(seed), **kw)
    z_acc = _identity_z(ChainState.from_record(acc), single)
    z_disp = _identity_z(ChainState.from_record(disp), single)
    np.testing.assert_array_less(np.abs(z_acc - z_disp), 1.0)
    est = estimate(acc, single)
    for k in ("a2", "n2"):
        assert abs(est.values[k] - hosid.PAPER_PARAMS[k]) < 2.5 * est.sd[k], k


def test_a_five_storey_chain_driven_at_the_roof_from_its_accelerations(tmp_path):
    """hosid's own simulation of a uniform shear chain like the building of
    ``analyses/building.py`` (white force at the roof, 5 accelerations, 409.6 s at 0.05
    s): the integrated accelerations have no displacement noise floor (which the chain's
    higher modes had mimicked at 14.2 rad/s, leaving no J2 band), and the estimate's
    first two natural frequencies lie within 2 % of the truth (0.8 % and 0.5 % here).
    """
    from hosid.model.linear_chain import modes

    dofs = ["x1", "x2", "x3", "x4", "x5"]
    text = f'dofs = {json.dumps(dofs)}\ndriven = ["x5"]\nmeasured = "acceleration"\n'
    for a, b in zip(["ground", *dofs[:-1]], dofs, strict=True):
        text += f'[[element]]\nbetween = ["{a}", "{b}"]\n'
        text += 'terms = ["linear_damping", "linear_stiffness"]\n'
    path = tmp_path / "tower.toml"
    path.write_text(text)
    system = System.from_toml(path)
    k = (np.pi * 0.5277 / np.sin(np.pi / 22)) ** 2
    kinds = {"a1": 0.012 * k / (np.pi * 0.5277), "a2": k, "S0": 1e-3, "ma": 1.0}
    values = {n: kinds[n[:2]] for n in system.param_names}
    rec = simulate_chain(system, values, duration=409.6, dt=0.05,
                         rng=np.random.default_rng(1), measured="acceleration")  # fmt: skip
    state = ChainState.from_record(rec, centred=False)
    assert all(c.spectrum.floor == 0.0 for c in state.channels)
    est = estimate(rec, system)
    got, true = modes(est.model, est.theta).omega, modes(system, values).omega
    np.testing.assert_allclose(got[:2], true[:2], rtol=0.02)


@pytest.mark.parametrize("sd", [0.0, 50.0])
def test_sensor_noise_is_a_verdict(sd):
    """White noise of a known level on both accelerations of the two-dof chain: the check
    reads each element's share of noise in its relative displacement and velocity from the
    channels' floors, a lower bound: the least smoothed ordinate reads a white noise at
    0.50 and 0.60 of its level on these channels (at 2, 6, 20 and 50 m/s^2 alike), so 0.4-1.1
    of the share the known noise makes (:func:`noise_shares`); without noise the shares are
    far below :data:`NOISE_SHARE` and it passes."""
    from hosid.components.chain_features import BUTTER_NOISE, BUTTER_WALK, noise_shares
    from hosid.inference.system_estimate import NOISE_SHARE, noise_check

    rec = simulate_chain(LINEAR2, duration=1000.0, dt=DT, rng=np.random.default_rng(6),
                         measured="acceleration")  # fmt: skip
    noisy = dataclasses.replace(rec, x=rec.x + sd * np.random.default_rng(7).standard_normal(
        rec.x.shape))  # fmt: skip
    state = ChainState.from_record(noisy)
    (check,) = noise_check(state, LINEAR2)
    got = noise_shares(state, LINEAR2)
    if sd == 0.0:
        assert check.status == "pass" and check.value < 0.1 * NOISE_SHARE
        return
    B, N = LINEAR2.incidence, sd**2 * DT / (2 * np.pi)  # two-sided, per rad/s
    wl = np.array([c.omega_low for c in state.channels])
    noise = np.stack([2 * N * BUTTER_NOISE / wl**3, 2 * N * BUTTER_WALK / wl])
    var = np.stack([(B @ state.q).var(axis=1), (B @ state.v).var(axis=1)])
    true = (B**2 @ noise.T) / var.T
    assert np.all((0.4 * true < got) & (got < 1.1 * true)), (got, true)
    assert check.status == "warn" and check.value == pytest.approx(got.max())
