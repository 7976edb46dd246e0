"""The five-storey building of ``analyses/building.py``: its input-output reference, SSI and
hosid's fits on the Unison Tower record.

The record is not part of the project: the tests read ``$HOSID_BUILDING`` (default
``../shared/data/unison-tower/wn_01.dat`` next to the project) and skip, saying why, when
it is absent; the SSI and the written results need koma-python (optional).
"""

import csv
import importlib
import os
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
FILE = Path(
    os.environ.get(
        "HOSID_BUILDING", str(ROOT.parent / "shared" / "data" / "unison-tower" / "wn_01.dat")
    )
)
pytestmark = pytest.mark.skipif(
    not FILE.is_file(),
    reason=f"the building record {FILE} is absent (set HOSID_BUILDING to wn_01.dat)",
)


@pytest.fixture(scope="module")
def analysis():
    """``analyses/building.py``, imported as the script runs."""
    sys.path.insert(0, str(ROOT / "analyses"))
    try:
        yield importlib.import_module("building")
    finally:
        sys.path.remove(str(ROOT / "analyses"))
        sys.modules.pop("building", None)


@pytest.fixture(scope="module")
def ref(analysis):
    return analysis.reference(*analysis.load(FILE))


@pytest.fixture(scope="module")
def run(analysis, tmp_path_factory):
    """The quick path of the script, its results in a temporary folder."""
    pytest.importorskip("koma.oma", reason="koma-python is optional (pip install --no-deps)")
    out = tmp_path_factory.mktemp("building")
    return analysis.main(["--data", str(FILE), "--quick", "--out", str(out)]), out


def test_reference_finds_the_two_bending_modes(ref):
    (m1, m2) = ref
    assert 0.4 < m1["f"] < 0.6 and 1.5 < m2["f"] < 1.9
    for m in ref:
        assert 0.001 < m["zeta"] < 0.10 and 0.001 < m["frf"]["zeta"] < 0.10
        assert 0 < m["f_err"] < 0.01 * m["f"] and 0 < m["zeta_err"] < 0.3 * m["zeta"]
        assert m["coherence"] > 0.5  # the force explains most of the floors' motion there
        assert np.max(m["shape"]) == pytest.approx(1.0)
        assert abs(m["frf"]["f"] / m["f"] - 1) < 0.01  # the FRF fit agrees on f
    assert np.all(m1["shape"] > 0) and np.all(np.diff(m1["shape"]) > 0)  # a first bending mode
    assert np.any(m2["shape"] < 0) and np.any(m2["shape"] > 0)  # a node: the second
    # the time-domain fit recovers a simulated 2 % mode driven by the measured force
    assert m1["sim"][0] == pytest.approx(0.02, rel=0.1)


def test_quick_run_writes_the_three_methods(run):
    res, out = run
    ref, ssi = res["reference"], res["ssi"]
    for r, s in zip(ref, ssi, strict=True):  # SSI finds both modes with their shapes
        assert s is not None and abs(s["f"] / r["f"] - 1) < 0.03
    with (out / "building.csv").open() as fh:
        rows = list(csv.DictReader(fh))
    methods = {r["method"] for r in rows}
    assert {"reference (I/O, time domain)", "FRF fit (H1)", "SSI-cov"} <= methods
    assert float(next(r["mac"] for r in rows if r["method"] == "SSI-cov")) > 0.9
    md = (out / "building.md").read_text()
    for name in res["hosid"]:  # every hosid variant tried says how it went
        assert f"| {name['variant']} |" in md
        assert "error" in name or "hansen" in name
    assert any(r["method"].startswith("hosid") for r in rows) == any(
        "matched" in f for f in res["hosid"]
    )
    clean, noisy, modelled = res["control"][1:4]  # as simulated, with the sensors' noise
    assert clean.startswith("estimated modes [0.52")  # its first mode, 0.528 Hz, recovered
    assert noisy.startswith(("estimated modes", "the estimate fails"))
    assert modelled.startswith("estimated modes [0.52")  # the noise modelled: recovered
    white, shaped = res["control"][5:]  # driven by a narrow-band force, with that noise
    assert white.startswith(("estimated modes", "the estimate fails"))
    assert shaped.startswith("estimated modes [0.52") and "wf " in shaped  # recovered
    assert (out / "building.png").stat().st_size > 0
    assert (out / "work" / "floors.npz").is_file()
