"""``hosid diagnose`` of a system: (effect, element) pairs weighed by their Wald z
(:mod:`hosid.check.locate`), and ``--measured`` on the commands that read a record.

Power and false alarms are measured over replicated records in
``analyses/locate_power.py``; here one seeded record a case checks the mechanics.
"""

import importlib
import json
import sys
from pathlib import Path

import numpy as np
import pytest

from hosid import cli
from hosid.check.locate import extended, locate, pairs
from hosid.errors import HosidInputError
from hosid.model.chain import simulate_chain
from hosid.model.system import System
from hosid.record import write_record

ANALYSES = Path(__file__).resolve().parents[1] / "analyses"


@pytest.fixture(scope="module")
def base(tmp_path_factory):
    """The all-linear 2-dof chain of ``analyses/locate_power.py`` and its file."""
    sys.path.insert(0, str(ANALYSES))
    try:
        text = importlib.import_module("locate_power").BASE
    finally:
        sys.path.remove(str(ANALYSES))
    path = tmp_path_factory.mktemp("locate") / "base.toml"
    path.write_text(text)
    return System.from_toml(path), path


def _record(system, values, seed, **kw):
    return simulate_chain(system, system.vector(values), duration=1000.0, dt=0.02,
                          rng=np.random.default_rng(seed), **kw)  # fmt: skip


def test_the_pairs_are_each_candidate_in_each_element_that_lacks_it(base):
    s, _ = base
    assert pairs(s, ("quadratic_damping", "cubic_stiffness")) == [
        ("quadratic_damping", 0), ("cubic_stiffness", 0),
        ("quadratic_damping", 1), ("cubic_stiffness", 1),
    ]  # fmt: skip
    ext = extended(s, "cubic_stiffness", 1)
    assert "n2[x1-x2]" in ext.param_names and len(ext.param_names) == len(s.param_names) + 1
    assert ext.masses == s.masses and ext.driven == s.driven
    assert pairs(ext, ("cubic_stiffness",)) == [("cubic_stiffness", 0)]


def test_a_strong_cubic_spring_is_named_in_its_element(base):
    s, _ = base
    ext = extended(s, "cubic_stiffness", 1)
    rec = _record(ext, {**dict(s.values), "n2[x1-x2]": 0.08}, 3)  # ~7 bound sd at 1000 s
    loc = locate(rec, s)
    assert loc.named_effects == ["cubic_stiffness in x1-x2"]
    first = {w.label: w for w in loc.rounds[0].weighed}
    assert len(first) == 4 and first["cubic_stiffness in x1-x2"].z > 4.0
    assert loc.estimate["n2[x1-x2]"] == pytest.approx(0.08, rel=0.35)
    rep = loc.report()
    assert rep["named"][0]["element"] == "x1-x2" and rep["named"][0]["effect"] == "cubic_stiffness"


def test_a_linear_record_names_nothing_and_its_z_are_moderate(base):
    s, _ = base
    loc = locate(rec := _record(s, dict(s.values), 4), s)
    assert loc.named_effects == [] and len(loc.rounds) == 1
    assert all(abs(w.z) < 3.0 for w in loc.rounds[0].weighed)
    assert "no pair is supported" in loc.decision
    assert rec.n == 50000


def test_bad_candidates_and_a_full_system_are_one_line_errors(base):
    s, _ = base
    rec = _record(s, dict(s.values), 5)
    with pytest.raises(HosidInputError, match="not candidate effects of a system: coulomb"):
        locate(rec, s, candidates=["coulomb_friction"])
    full = extended(extended(s, "cubic_stiffness", 0), "cubic_stiffness", 1)
    with pytest.raises(HosidInputError, match="already has every candidate"):
        locate(rec, full, candidates=["cubic_stiffness"])


def test_diagnose_with_a_system_file_writes_the_located_pair(base, tmp_path, capsys):
    s, toml = base
    ext = extended(s, "cubic_stiffness", 1)
    rec = _record(ext, {**dict(s.values), "n2[x1-x2]": 0.08}, 6, measured="acceleration")
    path = tmp_path / "acc.csv"  # a CSV says nothing of what it holds: --measured does
    write_record(rec, path)
    out = tmp_path / "d"
    argv = ["diagnose", str(path), "--model", str(toml), "--measured", "acceleration",
            "--out", str(out), "--no-progress"]  # fmt: skip
    assert cli.main(argv) == 0
    rep = json.loads((out / "report.json").read_text())
    assert rep["named_effects"] == ["cubic_stiffness in x1-x2"]
    assert {"report.html", "report.json", "evidence.png"} <= {p.name for p in out.iterdir()}
    assert "named: cubic_stiffness in x1-x2" in capsys.readouterr().out


def test_measured_declares_what_the_channels_hold(base, tmp_path, capsys):
    s, _ = base
    rec = _record(s, dict(s.values), 7, measured="acceleration")
    npz = tmp_path / "acc.npz"  # the file says acceleration
    write_record(rec, npz)
    argv = ["estimate", str(npz), "--model", str(base[1]), "--measured", "displacement"]
    assert cli.main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert "is an acceleration (its file says so) but was declared a displacement" in err
    assert "\n" not in err


def test_systems_of_one_topology_share_a_state_without_mixing_their_columns(base):
    """A state's cached feature transforms are keyed by element and term: fitting one
    extended system first leaves another's fit on the same state unchanged (they were
    keyed by column index, and ``n1[x1-x2]`` read ``a1[x1-x2]``'s transforms).
    """
    from hosid.inference.system_estimate import estimate_system, system_state

    s, _ = base
    rec = _record(s, dict(s.values), 9, measured="acceleration")
    first, second = extended(s, "quadratic_damping", 0), extended(s, "quadratic_damping", 1)
    shared = system_state(rec, s)
    estimate_system(shared, first)
    alone = estimate_system(system_state(rec, s), second).theta
    np.testing.assert_allclose(estimate_system(shared, second).theta, alone, rtol=1e-9)
