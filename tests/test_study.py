"""The efficiency study's scripts (analyses/) on tiny settings, so that they never rot."""

import csv
import importlib
import math
import sys
from pathlib import Path

import numpy as np
import pytest

ANALYSES = Path(__file__).resolve().parents[1] / "analyses"
SCRIPTS = (
    "regimes",
    "independent_sim",
    "crb",
    "efficiency_summary",
    "efficiency_study",
    "record_checks",
)


@pytest.fixture(scope="module")
def study():
    """The study modules, imported with ``analyses/`` on the path (as the scripts run)."""
    sys.path.insert(0, str(ANALYSES))
    try:
        yield {name: importlib.import_module(name) for name in SCRIPTS}
    finally:
        sys.path.remove(str(ANALYSES))
        for name in SCRIPTS:
            sys.modules.pop(name, None)


def test_independent_simulator_is_stationary_and_seeded(study):
    sim = study["independent_sim"].simulate
    regime = study["regimes"].BY_NAME["paper_S100"]
    a, va = sim(regime.params, duration=500.0, dt=0.02, rng=np.random.default_rng(3))
    b, _ = sim(regime.params, duration=500.0, dt=0.02, rng=np.random.default_rng(3))
    assert a.x.size == 25000 and va.size == 25000
    np.testing.assert_array_equal(a.x, b.x)
    d = study["regimes"].describe(regime, a.x, va)
    # energy balance a1 E[v^2] + n1 E|v|^3 = pi S0 holds within sampling error
    assert abs(d["balance"] - 1.0) < 0.05
    with pytest.raises(TypeError):
        sim(regime.params, duration=10.0, dt=0.02, rng=3)


def test_crb_and_study_tiny(study, tmp_path, capsys):
    crb, es = study["crb"], study["efficiency_study"]
    rows = crb.main(["--regimes", "short", "--sim-duration", "2000", "--out", str(tmp_path)])
    assert set(rows) == {"short"}
    assert all(math.isfinite(rows["short"][f"sd_{p}"]) for p in ("a1", "n1", "a2", "n2", "a1eq"))
    assert "| short |" in (tmp_path / "crb.md").read_text()

    argv = ["--regimes", "short", "--records", "2", "--n-steps", "200", "--out", str(tmp_path)]
    argv += ["--work", str(tmp_path / "batch"), "--workers", "1", "--no-progress"]
    summary = es.main(argv)
    path = tmp_path / "efficiency_default.csv"  # the batch's results.csv, one row a record
    with path.open() as fh:
        table = list(csv.DictReader(fh))
    assert [(r["design"], r["seed_index"], r["status"]) for r in table] == [
        ("short", "0", "ok"),
        ("short", "1", "ok"),
    ]
    params = ("a1", "n1", "a2", "n2", "S0", "a1eq")
    for r in table:
        for p in params:
            for k in ("mean", "sd", "q05", "q25", "q50", "q75", "q95", "r_hat", "ess_bulk"):
                assert math.isfinite(float(r[f"{p}_{k}"])), (p, k)
            assert float(r[f"{p}_q05"]) <= float(r[f"{p}_q50"]) <= float(r[f"{p}_q95"])
            assert math.isfinite(float(r[f"true_{p}"]))
        # a1eq truth: eq (65) at the simulated velocity's sd
        assert float(r["true_a1eq"]) == pytest.approx(
            0.5 + 0.5 * math.sqrt(8 / math.pi) * float(r["sigma_v"])
        )

    stats = summary["regimes"]["short"]
    for p in ("a1", "n1", "a2", "n2", "a1eq"):
        assert stats[p]["n"] == 2
        assert math.isfinite(stats[p]["eff"]) and stats[p]["eff"] > 0
        assert math.isfinite(stats[p]["bias_crb"])
    assert 0 <= summary["pooled"]["c90"] <= 1 and summary["pooled"]["n"] == 10
    assert math.isfinite(summary["averages"]["S0"]["rel_bias"])
    assert "## Efficiency" in (tmp_path / "efficiency_default.md").read_text()
    assert (tmp_path / "efficiency_default.png").stat().st_size > 0

    # resumable: a second run fits nothing new; --summary alone rewrites the report
    capsys.readouterr()
    es.main(argv)
    assert "0 fits run, 2 done before" in capsys.readouterr().out
    with path.open() as fh:
        assert len(list(csv.DictReader(fh))) == len(table)
    (tmp_path / "efficiency_default.md").unlink()
    es.main(["--summary", "--out", str(tmp_path)])
    assert (tmp_path / "efficiency_default.md").is_file()


def test_seeds_are_keyed_by_regime_and_record(study, tmp_path):
    """Record k of the regime with key r: SeedSequence(seed).spawn(r + 1)[r].spawn(k + 1)[k],
    split into the simulation's and the fit's streams (the records of the study before
    it ran through hosid batch).
    """
    from hosid.batch import design_tasks, read_design

    es, regimes = study["efficiency_study"], study["regimes"]
    short, paper = regimes.BY_NAME["short"], regimes.BY_NAME["paper_S100"]
    design = es.write_design([paper, short], tmp_path / "design.csv", records=3)
    tasks = design_tasks(read_design(design), analysis="fit", options={}, seed=1)
    assert [t.label for t in tasks] == [f"{r.name}-{k}" for r in (paper, short) for k in range(3)]
    for t in tasks:
        r = regimes.BY_NAME[t.point.name]
        old = np.random.SeedSequence(1).spawn(r.key + 1)[r.key].spawn(t.point.index + 1)
        np.testing.assert_array_equal(
            t.seed_sequence().generate_state(4), old[t.point.index].generate_state(4)
        )
    assert t.point.ref == f"{ANALYSES / 'independent_sim.py'}:simulate"
    with pytest.raises(ValueError, match="unknown cost"):
        es.run_study([short], records=1, cost="J9", work=tmp_path / "unused")


def test_record_checks_study_tiny(study, tmp_path):
    kinds = ["short", "white noise", "quantised to sd/10"]
    assert (
        study["record_checks"].main(["--records", "1", "--kinds", *kinds, "--out", str(tmp_path)])
        == 0
    )
    with open(tmp_path / "record_checks.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert {r["kind"] for r in rows} == set(kinds) and len(rows) == 6  # two seed sets
    verdict = {(r["set"], r["kind"]): r for r in rows}
    assert verdict[("held", "white noise")]["oscillator"] == "fail"
    assert verdict[("held", "short")]["oscillator"] == "pass"
    assert verdict[("tune", "quantised to sd/10")]["quantisation"] == "warn"
    assert "Held-out good records: 0 of 1 rejected" in (tmp_path / "record_checks.md").read_text()
