"""A system's forces with a shared spectral shape (``excitation = "narrowband_excitation"``):
the parameters and the file, the spectral matrix against its closed form, the simulated
shaped force's spectrum, and the estimate of a chain driven by a narrow-band force
(:mod:`hosid.model.system`, :mod:`hosid.components.chain_spectral_matrix`)."""

import dataclasses
import math

import numpy as np
import pytest

import hosid
from hosid.components.chain_spectral_matrix import (
    _hermitian_parts,
    band_periodogram,
    spectral_matrix,
    spectral_parts,
)
from hosid.errors import HosidInputError
from hosid.inference.system_estimate import estimate_system, system_components
from hosid.model.chain import simulate_chain
from hosid.model.system import System
from hosid.model.system_file import system_from_dict

DT = 0.05
ELEMENTS = [(("ground", "x1"), ("linear",)), (("x1", "x2"), ("linear",))]
#: The two-dof chain (modes 2.4 and 5.9 rad/s) driven at its top by a force peaked at
#: 4 rad/s between them, each channel with a small white noise.
VALUES = {
    "a1[ground-x1]": 0.3, "a2[ground-x1]": 20.0, "a1[x1-x2]": 0.2, "a2[x1-x2]": 10.0,
    "mass[x2]": 0.8, "S0[x2]": 1.0, "wf": 4.0, "zf": 0.3, "N[x1]": 0.01, "N[x2]": 0.01,
}  # fmt: skip
SHAPED = System(("x1", "x2"), ELEMENTS, driven=("x2",), measured="acceleration",
                sensor_noise=True, excitation="narrowband_excitation",
                values=VALUES)  # fmt: skip


def narrowband(w, wf, zf):
    """The shaping filter's L(w) (:class:`hosid.model.excitation.NarrowbandExcitation`)."""
    return wf**4 / ((wf**2 - w**2) ** 2 + (2 * zf * wf * w) ** 2)


def test_parameters_and_file():
    assert SHAPED.param_names[-5:] == ("S0[x2]", "wf", "zf", "N[x1]", "N[x2]")
    assert {SHAPED.index("wf"), SHAPED.index("zf")} <= set(SHAPED.log_params)
    assert SHAPED.describe()["excitation"] == ["narrowband_excitation"]
    assert not SHAPED.spectrum.white
    w = np.array([1.0, 4.0, 9.0])
    np.testing.assert_allclose(SHAPED.spectrum.shape(w, SHAPED.vector()), narrowband(w, 4, 0.3))
    data = {"dofs": ["x1"], "element": [{"between": ["ground", "x1"], "terms": ["linear"]}]}
    assert system_from_dict({**data, "excitation": "white"}).excitation == ()
    got = system_from_dict({**data, "excitation": "coloured_excitation"})
    assert got.param_names[-1] == "wc"
    for bad, said in (("band_limited_excitation", "'band_limited_excitation' is not"),
                      (["coloured_excitation", "narrowband_excitation"], "several shapes"),
                      (3, "must be 'white' or one of")):  # fmt: skip
        with pytest.raises(HosidInputError, match=said):
            system_from_dict({**data, "excitation": bad})


def test_spectral_matrix_is_the_oscillators_closed_form():
    """One element under the shaping filter: S = s2 w^4 S0 L(w) / ((k - m w^2)^2 + (c w)^2)
    + (1 - s2) L(2 pi / dt - w) S0 / m^2 + N, to rounding."""
    one = System(("x1",), [(("ground", "x1"), ("linear",))], measured="acceleration",
                 masses={"x1": 2.0}, sensor_noise=True,
                 excitation="narrowband_excitation")  # fmt: skip
    th = np.array([0.3, 9.0, 2.0, 3.0, 0.2, 0.01])  # a1, a2, S0, wf, zf, N
    w = np.linspace(0.1, 20.0, 300)
    s2 = np.sinc(w * DT / (2 * math.pi)) ** 2
    motion = w**4 * 2.0 * narrowband(w, 3.0, 0.2) / ((9.0 - 2.0 * w**2) ** 2 + (0.3 * w) ** 2)
    alias = (1 - s2) * narrowband(2 * math.pi / DT - w, 3.0, 0.2) * 2.0 / 4
    S = spectral_matrix(one, th, w, DT)[:, 0, 0]
    np.testing.assert_allclose(S.real, s2 * motion + alias + 0.01, rtol=1e-10)
    batch = spectral_matrix(one, np.stack([th, th]), w, DT)  # walkers broadcast
    np.testing.assert_allclose(batch[1], spectral_matrix(one, th, w, DT), rtol=1e-14)


