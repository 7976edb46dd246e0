"""A measured excitation shape (``--excitation-shape``): the table, its second-order
form, the estimate's invariance to the table's scale, the result's round trip, and the
command line's errors.
"""

import json
import math

import numpy as np
import pytest

from hosid import cli
from hosid.errors import HosidInputError
from hosid.inference.estimate import estimate
from hosid.model import Model
from hosid.model.measured import MeasuredExcitation, rational_fit, read_shape
from hosid.model.simulate import simulate
from hosid.output.results import load, stored_model

WF, ZF = 7.0, 0.2
OMEGA = np.linspace(0.0, 60.0, 1200)


def filter_shape(omega, wf=WF, zf=ZF):
    return wf**4 / ((wf**2 - omega**2) ** 2 + (2 * zf * wf * omega) ** 2)


@pytest.fixture(scope="module")
def record():
    truth = {"a1": 0.5, "n1": 0.5, "a2": 25.0, "n2": 5.0, "S0": 100.0, "wf": WF, "zf": ZF}
    return simulate(truth, duration=400.0, dt=0.02, rng=np.random.default_rng(11))


def test_rational_fit_recovers_a_second_order_filter():
    # the table of an exact second-order filter times 3 (every 0.05 rad/s): its form to
    # 1e-4 (what the table's linear interpolation leaves)
    G, wf, zf = rational_fit(OMEGA, 3.0 * filter_shape(OMEGA))
    assert (G, wf, zf) == pytest.approx((3.0, WF, ZF), rel=1e-4)
    term = MeasuredExcitation.from_table(OMEGA, filter_shape(OMEGA))
    assert term.misfit(np.linspace(0.5, 30.0, 50)) < 1e-3
    # its operator whitens: |P(i w)|^2 times the table is 1
    p = term.operator()
    s = 1j * OMEGA
    np.testing.assert_allclose(abs(p[0] + p[1] * s + p[2] * s**2) ** 2 * term.table(OMEGA), 1.0,
                               rtol=1e-4)  # fmt: skip
    # the table, interpolated linearly inside its range
    mid = 0.5 * (OMEGA[10] + OMEGA[11])
    assert term.table(mid) == pytest.approx(0.5 * sum(filter_shape(OMEGA[10:12])))


def test_the_spectrum_is_the_table_times_the_level():
    term = MeasuredExcitation.from_table(OMEGA, filter_shape(OMEGA))
    model = Model.from_spec(["paper", term])
    assert model.param_names == ("a1", "n1", "a2", "n2", "S0")
    from hosid.model.excitation import Spectrum

    sp = Spectrum(model)
    theta = np.array([0.5, 0.5, 25.0, 5.0, 2.0])
    np.testing.assert_allclose(2.0 * sp.shape(OMEGA[1:], theta), 2.0 * filter_shape(OMEGA[1:]))
    assert sp.whitening and sp.order == 2 and sp.shape_indices == ()
    # a known shape leaves no excitation candidate but the non-shape effects
    assert "narrowband_excitation" not in model.candidates
    assert "impulsive_excitation" not in model.candidates


def test_estimate_does_not_depend_on_the_tables_scale(record):
    # S(w) = S0 l(w): a table ten times smaller gives the same drift and ten times S0
    def model(scale):
        return Model.from_spec(
            ["paper", MeasuredExcitation.from_table(OMEGA, scale * filter_shape(OMEGA))]
        )

    a, b = estimate(record, model(1.0)), estimate(record, model(0.1))
    np.testing.assert_allclose(b.theta[:4], a.theta[:4], rtol=1e-4)
    assert b.theta[4] == pytest.approx(10.0 * a.theta[4], rel=1e-4)
    assert any("second-order form" in n for n in a.notes)


@pytest.mark.parametrize(
    "text, message",
    [
        ("omega,lvl\n0,1\n1,1\n2,1\n3,1\n", "missing level"),
        ("omega,level\n0,1\n1,1\n2,1\n", "at least 4 rows"),
        ("omega,level\n0,1\n1,-1\n2,1\n3,1\n", ">= 0"),
        ("omega,level\n0,1\n1,1\n1,1\n3,1\n", "repeated"),
        ("omega,level\n0,1\n1,x\n2,1\n3,1\n", "numbers"),
        ("omega,level\n0,0\n1,0\n2,0\n3,1\n", "positive at 4"),
    ],
)
def test_bad_tables_get_one_clear_error(tmp_path, text, message):
    with pytest.raises(HosidInputError, match="--excitation-shape"):
        Model.from_spec("paper,measured_excitation")
    path = tmp_path / "shape.csv"
    path.write_text(text)
    with pytest.raises(HosidInputError, match=message):
        read_shape(path)


