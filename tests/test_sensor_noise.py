"""Sensor noise in a system's acceleration channels (``sensor_noise = true``): the
parameters, the simulation, the channels' spectral matrix against its closed form, and the
estimate on simulated noisy records (:mod:`hosid.components.chain_spectral_matrix`)."""

import math

import numpy as np
import pytest

import hosid
from hosid.chain_state import ChainState
from hosid.components.chain_spectral_matrix import (
    ChainSpectralMatrix,
    band_periodogram,
    spectral_matrix,
)
from hosid.errors import HosidInputError
from hosid.model.chain import simulate_chain
from hosid.model.linear_chain import modes
from hosid.model.system import System
from hosid.model.system_file import system_from_dict

DT = 0.05
ELEMENTS = [(("ground", "x1"), ("linear",)), (("x1", "x2"), ("linear",))]
#: The two-dof chain driven at its top, each channel with a white noise of sd 10 (N
#: two-sided per rad/s: sd^2 dt / 2 pi): at the undriven dof all of its flat part above
#: the modes, at the driven one 4 % of its force's flat level there.
VALUES = {
    "a1[ground-x1]": 1.0, "a2[ground-x1]": 25.0, "a1[x1-x2]": 0.5, "a2[x1-x2]": 15.0,
    "mass[x2]": 0.5, "S0[x2]": 5.0, "N[x1]": 100.0 * DT / (2 * math.pi),
    "N[x2]": 100.0 * DT / (2 * math.pi),
}  # fmt: skip
NOISY = System(("x1", "x2"), ELEMENTS, driven=("x2",), measured="acceleration",
               sensor_noise=True, values=VALUES)  # fmt: skip


def test_parameters_and_file():
    assert NOISY.param_names[-3:] == ("S0[x2]", "N[x1]", "N[x2]")
    np.testing.assert_allclose(NOISY.noise_levels(NOISY.vector()), [VALUES["N[x1]"]] * 2)
    np.testing.assert_allclose(NOISY.levels(NOISY.vector()), [0.0, 5.0])
    assert NOISY.index("N[x1]") in NOISY.log_params
    data = {"dofs": ["x1", "x2"], "sensor_noise": ["x2"],
            "element": [{"between": ["ground", "x1"], "terms": ["linear"]}]}  # fmt: skip
    data["element"].append({"between": ["x1", "x2"], "terms": ["linear"]})
    assert system_from_dict(data).sensor_noise == ("x2",)
    with pytest.raises(HosidInputError, match="sensor_noise: unknown degree of freedom 'x3'"):
        system_from_dict({**data, "sensor_noise": ["x3"]})
    with pytest.raises(HosidInputError, match="sensor_noise must be true, false or a list"):
        system_from_dict({**data, "sensor_noise": "x1"})


def test_simulation_adds_each_channels_noise():
    """The same draws of the motion with and without the noise: the difference is white of
    variance 2 pi N / dt (within 5 %, 4000 samples a channel)."""
    quiet = System(("x1", "x2"), ELEMENTS, driven=("x2",), measured="acceleration",
                   values={k: v for k, v in VALUES.items() if not k.startswith("N")})  # fmt: skip
    a = simulate_chain(quiet, duration=200.0, dt=DT, rng=np.random.default_rng(4))
    b = simulate_chain(NOISY, duration=200.0, dt=DT, rng=np.random.default_rng(4))
    e = b.x - a.x
    np.testing.assert_allclose(e.var(axis=0), 2 * math.pi * VALUES["N[x1]"] / DT, rtol=0.05)
    assert abs(np.corrcoef(e[:-1, 0], e[1:, 0])[0, 1]) < 0.05


