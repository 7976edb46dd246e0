"""The Silverbox benchmark file: the loader, the input-output reference of
``analyses/silverbox.py`` and hosid's output-only estimate of the circuit.

The file is not part of the project: the tests read ``$HOSID_SILVERBOX`` (default
``../shared/data/silverbox/Schroeder80mV.mat`` next to the project) and skip, saying
why, when it is absent.
"""

import importlib
import math
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from hosid.datasets import SILVERBOX_FS, SILVERBOX_PERIOD, load_silverbox
from hosid.errors import HosidInputError
from hosid.inference import estimate

ROOT = Path(__file__).resolve().parents[1]
FILE = Path(
    os.environ.get(
        "HOSID_SILVERBOX", str(ROOT.parent / "shared" / "data" / "silverbox" / "Schroeder80mV.mat")
    )
)
pytestmark = pytest.mark.skipif(
    not FILE.is_file(),
    reason=f"the Silverbox file {FILE} is absent (set HOSID_SILVERBOX to Schroeder80mV.mat)",
)


@pytest.fixture(scope="module")
def sb():
    return load_silverbox(FILE)


@pytest.fixture(scope="module")
def analysis():
    """``analyses/silverbox.py``, imported as the script runs."""
    sys.path.insert(0, str(ROOT / "analyses"))
    try:
        yield importlib.import_module("silverbox")
    finally:
        sys.path.remove(str(ROOT / "analyses"))
        sys.modules.pop("silverbox", None)


@pytest.fixture(scope="module")
def ref(sb, analysis):
    return analysis.reference(sb)


def test_loader_finds_the_ten_steady_state_periods(sb):
    rec = sb.record
    assert rec.n_segments == 10 and rec.n == 10 * SILVERBOX_PERIOD
    assert rec.dt == 1.0 / SILVERBOX_FS == 2**14 / 1e7
    # the README's layout: the ten random-phase odd multisines lie in [21867, 108783)
    assert sb.starts[0] >= 21867 and sb.starts[-1] + SILVERBOX_PERIOD <= 108783
    half = SILVERBOX_PERIOD // 2
    for u in sb.inputs:  # odd multisines: u[n + P/2] = -u[n] around the input's offset
        d = u[:half] + u[half:] - 2 * np.mean(u)
        # measured: rms 1.6-1.7 % and at most 6 % of the input's sd (measurement noise)
        assert np.std(d) < 0.025 * np.std(u) and np.max(np.abs(d)) < 0.1 * np.std(u)


def test_loader_reads_the_official_csv_and_refuses_other_files(sb, tmp_path):
    from scipy.io import loadmat

    data = loadmat(FILE)
    v1, v2 = data["V1"].ravel(), data["V2"].ravel()
    # the zip's Schroeder80mV.csv: header Ovld2,Ovld1,V1,V2, the flags blank after row 1
    rows = [f"0,0,{float(v1[0])!r},{float(v2[0])!r}"]
    rows += [f",,{float(a)!r},{float(b)!r}" for a, b in zip(v1[1:], v2[1:], strict=True)]
    path = tmp_path / "Schroeder80mV.csv"
    path.write_text("Ovld2,Ovld1,V1,V2\n" + "\n".join(rows) + "\n")
    again = load_silverbox(path)
    assert again.starts == sb.starts
    np.testing.assert_array_equal(again.record.x, sb.record.x)
    (tmp_path / "other.csv").write_text("a,b\n1,2\n")
    with pytest.raises(HosidInputError, match="no columns V1 and V2"):
        load_silverbox(tmp_path / "other.csv")
    with pytest.raises(HosidInputError, match="no such file"):
        load_silverbox(tmp_path / "missing.mat")


def test_reference_is_the_circuit_the_readme_describes(ref):
    # README: resonance near 69-70 Hz, damping ratio about 5 %, band flat up to 200 Hz
    assert 68.0 < math.sqrt(ref["k1"]) / (2 * math.pi) < 71.0
    assert 0.04 < ref["c"] / (2 * math.sqrt(ref["k1"])) < 0.06
    assert ref["k3"] > 0  # hardening
    assert ref["edge_rad_s"] == pytest.approx(2 * math.pi * 199.9, abs=2 * math.pi * 0.08)
    # the equation explains the acceleration to 1.7 % rms (the rest: harmonics, noise)
    assert ref["residual_rms"] < 0.03 * ref["acceleration_rms"]


