"""Command line plumbing: argument parsing, output files, error exits.

STUBBED: every test here except the subprocess ones replaces the numerical core
(``hosid.simulate.simulate`` and ``hosid.estimators.estimate``) with fakes, so
it checks only the CLI's plumbing, never the numbers. End-to-end tests of the
real core live elsewhere.
"""

import json
import math
import subprocess
import sys
import types

import numpy as np
import pytest

from hosid import cli
from hosid.errors import HosidInputError
from hosid.records import Record, read_record, write_record

FAKE_ESTIMATES = {"a1": 0.51, "n1": 0.49, "a2": 25.1, "n2": 4.9, "S0": math.nan, "a1eq": None}


class Calls:
    """Arguments the fakes were called with."""

    def __init__(self):
        self.simulate = []
        self.estimate = []


@pytest.fixture
def stub_core(monkeypatch):
    """STUB the numerical core with fakes, for plumbing tests only."""
    calls = Calls()

    def fake_simulate(params, *, duration, dt, rng, return_velocity=False):
        calls.simulate.append({"params": params, "duration": duration, "dt": dt, "rng": rng})
        rec = Record(rng.standard_normal(round(duration / dt)), dt)
        return (rec, np.gradient(rec.x, dt)) if return_velocity else rec

    def fake_estimate(
        record, *, method, window, block_seconds, omega_max, domain="principal", form="scaled"
    ):
        calls.estimate.append(
            {
                "record": record,
                "method": method,
                "window": window,
                "block_seconds": block_seconds,
                "omega_max": omega_max,
            }
        )
        return {
            "method": method,
            "estimates": dict(FAKE_ESTIMATES),
            "settings": {"window": window, "spread": np.float64(0.25), "k": np.arange(2)},
        }

    sim = types.ModuleType("hosid.simulate")
    sim.simulate = fake_simulate
    est = types.ModuleType("hosid.estimators")
    est.estimate = fake_estimate
    monkeypatch.setitem(sys.modules, "hosid.simulate", sim)
    monkeypatch.setitem(sys.modules, "hosid.estimators", est)
    return calls


@pytest.fixture
def rec_file(tmp_path):
    """A record long enough for 8 blocks of 20.48 s at dt = 0.02."""
    rng = np.random.default_rng(3)
    return write_record(Record(rng.standard_normal(9000), 0.02), tmp_path / "rec.csv")


def one_error_line(capsys):
    err = capsys.readouterr().err
    lines = err.splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("hosid: error: ")
    assert "Traceback" not in err
    return lines[0]


def test_simulate_defaults(stub_core, tmp_path, capsys):
    out = tmp_path / "rec.npz"
    assert cli.main(["simulate", "--duration", "10", "--out", str(out)]) == 0
    (call,) = stub_core.simulate
    assert call["params"] == {"a1": 0.5, "n1": 0.5, "a2": 25.0, "n2": 5.0, "S0": 100.0}
    assert call["dt"] == 0.02
    assert call["duration"] == 10.0
    assert isinstance(call["rng"], np.random.Generator)
    assert read_record(out).n == 500
    assert "wrote" in capsys.readouterr().out


def test_simulate_options_and_seed(stub_core, tmp_path):
    argv = ["simulate", "--a1", "1", "--n1", "0", "--a2", "9", "--n2", "0", "--S0", "2500"]
    argv += ["--duration", "5", "--dt", "0.01", "--seed", "4"]
    for name in ("a.csv", "b.csv"):
        assert cli.main([*argv, "--out", str(tmp_path / name)]) == 0
    call = stub_core.simulate[0]
    assert call["params"] == {"a1": 1.0, "n1": 0.0, "a2": 9.0, "n2": 0.0, "S0": 2500.0}
    assert (call["duration"], call["dt"]) == (5.0, 0.01)
    a, b = read_record(tmp_path / "a.csv"), read_record(tmp_path / "b.csv")
    np.testing.assert_array_equal(a.x, b.x)


def test_estimate_table_and_json(stub_core, rec_file, tmp_path, capsys):
    out = tmp_path / "est.json"
    argv = ["estimate", str(rec_file), "--method", "J4A", "--window", "boxcar"]
    argv += ["--block-seconds", "10.24", "--omega-max", "12", "--json", str(out)]
    assert cli.main(argv) == 0
    (call,) = stub_core.estimate
    assert call["method"] == "J4A"
    assert call["window"] == "boxcar"
    assert call["block_seconds"] == 10.24
    assert call["omega_max"] == 12.0
    assert call["record"].n == 9000
    text = capsys.readouterr().out
    for key in ("a1", "n1", "a2", "n2", "S0", "a1eq"):
        assert key in text
    assert "25.1" in text
    data = json.loads(out.read_text())
    assert data["method"] == "J4A"
    assert data["estimates"]["S0"] is None
    assert data["estimates"]["a1eq"] is None
    assert data["estimates"]["a2"] == 25.1
    assert data["settings"] == {"window": "boxcar", "spread": 0.25, "k": [0, 1]}


def test_estimate_defaults(stub_core, rec_file):
    assert cli.main(["estimate", str(rec_file)]) == 0
    (call,) = stub_core.estimate
    assert (call["method"], call["window"]) == ("paper", "hann")
    assert (call["block_seconds"], call["omega_max"]) == (20.48, 8.0)