def test_spectral_matrix_is_the_oscillators_closed_form():
    """One element: S = s2 w^4 S0 / ((k - m w^2)^2 + (c w)^2) + (1 - s2) S0 / m^2 + N with
    s2 = sinc^2(w dt / 2) (the interval average and its aliases), to rounding."""
    one = System(("x1",), [(("ground", "x1"), ("linear",))], measured="acceleration",
                 masses={"x1": 2.0}, sensor_noise=True)  # fmt: skip
    th = np.array([0.3, 9.0, 2.0, 0.01])  # a1, a2, S0, N
    w = np.linspace(0.1, 20.0, 300)
    s2 = np.sinc(w * DT / (2 * math.pi)) ** 2
    exact = s2 * w**4 * 2.0 / ((9.0 - 2.0 * w**2) ** 2 + (0.3 * w) ** 2) + (1 - s2) * 2.0 / 4
    S = spectral_matrix(one, th, w, DT)[:, 0, 0]
    np.testing.assert_allclose(S.real, exact + 0.01, rtol=1e-10)
    np.testing.assert_array_less(np.abs(S.imag), 1e-12 * S.real)
    batch = spectral_matrix(one, np.stack([th, th]), w, DT)  # walkers broadcast
    np.testing.assert_allclose(batch[1], spectral_matrix(one, th, w, DT), rtol=1e-14)


def test_periodogram_of_white_channels_is_their_level():
    """Independent white channels: each periodogram ordinate's mean over the band is the
    two-sided level (within 4 standard errors), the cross-ordinates' mean is near 0."""
    rng = np.random.default_rng(8)
    x = rng.standard_normal((20000, 2)) * [1.0, 3.0]
    rec = hosid.Record(x, DT, "white", channels=("x1", "x2"), measured=("acceleration",) * 2)
    P = band_periodogram(rec, 0.5, 50.0)
    level = np.array([1.0, 9.0]) * DT / (2 * math.pi)
    got = np.einsum("kii->ki", P.matrix).real.mean(axis=0)
    assert np.all(np.abs(got / level - 1) < 4 / math.sqrt(P.omega.size))
    assert abs(P.matrix[:, 0, 1].mean()) < 4 * math.sqrt(level.prod() / P.omega.size)


def test_estimate_of_a_noisy_chain():
    """2000 s of the noisy two-dof chain: the estimate's modes within 4 sd (Laplace,
    delta method by the modes' finite differences) of the truth, its noise level at the
    undriven dof within 20 %; the equations' influence rows are groups of bins."""
    rec = simulate_chain(NOISY, duration=2000.0, dt=DT, rng=np.random.default_rng(11))
    est = hosid.estimate(rec, NOISY)
    assert [m.component for m in est.ql.moments] == ["spectral matrix"]
    assert est.ql.moments[0].info["groups"] > 10 * len(NOISY.param_names)
    true = modes(NOISY, VALUES)
    f = lambda th: np.r_[modes(NOISY, th).omega, modes(NOISY, th).zeta]  # noqa: E731
    h = 1e-6 * np.abs(est.theta)
    J = np.stack([(f(est.theta + e) - f(est.theta - e)) / (2 * e.sum()) for e in np.diag(h)], 1)
    sd = np.sqrt(np.einsum("ij,jk,ik->i", J, est.cov, J))
    z = (f(est.theta) - np.r_[true.omega, true.zeta]) / sd
    assert np.all(np.abs(z) < 4), z
    assert est.theta[NOISY.index("N[x1]")] == pytest.approx(VALUES["N[x1]"], rel=0.2)


def test_sensor_noise_needs_a_linear_system_of_accelerations():
    cubic = System(("x1",), [(("ground", "x1"), ("linear", "cubic_stiffness"))],
                   measured="acceleration", sensor_noise=True,
                   values={"a1[ground-x1]": 0.5, "a2[ground-x1]": 25.0, "n2[ground-x1]": 5.0,
                           "S0[x1]": 10.0, "N[x1]": 0.01})  # fmt: skip
    rec = simulate_chain(cubic, duration=300.0, dt=DT, rng=np.random.default_rng(2))
    state = ChainState.from_record(rec)
    with pytest.raises(HosidInputError, match=r"linear systems only .* cubic_stiffness"):
        ChainSpectralMatrix().prepare(state, cubic, cubic.vector())


