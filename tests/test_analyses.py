"""The analysis scripts run on tiny settings so that they never rot (STYLE.md 9)."""

import csv
import importlib.util
import math
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
    md = mod.run(
        1, cost="J4A", S0=100.0, duration=600.0, seed=3, out=tmp_path, n_steps=40, n_bootstrap=3
    )
    text = md.read_text()
    assert "| a1 |" in text and "90 % coverage" in text
    assert (tmp_path / "coverage_J4A.csv").is_file()


# ---------------------------------------------------------------- figure scripts (issue 5)
@pytest.fixture(scope="module")
def figs():
    """Import the figure scripts (they import ``common`` from analyses/)."""
    import sys

    if str(ANALYSES) not in sys.path:
        sys.path.insert(0, str(ANALYSES))
    return _load


def _rows(path):
    with open(path) as fh:
        return list(csv.DictReader(fh))


def _png(path):
    assert path.is_file() and path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_fig01_02_stiffness_tiny(figs, tmp_path):
    mod = figs("fig01_02_stiffness")
    mod.main(["--quick", "--levels", "100", "--out", str(tmp_path)])
    rows = _rows(tmp_path / "fig01_02_stiffness.csv")
    methods = [r["method"] for r in rows]
    assert len(rows) == 2 * len(mod.METHODS) + 1
    assert set(methods) == {*mod.METHODS, mod.POSTERIOR}
    mom = [float(r["a2"]) for r in rows if r["method"] == "moments"]
    assert all(abs(a / 25 - 1) < 0.25 for a in mom)
    (post,) = [r for r in rows if r["method"] == mod.POSTERIOR]
    assert float(post["a2_q05"]) < float(post["a2"]) < float(post["a2_q95"])
    _png(tmp_path / "fig01_a2.png")
    _png(tmp_path / "fig02_n2.png")
    rows = [
        {k: (float(v) if k not in ("method",) and v else v) for k, v in r.items()} for r in rows
    ]
    ax = mod.plot(rows, "n2", 5.0).axes[0]
    assert ax.get_xscale() == "log" and ax.get_ylabel() == "$n_2$"


def test_fig03_restoring_force_tiny(figs, tmp_path):
    mod = figs("fig03_restoring_force")
    mod.main(["--quick", "--panels", "J2:8", "J4A:8", "--out", str(tmp_path)])
    rows = _rows(tmp_path / "fig03_restoring_force.csv")
    assert len(rows) == 2 * mod.N_X
    assert {(r["cost"], float(r["omega_max"])) for r in rows} == {("J2", 8.0), ("J4A", 8.0)}
    for r in rows:
        x = float(r["x"])
        assert float(r["true"]) == pytest.approx(25 * x + 5 * x**3, rel=1e-4, abs=1e-3)
        assert float(r["post_q05"]) <= float(r["post_q50"]) <= float(r["post_q95"])
    # the posterior (moment-informed stiffness) follows the truth within 25 %
    assert max(float(r["max_err_post"]) for r in rows) < 0.25
    _png(tmp_path / "fig03_restoring_force.png")


def test_fig04_05_J2_sweep_tiny(figs, tmp_path):
    mod = figs("fig04_05_J2_sweep")
    mod.main(["--quick", "--levels", "100", "--out", str(tmp_path)])
    rows = _rows(tmp_path / "fig04_05_J2_sweep.csv")
    assert len(rows) == 2 * len(mod.METHODS) + 1
    prot = [r for r in rows if r["method"] == "J2, moment stiffness"]
    assert all(abs(float(r["S0"]) / 100 - 1) < 0.3 for r in prot)
    assert all(abs(float(r["a1eq"]) / float(r["a1eq_true"]) - 1) < 0.3 for r in prot)
    _png(tmp_path / "fig04_equivalent_damping.png")
    _png(tmp_path / "fig05_S0.png")


def test_fig06_damping_scatter_tiny(figs, tmp_path):
    mod = figs("fig06_damping_scatter")
    mod.main(["--quick", "--fits", "1", "--methods", "J2", "J4B line", "--out", str(tmp_path)])
    rows = _rows(tmp_path / "fig06_damping_scatter.csv")
    draws = {r["method"] for r in rows if r["method"].startswith("draws")}
    assert draws == {"draws J2", "draws J4A"}
    rows = [r for r in rows if r["method"] not in draws]
    assert sorted(r["method"] for r in rows) == sorted(
        ["J2", "J4B line"] * 2 + ["posterior J2", "posterior J4A"]
    )
    # every estimate keeps the physical sign (a1, n1 >= 0)
    assert all(float(r["a1"]) >= 0 and float(r["n1"]) >= 0 for r in rows)
    _png(tmp_path / "fig06_damping_scatter.png")


