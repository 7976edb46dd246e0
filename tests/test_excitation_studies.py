"""The excitation studies' scripts in ``analyses/``: the coincident resonances' study on
two short records, and the kept tables of the excitation study.
"""

import importlib
from pathlib import Path


def test_coincident_resonances_study_tiny(tmp_path):
    """``analyses/coincident_resonances.py`` on 2 short records (its numbers: 24 records,
    ``results/coincident_resonances.md``): a z-score per parameter, the symmetric
    functions of the two squared frequencies beside the pair, the table written.
    """
    import sys

    analyses = Path(__file__).resolve().parents[1] / "analyses"
    sys.path.insert(0, str(analyses))
    try:
        cr = importlib.import_module("coincident_resonances")
        out = tmp_path / "cr.md"
        cr.main(["--records", "2", "--duration", "2000", "--workers", "1", "--out", str(out),
                 "--variants", "default", "simulated_weight"])  # fmt: skip
    finally:
        sys.path.remove(str(analyses))
        for name in ("coincident_resonances", "excitation_study", "independent_sim"):
            sys.modules.pop(name, None)
    text = out.read_text()
    for row in ("| a1 |", "| wf |", "| zf |", "| s = a2 + wf^2 |", "| p = a2 wf^2 |"):
        assert row in text
    cells = [
        c.strip() for line in text.splitlines() if line.startswith("| ") for c in line.split("|")
    ]
    assert not any(c.lstrip("+-") == "nan" for c in cells)
    assert text.count("The equations' J (k = 14, 7 parameters)") == 2  # one per variant


def test_excitation_study_keeps_the_rows_of_cases_not_rerun_in_their_places(tmp_path):
    """A rerun of some cases replaces their rows where they stand: the kept table of
    ``analyses/excitation_study.py`` keeps its order, and new records come last.
    """
    import csv
    import sys

    analyses = Path(__file__).resolve().parents[1] / "analyses"
    sys.path.insert(0, str(analyses))
    try:
        es = importlib.import_module("excitation_study")
    finally:
        sys.path.remove(str(analyses))
        for name in ("excitation_study", "independent_sim"):
            sys.modules.pop(name, None)

    def table(path, rows):
        path.parent.mkdir(parents=True, exist_ok=True)
        with path.open("w", newline="") as fh:
            w = csv.DictWriter(fh, fieldnames=["record", "a2_mean"], lineterminator="\n")
            w.writeheader()
            w.writerows({"record": r, "a2_mean": v} for r, v in rows)

    out, work = tmp_path / "out", tmp_path / "work"
    table(out / "narrowband.csv", [("a-0", "1"), ("b-0", "2"), ("c-0", "3")])
    table(work / "narrowband" / "results.csv", [("b-0", "20"), ("d-0", "40")])
    kept = es.keep_tables({"narrowband": work / "narrowband" / "results.csv"}, work, out)
    with kept["narrowband"].open(newline="") as fh:
        rows = [(r["record"], r["a2_mean"]) for r in csv.DictReader(fh)]
    assert rows == [("a-0", "1"), ("b-0", "20"), ("c-0", "3"), ("d-0", "40")]