def test_the_default_estimate_describes_the_circuit(sb, ref):
    est = estimate(sb.record)  # the engine of `hosid fit REC`, without the sampling
    assert "band_limited_excitation" in est.model.names
    lo, hi = est.state.spectrum.edge
    assert lo <= ref["edge_rad_s"] <= hi + 1.0
    assert "after 4096 samples" in est.state.repeat_note()  # odd multisine: half periods
    assert est.test["p_value"] > 0.01
    sd = est.sd
    a1eq = float(est.model.equivalent_damping(est.theta, est.sigma_v))
    g = np.zeros(est.theta.size)
    g[:2] = 1.0, math.sqrt(8 / math.pi) * est.sigma_v
    sd_a1eq = math.sqrt(g @ est.cov @ g)
    # within the 90 % Laplace interval: measured a1eq +0.4 sd, a2 +1.1 sd
    assert abs(a1eq - ref["a1eq"]) < 1.645 * sd_a1eq
    assert abs(est.values["a2"] - ref["a2"]) < 1.645 * sd["a2"]
    # n2 rests on the displacement's fourth and sixth moments: -1.9 sd on this
    # realization, and as much with the reference circuit driven by this input or by a
    # flat multisine with its phases: the phases of these ten periods, not the circuit
    # (analyses/silverbox_coverage.py: over 120 random-phase realizations its 90 %
    # Laplace interval held the truth in 109, its 50 % in 62)
    assert abs(est.values["n2"] - ref["n2"]) < 2.5 * sd["n2"]
    v = est.values
    r = math.sqrt(v["rolloff"])  # the mean of 1 / (1 + beta (w / wb)^2) over the band
    band_level = v["S0"] * math.atan(r) / r
    assert band_level == pytest.approx(ref["S0"], rel=0.25)  # measured +1.8 %


@pytest.mark.slow
def test_hosid_fit_of_the_owners_csv_with_no_option(sb, ref, analysis, tmp_path):
    csv = analysis.owners_csv(sb, slice(None), tmp_path / "silverbox.csv")
    t0 = time.perf_counter()
    run = subprocess.run(
        [sys.executable, "-m", "hosid", "fit", str(csv), "--out", str(tmp_path / "fit")],
        capture_output=True,
        text=True,
        check=False,
    )
    seconds = time.perf_counter() - t0
    assert run.returncode == 0, run.stderr
    assert seconds < 120.0  # measured 67 s with the machine's two cores shared
    import json

    params = json.loads((tmp_path / "fit" / "summary.json").read_text())["parameters"]
    for p in ("a1eq", "a2"):
        assert params[p]["q05"] <= ref[p] <= params[p]["q95"], p


@pytest.mark.slow
def test_the_analysis_script_on_half_the_periods(analysis, tmp_path):
    out = analysis.main(["--parts", "second half", "--no-diagnose", "--out", str(tmp_path)])
    rows = {r["parameter"]: r for r in out["results"]["second half"]["table"]}
    assert rows["a1eq"]["holds"] and rows["a2"]["holds"]  # measured: n2 held too
    assert (tmp_path / "table.md").is_file() and (tmp_path / "summary.json").is_file()


def test_the_discrepancy_measures_fit_the_circuit(sb):
    """The measures' layout follows the record: segments, a resonance at 0.23 of the
    Nyquist frequency, and no spectral-tail measure above the multisine's 200 Hz edge.
    """
    from hosid.check.measures import MeasureSpec, measures

    spec = MeasureSpec.from_record(sb.record)
    assert spec.omega_n == pytest.approx(433.0, rel=0.02)  # sigma_v / sigma_x
    assert spec.tail_band == ()  # 0.8 x the edge (1184 rad/s) < 4 omega_n
    m = measures(sb.record, spec=spec)
    assert "psd_tail" not in m and all(np.all(np.isfinite(v)) for v in m.values())


@pytest.mark.slow
def test_diagnose_names_the_mean_force_the_reference_holds(sb, ref, analysis, tmp_path):
    """Measured: excitation_mean named, m = 116 +- 31 against the reference's 139.9; the
    gap 2.44 -> 0.91.
    """
    csv = analysis.owners_csv(sb, slice(None), tmp_path / "silverbox.csv")
    out = analysis.run_diagnose(csv, tmp_path, seed=0, ref=ref)
    assert "error" not in out, out
    assert out["named_effects"][:1] == ["excitation_mean"]
    assert out["named"][0]["holds"] and out["gaps"][1] < out["gaps"][0]