def test_the_record_calls_for_the_noise_unless_the_file_says():
    """Not given, the sensor noise is modelled where the ``sensor_noise`` check warns (a
    linear system of accelerations; here noise of sd 30, the check's share 0.24);
    ``sensor_noise = false`` keeps the identities."""
    loud = {**VALUES, "N[x1]": 9 * VALUES["N[x1]"], "N[x2]": 9 * VALUES["N[x2]"]}
    rec = simulate_chain(NOISY, loud, duration=600.0, dt=DT, rng=np.random.default_rng(5))
    values = {k: v for k, v in VALUES.items() if not k.startswith("N")}
    plain = System(("x1", "x2"), ELEMENTS, driven=("x2",), measured="acceleration",
                   values=values)  # fmt: skip
    est = hosid.estimate(rec, plain)
    assert est.model.sensor_noise == ("x1", "x2") and est.model.has("N[x1]")
    assert [m.component for m in est.ql.moments] == ["spectral matrix"]
    (check,) = [c for c in est.checks if c.name == "sensor_noise"]
    assert check.status == "pass" and "modelled" in check.message
    off = System(("x1", "x2"), ELEMENTS, driven=("x2",), measured="acceleration",
                 sensor_noise=False, values=values)  # fmt: skip
    est = hosid.estimate(rec, off)
    assert not est.model.has("N[x1]") and est.ql.moments[0].component == "identities"
    assert [c.status for c in est.checks if c.name == "sensor_noise"] == ["warn"]
    # walkers enough for the file's 6 parameters but not for the 8 the record called for
    with pytest.raises(HosidInputError, match=r"at least 18 \(the record added 2 param"):
        hosid.fit(rec, plain, n_walkers=14, progress=False)


def test_the_twin_study_runs(tmp_path):
    """``analyses/sensor_noise_study.py`` on one record writes its table."""
    import importlib
    import sys
    from pathlib import Path

    analyses = Path(__file__).resolve().parents[1] / "analyses"
    sys.path.insert(0, str(analyses))
    try:
        study = importlib.import_module("sensor_noise_study")
        got = study.main(["--records", "2", "--out", str(tmp_path)])
    finally:
        sys.path.remove(str(analyses))
        sys.modules.pop("sensor_noise_study", None)
    assert [r["quantity"] for r in got["rows"]][-4:] == ["f1", "f2", "zeta1", "zeta2"]
    assert all(np.isfinite(r["mean_z"]) for r in got["rows"])
    assert "| a2[x4-x5] |" in (tmp_path / "sensor_noise.md").read_text()


def test_a_fit_starts_from_the_maximum_with_dampers_at_least_zero():
    """An undamped upper element: Whittle's maximum of this 500 s record puts its damper
    below zero, outside eq (65); the fit's start is searched again with every damper at
    least 0, from the same state, and says so in the notes."""
    from hosid.inference.fit import _floored
    from hosid.inference.options import FitOptions

    values = {**VALUES, "a1[x1-x2]": 0.0}
    rec = simulate_chain(NOISY, values, duration=500.0, dt=DT, rng=np.random.default_rng(0))
    model = System(("x1", "x2"), ELEMENTS, driven=("x2",), measured="acceleration",
                   sensor_noise=True, excitation="white")  # fmt: skip
    est = hosid.estimate(rec, model)
    priors = est.model.default_priors(est.scales())
    assert est.theta[2] < 0 and not np.isfinite(priors.ln_prob(est.theta[None])[0])
    got = _floored(est, priors, FitOptions())
    assert got.state is est.state
    assert np.all(got.theta[[0, 2]] >= 0) and got.theta[2] < 0.05
    assert got.theta[3] == pytest.approx(15.0, rel=0.05)
    assert "every damper's coefficient at least 0" in got.notes[-1]
    assert _floored(est, priors, FitOptions(constrained=False)) is est