def test_demo_writes_outputs(stub_core, tmp_path, capsys):
    out = tmp_path / "demo"
    assert cli.main(["demo", "--out", str(out), "--seed", "5"]) == 0
    assert [c["method"] for c in stub_core.estimate] == list(cli.DEMO_METHODS)
    (call,) = stub_core.simulate
    assert call["params"] == cli.PAPER_PARAMS
    assert (call["duration"], call["dt"]) == (2000.0, 0.02)
    assert read_record(out / "demo_record.csv").n == 100_000
    data = json.loads((out / "estimates.json").read_text())
    assert data["seed"] == 5
    assert data["truth"]["a2"] == 25.0
    assert data["truth"]["a1eq"] > 0.5
    assert set(data["results"]) == set(cli.DEMO_METHODS)
    report = (out / "report.md").read_text()
    assert "| parameter | truth | " + " | ".join(cli.DEMO_METHODS) + " |" in report
    assert "truth" in capsys.readouterr().out


def test_estimator_input_error_becomes_exit_2(stub_core, rec_file, monkeypatch, capsys):
    def refuse(record, **kwargs):
        raise HosidInputError("cannot estimate\nthis record")

    monkeypatch.setattr(sys.modules["hosid.estimators"], "estimate", refuse)
    assert cli.main(["estimate", str(rec_file)]) == 2
    assert one_error_line(capsys) == "hosid: error: cannot estimate this record"


@pytest.mark.parametrize(
    ("argv", "match"),
    [
        ([], "a command is required"),
        (["--bogus"], "--bogus"),
        (["frobnicate"], "invalid choice"),
        (["simulate", "--out", "r.csv", "--frob", "1"], "--frob"),
        (["simulate"], "--out"),
        (["simulate", "--out", "r.csv", "--dt", "0"], "must be positive"),
        (["simulate", "--out", "r.csv", "--dt", "-0.02"], "must be positive"),
        (["simulate", "--out", "r.csv", "--duration", "0"], "must be positive"),
        (["simulate", "--out", "r.csv", "--S0", "-100"], "must be positive"),
        (["simulate", "--out", "r.csv", "--S0", "nan"], "must be finite"),
        (["simulate", "--out", "r.csv", "--a1", "abc"], "not a number"),
        (["simulate", "--out", "r.csv", "--n1", "-1"], "non-negative"),
        (["simulate", "--out", "r.csv", "--seed", "-1"], "non-negative"),
        (["simulate", "--out", "r.csv", "--seed", "1.5"], "not an integer"),
        (["simulate", "--out", "r.csv", "--a1", "0", "--n1", "0"], "needs damping"),
        (["simulate", "--out", "r.csv", "--a2", "-1", "--n2", "0"], "restoring force"),
        (["simulate", "--out", "r.csv", "--duration", "0.1"], "at least 16"),
        (["simulate", "--out", "r.txt"], "unknown file type"),
        (["estimate"], "record"),
        (["estimate", "missing.csv"], "no such file"),
        (["estimate", "rec.txt"], "unknown file type"),
        (["estimate", "REC", "--method", "J3"], "invalid choice"),
        (["estimate", "REC", "--window", "hamming"], "invalid choice"),
        (["estimate", "REC", "--block-seconds", "0"], "must be positive"),
        (["estimate", "REC", "--omega-max", "-8"], "must be positive"),
        (["estimate", "REC", "--omega-max", "200"], "Nyquist"),
        (["estimate", "REC", "--block-seconds", "0.01"], "shorter than two samples"),
        (["estimate", "REC", "--block-seconds", "40.96"], "too short for 8 blocks"),
        (["estimate", "SHORT"], "too short for 8 blocks"),
        (["estimate", "NAN"], "sample 7 is nan"),
        (["demo", "--seed", "x"], "not an integer"),
    ],
)
def test_bad_input_exits_2_with_one_line(
    stub_core, rec_file, tmp_path, monkeypatch, capsys, argv, match
):
    monkeypatch.chdir(tmp_path)
    short = write_record(Record(np.zeros(1000), 0.02), tmp_path / "short.csv")
    x = np.zeros(9000)
    x[7] = np.nan
    nan_file = tmp_path / "nan.csv"
    nan_file.write_text("t,x\n" + "".join(f"{0.02 * i!r},{float(v)!r}\n" for i, v in enumerate(x)))
    files = {"REC": str(rec_file), "SHORT": str(short), "NAN": str(nan_file)}
    argv = [files.get(a, a) for a in argv]
    assert cli.main(argv) == 2
    assert match in one_error_line(capsys)
    assert not stub_core.estimate
    assert not stub_core.simulate


def test_help_and_version(capsys):
    with pytest.raises(SystemExit) as exc:
        cli.main(["--version"])
    assert exc.value.code == 0
    assert "hosid" in capsys.readouterr().out
    with pytest.raises(SystemExit) as exc:
        cli.main(["estimate", "--help"])
    assert exc.value.code == 0
    assert "--omega-max" in capsys.readouterr().out


@pytest.mark.parametrize(
    "argv", [["--no-such-option"], ["estimate", "does-not-exist.csv"], ["simulate", "--dt", "0"]]
)
def test_python_m_hosid_no_traceback(tmp_path, argv):
    proc = subprocess.run(
        [sys.executable, "-m", "hosid", *argv],
        capture_output=True,
        text=True,
        cwd=tmp_path,
        timeout=120,
        check=False,
    )
    assert proc.returncode == 2
    lines = proc.stderr.splitlines()
    assert len(lines) == 1, proc.stderr
    assert lines[0].startswith("hosid: error: ")
    assert proc.stdout == ""
