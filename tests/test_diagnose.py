"""Tests of the discrepancy workflow (hosid.diagnose and ``hosid diagnose``).

Hidden-effect records: simulated with one effect the base model lacks, at a strength
the confusion study (analyses/diagnose_confusion.py) names in 5 of 5 records; and a
record with no missing effect.  Fewer replicates than the default keep this fast.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from hosid.cli import main
from hosid.diagnose import diagnose, write_report
from hosid.errors import HosidInputError
from hosid.records import write_record
from hosid.simulate import PAPER_PARAMS, simulate

PAPER = PAPER_PARAMS


def _record(params, seed, duration=2000.0):
    return simulate(params, duration=duration, dt=0.02, rng=np.random.default_rng(seed))


@pytest.fixture(scope="module")
def hidden_b2():
    rec = _record({**PAPER, "b2": 6.0}, 7)
    return diagnose(rec, "paper", rng=np.random.default_rng(0), replicates=12)


def test_hidden_quadratic_stiffness_is_named(hidden_b2):
    d = hidden_b2
    assert d.named_effect == "quadratic_stiffness"
    assert d.gap_after <= 0.5 * d.gap_before
    assert d.base.z >= 3.0
    # the final model's 90 % intervals hold the truth of the hidden parameter
    lo, hi = d.final.fit.interval(0.9)["b2"]
    assert lo <= 6.0 <= hi
    # the bispectral cost J3W of the inferred force sees the missing asymmetry
    assert d.base.spectral_costs["J3W"] > d.final.spectral_costs["J3W"] + 30.0


def test_no_missing_effect_names_none():
    rec = _record(PAPER, 8)
    d = diagnose(
        rec,
        "paper",
        rng=np.random.default_rng(1),
        replicates=12,
        candidates=["quadratic_stiffness", "excitation_mean", "coulomb_friction"],
    )
    assert d.named_effect is None
    assert d.gap_after == d.gap_before
    assert d.report()["final_model"] == d.report()["base"]


def test_report_files(hidden_b2, tmp_path):
    js, page = write_report(hidden_b2, tmp_path / "out")
    rep = json.loads(js.read_text())
    for key in ("named_effect", "gap_before", "gap_after", "candidates", "base", "final_model"):
        assert key in rep
    assert rep["named_effect"] == "quadratic_stiffness"
    assert "quadratic_stiffness" in rep["final_model"]
    assert {c["effect"] for c in rep["candidates"]} == set(hidden_b2.candidates)
    for c in rep["candidates"]:
        assert {"effect", "gap_after", "shrink", "p_value", "estimate"} <= set(c)
    text = page.read_text()
    assert text.count("data:image/png;base64,") == 2
    assert "Named effect: quadratic_stiffness" in text


def test_bad_arguments():
    rec = _record(PAPER, 2, duration=400.0)
    rng = np.random.default_rng(0)
    with pytest.raises(HosidInputError, match="not candidate effects"):
        diagnose(rec, "paper", rng=rng, candidates=["linear_stiffness"])
    with pytest.raises(HosidInputError, match="already in the base"):
        diagnose(rec, "paper", rng=rng, candidates=["cubic_stiffness"])
    with pytest.raises(HosidInputError, match="at least 8 replicates"):
        diagnose(rec, "paper", rng=rng, replicates=3)
    with pytest.raises(HosidInputError, match="unknown model term"):
        diagnose(rec, "papr", rng=rng)


def test_cli_diagnose(tmp_path, capsys):
    path = tmp_path / "rec.csv"
    write_record(_record({**PAPER, "m": 10.0}, 4, duration=1000.0), path)
    out = tmp_path / "diag"
    code = main(
        [
            "diagnose",
            str(path),
            "--model",
            "paper",
            "--candidates",
            "excitation_mean,coulomb_friction",
            "--replicates",
            "8",
            "--no-progress",
            "--out",
            str(out),
        ]
    )
    assert code == 0
    rep = json.loads((out / "report.json").read_text())
    assert rep["named_effect"] == "excitation_mean"
    assert "named effect: excitation_mean" in capsys.readouterr().out
    assert main(["diagnose", str(path), "--model", "nope", "--out", str(out)]) == 2
    assert "unknown model term" in capsys.readouterr().err
    assert main(["diagnose", str(path), "--shrink", "2", "--out", str(out)]) == 2


def test_failing_candidate_is_reported_not_fatal(monkeypatch):
    import hosid.diagnose as dg

    real = dg.check_model

    def flaky(record, model, **kw):
        if "coulomb_friction" in model.names:
            raise HosidInputError("posterior-predictive simulations keep diverging")
        return real(record, model, **kw)

    monkeypatch.setattr(dg, "check_model", flaky)
    rec = _record({**PAPER, "m": 10.0}, 5, duration=1000.0)
    d = dg.diagnose(
        rec,
        "paper",
        rng=np.random.default_rng(2),
        replicates=8,
        candidates=["coulomb_friction", "excitation_mean"],
    )
    assert d.named_effect == "excitation_mean"
    rep = d.report()
    failed = [c for c in rep["candidates"] if c["gap_after"] is None]
    assert [c["effect"] for c in failed] == ["coulomb_friction"]
    assert "diverging" in failed[0]["error"]


def test_diverging_base_is_a_gap_not_a_crash(monkeypatch, tmp_path):
    """A base model whose posterior draws escape (e.g. negative quadratic damping
    fitted to a friction record) gets an infinite gap; the candidates still run."""
    from hosid.terms import Model

    real = Model.simulate

    def escaping(self, theta, **kw):
        if "coulomb_friction" not in self.names and "excitation_mean" not in self.names:
            raise HosidInputError("record sample 7 is nan (9 non-finite samples in all)")
        return real(self, theta, **kw)

    monkeypatch.setattr(Model, "simulate", escaping)
    rec = _record({**PAPER, "m": 10.0}, 6, duration=1000.0)
    d = diagnose(
        rec,
        "paper",
        rng=np.random.default_rng(3),
        replicates=8,
        candidates=["coulomb_friction", "excitation_mean"],
    )
    assert d.base.diverged and d.gap_before == float("inf")
    assert d.named_effect == "excitation_mean"
    assert "diverge" in d.decision
    js, page = write_report(d, tmp_path)
    rep = json.loads(js.read_text())
    assert rep["gap_before"] is None and rep["base_diverged"] is True
    assert "diverged" in page.read_text()