@pytest.mark.parametrize("dt", [DT, None])
def test_spectral_parts_are_the_matrixs_hermitian_parts(dt):
    """The sampler's parts, built from the transfer's columns, are the whole matrix's
    (diagonal, sqrt 2 times the real and imaginary parts above it), for a batch of
    walkers of a shaped two-dof chain driven at both dofs with sensor noise: to rounding."""
    both = System(("x1", "x2"), ELEMENTS, driven=("x1", "x2"), measured="acceleration",
                  masses={"x1": 1.0}, sensor_noise=True,
                  excitation="narrowband_excitation")  # fmt: skip
    th = np.array([0.4, 30.0, 0.2, 18.0, 0.8, 1.5, 0.7, 6.0, 0.3, 0.02, 0.05])
    assert th.size == len(both.param_names)
    walkers = th * (1 + 0.05 * np.random.default_rng(3).standard_normal((4, th.size)))
    w = np.linspace(0.5, 30.0, 200)
    S = spectral_matrix(both, walkers, w, dt)
    assert S.shape == (4, 200, 2, 2)
    np.testing.assert_allclose(spectral_parts(both, walkers, w, dt), _hermitian_parts(S),
                               rtol=1e-12, atol=1e-14 * np.abs(S).max())  # fmt: skip


def test_simulated_shaped_force_has_the_model_spectrum():
    """Four 1000 s records: each channel's periodogram over the model's spectrum at the
    truth, bin by bin (mean 1 where the model holds, sd 1 a bin), averaged over bands of
    2 rad/s (about 1300 ratios, sd about 4 % with the taper's correlation) from below the
    first mode to twice the second: within 12 %."""
    ratios = []
    for seed in range(4):
        rec = simulate_chain(SHAPED, duration=1000.0, dt=DT, rng=np.random.default_rng(seed))
        P = band_periodogram(rec, 1.0, 13.0)
        S = spectral_matrix(SHAPED, SHAPED.vector(), P.omega, DT)
        ratios.append(np.einsum("kii->ki", P.matrix).real / np.einsum("kii->ki", S).real)
    ratio = np.mean(ratios, axis=0)
    bands = [ratio[(P.omega >= lo) & (P.omega < lo + 2)].mean(axis=0) for lo in range(1, 13, 2)]
    np.testing.assert_allclose(bands, 1.0, atol=0.12)


def test_estimate_of_a_chain_under_a_narrowband_force():
    """One 2000 s record: every parameter, the shape's included, within 4 of its Laplace
    sd of the truth; the white force's components are not used."""
    rec = simulate_chain(SHAPED, duration=2000.0, dt=DT, rng=np.random.default_rng(11))
    model = dataclasses.replace(SHAPED, values=())
    assert [c.name for c in system_components(system=model)] == ["spectral matrix"]
    est = estimate_system(rec, model)
    z = (est.theta - SHAPED.vector()) / np.sqrt(np.diag(est.cov))
    assert np.all(np.abs(z) < 4.0), dict(zip(model.param_names, z.round(2), strict=True))


def test_a_shaped_force_needs_the_spectral_matrix():
    rec = simulate_chain(SHAPED, duration=600.0, dt=DT, rng=np.random.default_rng(2))
    bare = dataclasses.replace(SHAPED, sensor_noise=False, values=())
    with pytest.raises(HosidInputError, match=r"shaped force .* every channel is an accel"):
        estimate_system(rec, bare)
    cubic = System(("x1", "x2"), [(("ground", "x1"), ("linear", "cubic_stiffness")),
                                  ELEMENTS[1]], driven=("x2",), measured="acceleration",
                   excitation="narrowband_excitation")  # fmt: skip
    with pytest.raises(HosidInputError, match=r"shaped force .* linear systems only"):
        estimate_system(rec, cubic, force=True)


def test_the_record_chooses_the_shape_when_the_file_is_silent():
    """A file silent on the shape: the narrow-band record rejects the white force (its
    deviance falls by far more than 13.8) and gets the shape; a white one (the same chain
    driven by white noise) keeps the white force; ``excitation = "white"`` is not asked."""
    silent = dataclasses.replace(SHAPED, excitation=None, values=())
    assert silent.excitation is None and "wf" not in silent.param_names
    rec = simulate_chain(SHAPED, duration=1000.0, dt=DT, rng=np.random.default_rng(3))
    est = hosid.estimate(rec, silent)
    assert [t.name for t in est.model.excitation] == ["narrowband_excitation"]
    assert "the record rejects a white force" in est.notes[-1]
    assert est.theta[est.model.index("wf")] == pytest.approx(4.0, rel=0.1)
    white = {k: v for k, v in VALUES.items() if k not in ("wf", "zf")}
    plain = dataclasses.replace(silent, excitation="white")
    rec = simulate_chain(plain, white, duration=1000.0, dt=DT, rng=np.random.default_rng(3))
    est = hosid.estimate(rec, silent)
    assert est.model.excitation == () and "white force kept" in est.notes[-1]
    assert not any("white force" in n for n in hosid.estimate(rec, plain).notes)
