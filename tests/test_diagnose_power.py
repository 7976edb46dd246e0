"""The power study of ``diagnose`` (analyses/diagnose_power.py) on tiny settings: one
clean record and one with friction, 300 s each, resumed, summarized; the clean record
again through ``hosid batch`` (the same row)."""

import json
import sys
from pathlib import Path

import numpy as np
import pytest

from hosid.batch import read_results

ANALYSES = Path(__file__).resolve().parents[1] / "analyses"


@pytest.fixture(scope="module")
def power():
    sys.path.insert(0, str(ANALYSES))
    try:
        import diagnose_power

        yield diagnose_power
    finally:
        sys.path.remove(str(ANALYSES))


def test_design_and_truth(power):
    cells = {c["cell"]: c for c in power.design()}
    assert cells["none:0@paper_S100/paper"]["records"] == 20
    assert cells["coulomb_friction:5@paper_S100/paper"]["records"] == 10
    assert cells["coulomb_friction:1@paper_S100/paper"]["records"] == 5
    assert "quadratic_damping:3@paper_S100/linear" in cells
    two = cells["quadratic_stiffness+coulomb_friction:5@ship_roll/paper"]
    keys = power.bound_keys(two)  # each effect's own bound and its bound given the other
    assert [k[2] for k in keys] == [
        "quadratic_stiffness", "coulomb_friction",
        "quadratic_stiffness given coulomb_friction=5",
        "coulomb_friction given quadratic_stiffness=5",
    ]  # fmt: skip
    bounds = dict(zip(keys, (0.01, 0.001, 0.02, 0.002), strict=True))
    bounds[("paper_S100", "paper", "coloured_excitation")] = 4e-6
    bounds[("paper_S100", "paper", "measurement_noise")] = 1e-6
    t = power.truth(two, bounds)  # two effects: each at 5 times its bound given the other
    assert t["b2"] == pytest.approx(0.1) and t["mu"] == pytest.approx(0.01)
    wc = power.truth(cells["coloured_excitation:10@paper_S100/paper"], bounds)["wc"]
    assert wc == pytest.approx(1 / np.sqrt(10 * 4e-6))
    assert cells["measurement_noise:5@paper_S1000/paper"]["records"] == 10
    assert "quadratic_damping:1@paper_S100/linear" in cells
    noise = power.truth(cells["measurement_noise:3@paper_S100/paper"], bounds)["noise_sd"]
    assert noise == pytest.approx(np.sqrt(3e-6))
    linear = power.truth(cells["cubic_stiffness:5@paper_S100/linear"], {
        ("paper_S100", "linear", "cubic_stiffness"): 0.02})  # fmt: skip
    assert linear["n2"] == pytest.approx(0.1) and linear["n1"] == 0.0
    # a1 = a1eq of the paper oscillator at the power balance: a1eq s^2 = pi S0 with
    # a1eq = a1 + n1 sqrt(8/pi) s
    s = np.sqrt(np.pi * 100.0 / linear["a1"])
    assert linear["a1"] == pytest.approx(0.5 + 0.5 * np.sqrt(8 / np.pi) * s, rel=1e-9)


CELLS = ["none:0@paper_S100/paper", "coulomb_friction:5@paper_S100/paper"]
TINY = ["--records", "1", "--duration", "300", "--replicates", "19"]


@pytest.fixture(scope="module")
def tiny(power, tmp_path_factory):
    """The single-process run of the two cells (one record each)."""
    out = tmp_path_factory.mktemp("power")
    assert power.main(["--cells", *CELLS, *TINY, "--out", str(out)]) == 0
    return out


@pytest.mark.slow  # a diagnose of 7 candidates on two records: 1.5 min of the suite
def test_tiny_run_resumes_and_summarizes(power, tiny):
    cells, args, tmp_path = CELLS, ["--cells", *CELLS, *TINY], tiny
    rows = sorted(power.read_csv(tmp_path / "power.csv"), key=lambda r: r["hidden"] != "none")
    assert [r["cell"] for r in rows] == cells and all(r["error"] == "" for r in rows)
    bounds = json.loads((tmp_path / "bounds.json").read_text())
    assert bounds["paper_S100|paper|coulomb_friction"] == pytest.approx(1.37, rel=0.05)
    assert json.loads(rows[1]["truth"])["mu"] == pytest.approx(5 * 1.37, rel=0.05)
    assert set(json.loads(rows[0]["evidence"])) == {
        "quadratic_stiffness", "coulomb_friction", "excitation_mean", "coloured_excitation",
        "narrowband_excitation", "impulsive_excitation", "measurement_noise",
    }  # fmt: skip
    # resuming skips what is done
    assert power.main([*args, "--out", str(tmp_path)]) == 0
    assert len(power.read_csv(tmp_path / "power.csv")) == 2
    text = (tmp_path / "power.md").read_text()
    assert "## False alarms on clean records" in text and "| paper_S100 | paper | 1 |" in text
    assert (tmp_path / "power.png").is_file()


@pytest.mark.slow
def test_batch_run_gives_the_same_rows(power, tiny, tmp_path):
    """``--batch``: the record simulated and diagnosed as a task of ``hosid batch
    simulate-study`` (the cell's own streams) gives the single-process row.
    """
    args = ["--cells", CELLS[0], *TINY, "--batch", "--workers", "1", "--out", str(tmp_path)]
    assert power.main(args) == 0
    design = json.loads((tmp_path / "batch" / "design_paper.json").read_text())
    assert [(d["name"], d["seeds"]) for d in design] == [(CELLS[0], 1)]
    (row,) = power.read_csv(tmp_path / "power.csv")
    (ref,) = [r for r in power.read_csv(tiny / "power.csv") if r["cell"] == CELLS[0]]
    for key in ("named", "gaps", "evidence", "truth", "rounds_calibrated", "error"):
        assert row[key] == ref[key], key
    (task,) = read_results(tmp_path / "batch" / "paper" / "results.csv")
    assert task["status"] == "ok" and task["a2_q05"] < task["a2_mean"] < task["a2_q95"]