def test_fig07_08_contours_tiny(figs, tmp_path):
    mod = figs("fig07_08_contours")
    mod.main(["--quick", "--out", str(tmp_path)])
    rows = _rows(tmp_path / "fig07_08_contours.csv")
    grid = [r for r in rows if r["kind"] == "grid"]
    assert len(grid) == 4 * 21 * 21
    fits = [r for r in rows if r["kind"] == "fit"]
    assert {r["cost"] for r in fits} == {"J2", "J4A"}
    assert all(0.0 <= float(r["fraction_negative_a1eq"]) <= 1.0 for r in fits)
    # J2 (as printed) has its positive-damping minimum on its valley, a1eq near the truth
    (m,) = [r for r in rows if r["kind"] == "min_pos" and r["cost"] == "J2"]
    (t,) = [r for r in rows if r["kind"] == "truth"]
    c = (8 / math.pi) ** 0.5 * float(t["sigma_v"])
    assert float(m["a1"]) + c * float(m["n1"]) == pytest.approx(float(t["a1eq"]), rel=0.25)
    png = tmp_path / "fig07_08_contours.png"
    png.unlink()
    mod.main(["--replot", "--out", str(tmp_path)])  # the figure again, from the CSV alone
    _png(png)


def test_beyond_coverage_tiny(figs, tmp_path):
    mod = figs("beyond_coverage")
    mod.main(["--quick", "--costs", "J2", "--out", str(tmp_path)])
    rows = _rows(tmp_path / "beyond_coverage.csv")
    assert len(rows) == 6 * 9
    assert {r["param"] for r in rows} == {"a1", "n1", "a2", "n2", "S0", "a1eq"}
    assert all(int(r["covered"]) <= int(r["records"]) == 2 for r in rows)
    _png(tmp_path / "beyond_coverage.png")


def test_beyond_record_length_tiny(figs, tmp_path):
    mod = figs("beyond_record_length")
    mod.main(["--quick", "--fits", "1", "--out", str(tmp_path)])
    rows = _rows(tmp_path / "beyond_record_length.csv")
    assert len(rows) == 2 * (2 * 3 + 1)  # lengths x (records x methods + fits)
    assert {float(r["duration"]) for r in rows} == {300.0, 400.0}
    _png(tmp_path / "beyond_record_length.png")


def test_beyond_peer_drift_tiny(figs, tmp_path):
    mod = figs("beyond_peer_drift")
    mod.main(["--quick", "--methods", "moments", "--out", str(tmp_path)])
    rows = _rows(tmp_path / "beyond_peer_drift.csv")
    assert [r["method"] for r in rows] == ["moments", *mod.PEER] * 2
    # with the true velocity, drift regression recovers the stiffness and the level
    oracle = [r for r in rows if r["method"] == mod.PEER[1]]
    assert all(abs(float(r["a2"]) / 25 - 1) < 0.15 for r in oracle)
    assert all(abs(float(r["S0"]) / 100 - 1) < 0.2 for r in oracle)
    _png(tmp_path / "beyond_peer_drift.png")


def test_run_all_quick_one_script(figs, tmp_path):
    mod = figs("run_all")
    assert mod.main(["--quick", "--only", "fig07_08_contours", "--out", str(tmp_path)]) == 0
    assert "fig07_08_contours\tok" in (tmp_path / "run_all.log").read_text()
    _png(tmp_path / "fig07_08_contours.png")


def test_diagnose_workflow_quick(tmp_path):
    mod = _load("diagnose_workflow")
    assert mod.main(["--quick", "--b2", "8", "--out", str(tmp_path)]) == 0
    out = tmp_path / "diagnose_workflow"
    assert (out / "workflow_force.png").stat().st_size > 0
    assert (out / "diagnose" / "report.html").stat().st_size > 0
    with open(out / "workflow.csv") as fh:
        rows = list(csv.DictReader(fh))
    assert rows[0]["model"] == "base (paper)"
    assert len(rows) == 6  # base and the five candidates the paper model lacks


def test_diagnose_confusion_quick(tmp_path):
    mod = _load("diagnose_confusion")
    code = mod.main(
        [
            "--quick",
            "--records",
            "1",
            "--jobs",
            "1",
            "--only",
            "none (paper)",
            "--out",
            str(tmp_path),
        ]
    )
    assert code == 0
    with open(tmp_path / "diagnose_confusion" / "confusion.csv") as fh:
        rows = list(csv.DictReader(fh))
    assert len(rows) == 1 and rows[0]["hidden"] == "none"
    assert float(rows[0]["gap_before"]) > 0
    assert "none (paper)" in (tmp_path / "diagnose_confusion" / "confusion.md").read_text()


def test_modelfit_coverage_quick(tmp_path):
    mod = _load("modelfit_coverage")
    assert mod.main(["--quick", "--out", str(tmp_path)]) == 0
    with open(tmp_path / "modelfit_coverage" / "modelfit_coverage.csv") as fh:
        rows = list(csv.DictReader(fh))
    assert {r["model"] for r in rows} == {"paper", "linear"}
    assert all(0.0 <= float(r["cover90"]) <= 1.0 for r in rows)
