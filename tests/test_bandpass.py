"""The band-pass force of a system (``excitation = "bandpass_excitation"``,
:mod:`hosid.model.bandpass`): its shape against the filter's frequency response, a single
oscillator's refusal, and a two-dof chain driven by it (the record chooses it)."""

import dataclasses

import numpy as np
import pytest

import hosid
from hosid.errors import HosidInputError
from hosid.model.bandpass import BandpassExcitation
from hosid.model.chain import simulate_chain
from hosid.model.system_file import system_from_dict
from test_system_excitation import DT, SHAPED

#: The two-dof chain of test_system_excitation (modes 2.4 and 5.9 rad/s) driven at its
#: top by a band-pass force peaked at 4 rad/s between them.
BANDPASS = dataclasses.replace(SHAPED, excitation="bandpass_excitation")


@pytest.mark.parametrize(("wf", "zf"), [(4.0, 0.3), (0.6, 0.05), (10.0, 20.0)])
def test_shape_is_the_band_pass_filters_squared_response(wf, zf):
    """L(w) = |H(iw)|^2 of H(s) = 2 zf wf s / (s^2 + 2 zf wf s + wf^2), evaluated as a
    rational function of the complex frequency (numpy's polynomials), to rounding: 1 at
    the peak, 0 at zero frequency."""
    w = np.geomspace(1e-3, 1e3, 400)
    s = 1j * w
    H = np.polyval([2 * zf * wf, 0.0], s) / np.polyval([1.0, 2 * zf * wf, wf**2], s)
    th = BANDPASS.vector().copy()
    th[BANDPASS.index("wf")], th[BANDPASS.index("zf")] = wf, zf
    got = BANDPASS.spectrum.shape(w, th)
    np.testing.assert_allclose(got, np.abs(H) ** 2, rtol=1e-12)
    assert BANDPASS.spectrum.shape(np.array([0.0, wf]), th) == pytest.approx([0.0, 1.0])
    assert BandpassExcitation().params == ("wf", "zf")


def test_the_file_takes_it_and_a_single_oscillator_refuses_it():
    data = {"dofs": ["x1"], "element": [{"between": ["ground", "x1"], "terms": ["linear"]}]}
    got = system_from_dict({**data, "excitation": "bandpass_excitation"})
    assert got.param_names[-2:] == ("wf", "zf")
    with pytest.raises(HosidInputError, match="bandpass_excitation is a system's force shape"):
        hosid.Model.from_spec("paper,bandpass_excitation")


def test_a_chain_under_a_band_pass_force():
    """One 2000 s record with the file silent on the shape: the record rejects the white
    force and chooses the band-pass shape over the low-pass filter; every parameter of the
    estimate within 4 of its Laplace sd of the truth."""
    rec = simulate_chain(BANDPASS, duration=2000.0, dt=DT, rng=np.random.default_rng(5))
    silent = dataclasses.replace(BANDPASS, excitation=None, values=())
    est = hosid.estimate(rec, silent)
    assert [t.name for t in est.model.excitation] == ["bandpass_excitation"]
    assert "rejects a white force" in est.notes[-1] and "bandpass_excitation" in est.notes[-1]
    z = (est.theta - BANDPASS.vector()) / np.sqrt(np.diag(est.cov))
    assert np.all(np.abs(z) < 4.0), dict(zip(est.model.param_names, z.round(2), strict=True))
