"""The analysis scripts run on tiny settings so that they never rot (STYLE.md 9)."""

import csv
import importlib.util
from pathlib import Path

import pytest

ANALYSES = Path(__file__).resolve().parents[1] / "analyses"


def _load(name):
    spec = importlib.util.spec_from_file_location(name, ANALYSES / f"{name}.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_accuracy_table_tiny(tmp_path):
    mod = _load("accuracy_table")
    mod.main(
        [
            "--records",
            "2",
            "--levels",
            "100",
            "--duration",
            "400",
            "--windows",
            "hann",
            "--methods",
            "moments",
            "paper",
            "--out",
            str(tmp_path),
        ]
    )
    with open(tmp_path / "accuracy.csv") as fh:
        rows = list(csv.DictReader(fh))
    assert len(rows) == 2 * 2  # records x methods
    assert {r["method"] for r in rows} == {"moments", "paper"}
    table = (tmp_path / "accuracy.md").read_text()
    assert "| 100 | hann | paper | a1eq |" in table
    # the paper protocol estimates every parameter
    paper = [r for r in rows if r["method"] == "paper"]
    assert all(float(r["S0"]) > 0 for r in paper)


@pytest.mark.slow
def test_accuracy_study_paper_targets(tmp_path):
    """Replicated study at S0 = 100 (10 records): median stiffness and S0 errors."""
    mod = _load("accuracy_table")
    mod.main(
        [
            "--records",
            "10",
            "--levels",
            "100",
            "--windows",
            "hann",
            "--methods",
            "paper",
            "--out",
            str(tmp_path),
        ]
    )
    with open(tmp_path / "accuracy.csv") as fh:
        rows = list(csv.DictReader(fh))
    import numpy as np

    def med_rel(p):
        return np.median([abs(float(r[p]) / float(r[p + "_true"]) - 1) for r in rows])

    assert med_rel("a2") < 0.03
    assert med_rel("n2") < 0.10
    assert med_rel("S0") < 0.10
    assert med_rel("a1eq") < 0.10


@pytest.mark.slow
def test_coverage_study_runs_on_tiny_settings(tmp_path):
    import importlib.util

    spec = importlib.util.spec_from_file_location(
        "coverage_study", Path(__file__).parents[1] / "analyses" / "coverage_study.py"
    )
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    md = mod.run(1, cost="J4A", S0=100.0, duration=600.0, seed=3, out=tmp_path, n_steps=40,
                 n_bootstrap=3)
    text = md.read_text()
    assert "| a1 |" in text and "90 % coverage" in text
    assert (tmp_path / "coverage_J4A.csv").is_file()