def test_cli_fit_with_a_shape_round_trips_and_rejects_a_short_table(tmp_path, record, capsys):
    rec = tmp_path / "rec.npz"
    np.savez(rec, t=np.arange(record.x.size) * record.dt, x=record.x)
    shape = tmp_path / "shape.csv"
    np.savetxt(shape, np.c_[OMEGA, filter_shape(OMEGA)], delimiter=",", header="omega,level",
               comments="")  # fmt: skip
    out = tmp_path / "fit"
    argv = ["fit", str(rec), "--excitation-shape", str(shape), "--walkers", "16", "--steps",
            "150", "--no-progress", "--out", str(out)]  # fmt: skip
    assert cli.main(argv) == 0
    tree = load(out / "posterior.nc")
    model = stored_model(tree)
    term = next(t for t in model.terms if isinstance(t, MeasuredExcitation))
    np.testing.assert_allclose(term.table(OMEGA), filter_shape(OMEGA))
    summary = json.loads((out / "summary.json").read_text())
    assert "measured_excitation" in summary["model"]
    assert (out / "force_spectrum.png").is_file()
    # a table that stops inside the record's band: one line, exit 2, no folder
    short = tmp_path / "short.csv"
    keep = OMEGA > 3.0
    np.savetxt(short, np.c_[OMEGA[keep], filter_shape(OMEGA[keep])], delimiter=",",
               header="omega,level", comments="")  # fmt: skip
    capsys.readouterr()
    assert cli.main([*argv[:3], str(short), "--out", str(tmp_path / "bad")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "covers 3.003-60 rad/s" in err
    assert not (tmp_path / "bad").exists()


@pytest.mark.slow
def test_known_shape_is_unbiased_over_records():
    # 8 records of the independent simulator (paper oscillator, filter at 7 / 0.2):
    # the mean estimate within 3 standard errors of the truth, the spread between records
    # over the mean Laplace sd within the 99 % band of sqrt(chi2_7 / 7), 0.38-1.70
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "analyses"))
    from independent_sim import simulate as independent
    from scipy.stats import chi2

    truth = {"a1": 0.5, "n1": 0.5, "a2": 25.0, "n2": 5.0, "S0": 100.0, "wf": WF, "zf": ZF}
    model = Model.from_spec(["paper", MeasuredExcitation.from_table(OMEGA, filter_shape(OMEGA))])
    est, se = [], []
    for seed in range(8):
        rec, _ = independent(truth, duration=2000.0, dt=0.02, rng=np.random.default_rng(seed))
        e = estimate(rec, model)
        est.append(e.theta)
        se.append(np.sqrt(np.diag(e.cov)))
    est, se = np.array(est), np.array(se)
    want = np.array([truth[p] for p in model.param_names])
    spread = est.std(axis=0, ddof=1)
    assert np.all(np.abs(est.mean(axis=0) - want) < 3 * spread / math.sqrt(8))
    lo, hi = np.sqrt(chi2.ppf([0.005, 0.995], 7) / 7)
    ratio = spread / se.mean(axis=0)
    assert np.all((ratio > lo) & (ratio < hi)), ratio


def test_a_model_with_a_shape_simulates_its_second_order_form():
    # the replicates diagnose draws: the filter's table simulates as the filter itself
    term = MeasuredExcitation.from_table(OMEGA, 2.0 * filter_shape(OMEGA))
    model = Model.from_spec(["paper", term])
    theta = [0.5, 0.5, 25.0, 5.0, 50.0]
    got = model.simulate(theta, duration=50.0, dt=0.02, rng=np.random.default_rng(1))
    want = simulate({"a1": 0.5, "n1": 0.5, "a2": 25.0, "n2": 5.0, "S0": 100.0, "wf": WF,
                     "zf": ZF}, duration=50.0, dt=0.02, rng=np.random.default_rng(1))  # fmt: skip
    np.testing.assert_allclose(got.x, want.x, rtol=1e-3, atol=1e-3 * want.x.std())
