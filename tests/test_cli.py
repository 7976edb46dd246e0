"""The command line end to end: simulate -> estimate -> fit -> report, and bad input.

Nothing is stubbed: the commands run the real engine on a 500 s record (24 blocks of
1024 samples), with ``--steps 200`` for the fit.
"""

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from hosid import __version__, cli
from hosid.errors import HosidInputError
from hosid.model import PAPER_PARAMS
from hosid.record import Record, read_record, write_record

REPORT_FILES = ("report.html", "summary.json", "corner.png", "trace.png")


def one_error_line(capsys) -> str:
    captured = capsys.readouterr()
    lines = captured.err.splitlines()
    assert len(lines) == 1, captured.err
    assert lines[0].startswith("hosid: error: ")
    assert "Traceback" not in captured.err
    return lines[0]


@pytest.fixture(scope="module")
def workdir(tmp_path_factory):
    """A 500 s paper record written by ``hosid simulate`` (seed 3)."""
    d = tmp_path_factory.mktemp("cli")
    rc = cli.main(["simulate", "--duration", "500", "--seed", "3", "--out", str(d / "rec.csv")])
    assert rc == 0
    return d


@pytest.fixture(scope="module")
def fitted(workdir):
    """``hosid fit rec.csv --steps 200`` into ``fit/``."""
    out = workdir / "fit"
    argv = ["fit", str(workdir / "rec.csv"), "--steps", "200", "--no-progress", "--seed", "1"]
    assert cli.main([*argv, "--out", str(out)]) == 0
    return out


# ------------------------------------------------------------------ simulate
def test_simulate_writes_the_record_and_its_truths(workdir):
    rec = read_record(workdir / "rec.csv")
    assert (rec.n, rec.dt, rec.name) == (25_000, 0.02, "rec")
    truths = json.loads((workdir / "rec.truths.json").read_text())
    assert truths == PAPER_PARAMS


def test_simulate_band_limited_force(tmp_path):
    """``--wb`` stops the force at its edge: the record's acceleration spectrum (the
    force's, far above the resonance) falls across it (by 77x at dt = 0.02 s; the rest
    is the sampled integrator's floor).
    """
    argv = ["simulate", "--a2", "25", "--wb", "40", "--rolloff", "0", "--duration", "400"]
    assert cli.main([*argv, "--dt", "0.02", "--out", str(tmp_path / "b.npz")]) == 0
    truths = json.loads((tmp_path / "b.truths.json").read_text())
    assert truths["wb"] == 40.0 and truths["rolloff"] == 0.0
    x = read_record(tmp_path / "b.npz").x
    w = 2 * np.pi * np.fft.rfftfreq(x.size, 0.02)
    Sa = np.abs(np.fft.rfft(x)) ** 2 * w**4
    inside, outside = Sa[(w > 25) & (w < 35)].mean(), Sa[(w > 50) & (w < 100)].mean()
    assert outside < 0.05 * inside  # measured 0.013 (white force: about 1)


def test_simulate_options_seed_and_npz(tmp_path, capsys):
    argv = ["simulate", "--a1", "1", "--n1", "0", "--a2", "9", "--n2", "0", "--S0", "25"]
    argv += ["--b2", "0.5", "--wc", "30", "--noise-sd", "0.01", "--m", "-1", "--mu", "0.2"]
    argv += ["--duration", "50", "--dt", "0.01", "--seed", "4"]
    for name in ("a.npz", "b.npz"):
        assert cli.main([*argv, "--out", str(tmp_path / name)]) == 0
    assert "wrote" in capsys.readouterr().out
    a, b = read_record(tmp_path / "a.npz"), read_record(tmp_path / "b.npz")
    assert (a.n, a.dt) == (5000, 0.01)
    np.testing.assert_array_equal(a.x, b.x)
    truths = json.loads((tmp_path / "a.truths.json").read_text())
    assert truths == {
        "a1": 1.0,
        "n1": 0.0,
        "a2": 9.0,
        "n2": 0.0,
        "S0": 25.0,
        "b2": 0.5,
        "mu": 0.2,
        "m": -1.0,
        "wc": 30.0,
        "noise_sd": 0.01,
    }


# ------------------------------------------------------------------ estimate
def test_estimate_prints_a_table_and_writes_json(workdir, capsys):
    out = workdir / "est.json"
    assert cli.main(["estimate", str(workdir / "rec.csv"), "--json", str(out)]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[0].startswith("rec: Model(linear_damping + quadratic_damping")
    assert "default components; Hansen J = " in lines[0]
    assert lines[1].split() == ["parameter", "estimate", "sd", "5%", "95%"]
    assert [ln.split()[0] for ln in lines[3:]] == ["a1", "n1", "a2", "n2", "S0", "a1eq"]
    data = json.loads(out.read_text())
    assert data["record"] == "rec" and data["cost"] is None and data["unit"] == "m"
    for k, (lo, hi) in data["interval90"].items():  # estimate +- 1.645 sd
        assert lo == pytest.approx(data["estimates"][k] - 1.6448536 * data["sd"][k])
        assert hi == pytest.approx(data["estimates"][k] + 1.6448536 * data["sd"][k])
    assert [c["name"] for c in data["checks"]][-2:] == ["oscillator", "calibration"]
    assert data["model"][:4] == [
        "linear_damping",
        "quadratic_damping",
        "linear_stiffness",
        "cubic_stiffness",
    ]
    assert set(data["estimates"]) == set(data["sd"]) == {*PAPER_PARAMS, "a1eq"}
    assert data["hansen"]["df"] == 2
    assert data["state"]["blocks"] == 24
    # the 500 s record recovers the truth within 3 sd (measured |z| < 1.3)
    for k, v in PAPER_PARAMS.items():
        assert abs(data["estimates"][k] - v) < 3 * data["sd"][k], k


def test_estimate_old_method_names_are_still_accepted(workdir, capsys):
    rec = str(workdir / "rec.csv")
    assert cli.main(["estimate", rec, "--method", "paper"]) == 0
    old = capsys.readouterr().out
    assert "J4A components" in old.splitlines()[0]
    assert cli.main(["estimate", rec, "--cost", "J4A"]) == 0
    assert capsys.readouterr().out == old  # --method paper means --cost J4A
    assert cli.main(["estimate", rec, "--method", "moments", "--model", "paper"]) == 0
    assert "J2 components" in capsys.readouterr().out


# ------------------------------------------------------------------ fit and report
def test_fit_writes_the_posterior_and_the_report(fitted, capsys):
    from hosid.output.results import load

    tree = load(fitted / "posterior.nc")
    assert set(tree["posterior"].data_vars) == {*PAPER_PARAMS, "a1eq"}
    assert tree.attrs["inference_library"] == "emcee"
    assert json.loads(tree.attrs["truths_json"]) == PAPER_PARAMS  # from rec.truths.json
    assert json.loads(tree.attrs["sampler_json"])["steps"] == 200
    pytest.importorskip("hosid.output.report")
    for name in REPORT_FILES:
        assert (fitted / name).stat().st_size > 0, name
    assert (fitted / "corner.png").read_bytes()[:4] == b"\x89PNG"


def test_fit_records_the_library_versions(fitted):
    """summary.json and posterior.nc's attributes list the versions of hosid and of the
    libraries the fit ran on (as installed: importlib.metadata).
    """
    from importlib.metadata import version

    from hosid.output.results import attr, load

    versions = json.loads((fitted / "summary.json").read_text())["versions"]
    for name in ("hosid", "numpy", "scipy", "emcee", "arviz", "numba", "matplotlib"):
        assert versions[name] == version(name), name
    assert versions["hosid"] == __version__
    assert attr(load(fitted / "posterior.nc"), "versions") == versions


def test_fit_prints_its_summary(workdir, capsys):
    out = workdir / "fit2"
    argv = ["fit", str(workdir / "rec.csv"), "--steps", "200", "--no-progress", "--seed", "2"]
    assert cli.main([*argv, "--walkers", "16", "--out", str(out)]) == 0
    captured = capsys.readouterr()
    lines = captured.out.splitlines()
    assert lines[0].startswith("rec: linear_damping + quadratic_damping")
    assert "16 walkers x" in lines[0]
    assert lines[1].split() == [
        "parameter",
        "mean",
        "sd",
        "q05",
        "q50",
        "q95",
        "r_hat",
        "ess_bulk",
    ]
    assert [ln.split()[0] for ln in lines[3:9]] == ["a1", "n1", "a2", "n2", "S0", "a1eq"]
    assert lines[-1].startswith(f"wrote {out / 'posterior.nc'}")
    # 200 steps cannot pass the diagnostics: one warning line, not an error
    err = captured.err.splitlines()
    assert len(err) == 1 and err[0].startswith("hosid: warning: convergence diagnostics")


def test_report_regenerates_from_the_posterior(fitted, capsys):
    pytest.importorskip("hosid.output.report")
    (fitted / "report.html").unlink()
    before = (fitted / "posterior.nc").stat().st_mtime_ns
    assert cli.main(["report", str(fitted)]) == 0
    assert (fitted / "report.html").stat().st_size > 0
    assert (fitted / "posterior.nc").stat().st_mtime_ns == before  # not rewritten
    text = capsys.readouterr().out
    assert "report.html" in text and "posterior.nc" not in text


# ------------------------------------------------------------------ figure processes
def _gone(pid: int) -> bool:
    """Whether process ``pid`` has ended (a zombie waiting for init counts as ended)."""
    import time
    from pathlib import Path

    for _ in range(200):
        try:
            state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
        except (FileNotFoundError, ProcessLookupError):
            return True
        if state == "Z":
            return True
        time.sleep(0.05)
    return False


@pytest.fixture
def figure_processes(monkeypatch):
    from hosid.output import render

    monkeypatch.setenv("HOSID_FIGURE_PROCESSES", "1")  # whatever the load
    if not render.enabled():
        pytest.skip("figures are drawn in the command's process here")
    return render


@pytest.mark.parametrize(
    ("error", "code", "line"),
    [
        (ValueError("no corner today"), 1, "drawing the report's figures failed: ValueError: "
         "no corner today"),
        (HosidInputError("cannot draw here"), 2, "cannot draw here"),
    ],
)  # fmt: skip
def test_a_figure_that_fails_in_its_process_is_one_error_line_and_writes_nothing(
    workdir, tmp_path, monkeypatch, capsys, figure_processes, error, code, line
):
    from hosid.output import plots

    def broken(tree):
        raise error

    monkeypatch.setattr(plots, "corner_plot", broken)  # the forked processes inherit it
    out = tmp_path / "fit"
    argv = ["fit", str(workdir / "rec.csv"), "--steps", "50", "--no-progress", "--out", str(out)]
    assert cli.main(argv) == code
    assert one_error_line(capsys) == f"hosid: error: {line}"
    assert [p.name for p in out.iterdir() if not p.name.startswith(".")] == []


def test_a_figure_process_that_dies_or_hangs_is_an_error_not_a_wait(
    workdir, tmp_path, monkeypatch, capsys, figure_processes
):
    import os
    import time

    from hosid.output import report

    pids = tmp_path / "pids"

    def dies(tree, stems, *, dpi):
        os._exit(7)

    def hangs(tree, stems, *, dpi):
        with pids.open("a") as fh:
            fh.write(f"{os.getpid()}\n")
        time.sleep(600)

    argv = ["fit", str(workdir / "rec.csv"), "--steps", "50", "--no-progress"]
    monkeypatch.setattr(report, "draw", dies)
    assert cli.main([*argv, "--out", str(tmp_path / "a")]) == 1
    assert one_error_line(capsys).endswith("a figure process ended without drawing its figures")
    monkeypatch.setattr(report, "draw", hangs)
    monkeypatch.setattr(figure_processes, "TIMEOUT", 2.0)
    monkeypatch.setattr(figure_processes, "_warm_up", lambda: None)  # takes the fit at once
    assert cli.main([*argv, "--out", str(tmp_path / "b")]) == 1
    assert one_error_line(capsys).endswith("the figures were not drawn within 2 s")
    drawing = [int(p) for p in pids.read_text().split()]
    assert len(drawing) == 2 and all(_gone(p) for p in drawing)  # both killed


def test_without_figure_processes_the_files_are_the_same(
    workdir, tmp_path, monkeypatch, figure_processes
):
    from hosid.output.report import STEMS

    argv = ["fit", str(workdir / "rec.csv"), "--steps", "100", "--no-progress", "--seed", "5"]
    assert cli.main([*argv, "--out", str(tmp_path / "a")]) == 0
    monkeypatch.setenv("HOSID_FIGURE_PROCESSES", "0")
    assert cli.main([*argv, "--out", str(tmp_path / "b")]) == 0
    drawn = [s for s in STEMS if (tmp_path / "a" / f"{s}.png").is_file()]
    assert drawn == [s for s in STEMS if s != "mode_shapes"]  # a single oscillator's
    for stem in drawn:
        png = f"{stem}.png"
        assert (tmp_path / "a" / png).read_bytes() == (tmp_path / "b" / png).read_bytes(), stem
    names = [sorted(p.name for p in (tmp_path / d).iterdir()) for d in "ab"]
    assert names[0] == names[1]


def test_fit_backend_refuses_another_record(workdir, tmp_path, capsys):
    backend = tmp_path / "chain.h5"
    argv = ["--steps", "100", "--no-progress", "--backend", str(backend)]
    assert cli.main(["fit", str(workdir / "rec.csv"), *argv, "--out", str(tmp_path / "a")]) == 0
    capsys.readouterr()
    assert (
        cli.main(
            ["simulate", "--duration", "500", "--seed", "9", "--out", str(tmp_path / "other.csv")]
        )
        == 0
    )
    capsys.readouterr()
    assert cli.main(["fit", str(tmp_path / "other.csv"), *argv, "--out", str(tmp_path / "b")]) == 2
    assert "holds a chain of another record" in one_error_line(capsys)


def test_fit_into_a_file_exits_2(workdir, tmp_path, capsys):
    # the output directory is checked only after the fit (see the report): keep it short
    (tmp_path / "file").write_text("")
    argv = ["fit", str(workdir / "rec.csv"), "--steps", "100", "--no-progress"]
    assert cli.main([*argv, "--out", str(tmp_path / "file")]) == 2
    assert "exists and is not a directory" in one_error_line(capsys)


def test_demo_runs_the_whole_pipeline_to_the_stop_rule(tmp_path, capsys):
    from hosid.output.results import load, summarize

    # a 2000 s record and a fit until the diagnostics pass: ~8 s
    out = tmp_path / "demo"
    assert cli.main(["demo", "--out", str(out), "--no-progress", "--seed", "5"]) == 0
    assert read_record(out / "demo_record.csv").n == 100_000
    summary = summarize(load(out / "posterior.nc"), warn=False)
    assert summary["converged"], summary["diagnostic_failures"]
    assert summary["truths"] == PAPER_PARAMS
    captured = capsys.readouterr()
    assert "paper oscillator" in captured.out
    assert captured.err == ""  # no convergence warning
    hidden = sorted(p.name for p in out.iterdir() if p.name.startswith("."))
    assert hidden == [".hosid-manifest.json"]  # no lock, chain or staging folder left


# ------------------------------------------------------------------ records hosid cannot describe
def _kinds(n: int = 30_000, dt: float = 0.02) -> dict[str, Record]:
    rng = np.random.default_rng(5)
    t = dt * np.arange(n)
    return {
        "constant": Record(np.full(n, 0.7), dt),
        "white": Record(rng.standard_normal(n), dt),
        "tone": Record(np.sin(5.0 * t), dt),
        "walk": Record(np.cumsum(rng.standard_normal(n)), dt),
    }


@pytest.mark.parametrize(
    ("kind", "why"),
    [
        ("constant", "the record is constant"),
        ("white", "does not fall off above a resonance"),
        ("tone", "tones, not a random response"),
        ("walk", "wanders like a random walk"),
    ],
)
@pytest.mark.parametrize("command", ["estimate", "fit", "diagnose"])
def test_a_record_that_is_no_oscillator_exits_3_and_writes_nothing(
    tmp_path, capsys, kind, why, command
):
    rec = write_record(_kinds()[kind], tmp_path / f"{kind}.csv")
    argv = [command, str(rec)]
    if command != "estimate":
        argv += ["--out", str(tmp_path / "out"), "--no-progress"]
    assert cli.main(argv) == 3
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1 and err[0].startswith("hosid: rejected: oscillator: "), err
    assert why in err[0] and "--force" in err[0]
    assert not (tmp_path / "out").exists()


def test_force_fits_a_rejected_record_and_says_so_in_red(tmp_path, capsys):
    rec = write_record(_kinds()["white"], tmp_path / "white.csv")
    out = tmp_path / "out"
    argv = ["fit", str(rec), "--force", "--steps", "100", "--no-progress", "--out", str(out)]
    assert cli.main(argv) == 0
    err = capsys.readouterr().err
    assert "hosid: fail: oscillator:" in err and "Traceback" not in err
    summary = json.loads((out / "summary.json").read_text())
    assert summary["forced"] is True and summary["verdict"] == "fail"
    failed = [c for c in summary["checks"] if c["status"] == "fail"]
    assert {c["name"] for c in failed} == {"sampling", "oscillator"}
    html = (out / "report.html").read_text()
    assert 'id="forced"' in html and '<tr class="fail"><td>oscillator</td>' in html


# ------------------------------------------------------------------ bad input
@pytest.mark.parametrize(
    ("argv", "match"),
    [
        ([], "a command is required"),
        (["--bogus"], "unrecognized arguments: --bogus"),
        (["frobnicate"], "invalid choice: 'frobnicate'"),
        (["simulate", "--out", "r.csv", "--frob", "1"], "unrecognized arguments: --frob"),
        (["simulate", "--out", "r.csv", "--dur", "1"], "unrecognized arguments: --dur"),
        (["simulate"], "required: --out"),
        (["simulate", "--out", "r.csv", "--dt", "0"], "--dt: must be positive"),
        (["simulate", "--out", "r.csv", "--dt", "-0.02"], "--dt: must be positive"),
        (["simulate", "--out", "r.csv", "--duration", "0"], "must be positive"),
        (["simulate", "--out", "r.csv", "--S0", "-100"], "--S0: must be positive"),
        (["simulate", "--out", "r.csv", "--S0", "nan"], "must be finite"),
        (["simulate", "--out", "r.csv", "--a1", "abc"], "--a1: not a number: 'abc'"),
        (["simulate", "--out", "r.csv", "--n1", "-1"], "--n1: must be non-negative"),
        (["simulate", "--out", "r.csv", "--seed", "-1"], "--seed: must be at least 0"),
        (["simulate", "--out", "r.csv", "--seed", "1.5"], "not an integer"),
        (["simulate", "--out", "r.csv", "--noise-sd", "0"], "--noise-sd: must be positive"),
        (["simulate", "--out", "r.csv", "--a2", "-1", "--n2", "0"], "restoring force"),
        (["simulate", "--out", "r.csv", "--a1", "0", "--n1", "0"], "needs damping"),
        (["simulate", "--out", "r.csv", "--duration", "0.1"], "fewer than 16 samples"),
        (["simulate", "--out", "r.txt"], "unknown file type '.txt'"),
        (["simulate", "--out", "r"], "unknown file type '(none)'"),
        (["estimate"], "required: record"),
        (["estimate", "missing.csv"], "missing.csv: no such file"),
        (["estimate", "missing.txt"], "missing.txt: no such file"),  # not its type
        (["estimate", "rec.txt"], "unknown file type"),
        (["estimate", "REC", "--method", "J3"], "invalid choice: 'J3'"),
        (["estimate", "REC", "--cost", "J3"], "invalid choice: 'J3'"),
        (["estimate", "REC", "--form", "literal"], "invalid choice: 'literal'"),
        (["estimate", "REC", "--domain", "octant"], "invalid choice: 'octant'"),
        (["estimate", "REC", "--model", "paper,stiction"], "unknown model term 'stiction'"),
        (["estimate", "REC", "--model", ""], "empty model spec"),
        (["estimate", "REC", "--block-seconds", "0"], "must be positive"),
        (["estimate", "REC", "--block-seconds", "0.01"], "use longer blocks"),
        (["estimate", "REC", "--block-seconds", "40.96"], "too short for 24 blocks"),
        (["estimate", "REC", "--omega-max", "-8"], "must be positive"),
        (["estimate", "REC", "--omega-max", "0.5"], "fewer than 3 bins"),
        (["estimate", "REC", "--json", "no/such/dir/e.json"], "cannot write"),
        (["estimate", "SHORT"], "periods"),
        (["estimate", "NAN"], "sample 7 is nan"),
        (["fit", "--out", "o"], "required: record"),
        (["fit", "REC"], "required: --out"),
        (["fit", "REC", "--cost", "J3", "--out", "o"], "invalid choice"),
        (["fit", "REC", "--domain", "magic", "--out", "o"], "invalid choice"),
        (["fit", "missing.csv", "--out", "o"], "no such file"),
        (["fit", "SHORT", "--out", "o"], "periods"),
        (["fit", "REC", "--walkers", "11", "--out", "o"], "even and at least 12"),
        (["fit", "REC", "--walkers", "8", "--out", "o"], "even and at least 12"),
        (["fit", "REC", "--walkers", "0", "--out", "o"], "--walkers: must be at least 2"),
        (["fit", "REC", "--walkers", "2.5", "--out", "o"], "not an integer"),
        (["fit", "REC", "--steps", "0", "--out", "o"], "--steps: must be at least 1"),
        (["fit", "REC", "--steps", "-5", "--out", "o"], "--steps: must be at least 1"),
        (["fit", "REC", "--seed", "-1", "--out", "o"], "--seed: must be at least 0"),
        (["fit", "REC", "--backend", "c.txt", "--out", "o"], "must be an HDF5 file"),
        (["fit", "REC", "--backend", "c", "--out", "o"], "must be an HDF5 file"),
        (["fit", "REC", "--truths", "none.json", "--out", "o"], "none.json: no such file"),
        (["fit", "REC", "--truths", "BADJSON", "--out", "o"], "not valid JSON"),
        (["fit", "REC", "--truths", "LIST", "--out", "o"], "JSON object of finite numbers"),
        (["fit", "REC", "--truths", "TEXT", "--out", "o"], "JSON object of finite numbers"),
        (["diagnose", "REC", "--replicates", "3", "--out", "o"], "must be at least 4"),
        (["diagnose", "REC", "--threshold", "0", "--out", "o"], "must be positive"),
        (["report"], "required: DIR"),
        (["report", "nowhere"], "posterior.nc: no such file"),
        (["report", "EMPTY"], "posterior.nc: no such file"),
        (["report", "GARBAGE"], "cannot read"),
        (["demo", "--seed", "x"], "not an integer"),
    ],
)
def test_bad_input_exits_2_with_one_line(workdir, tmp_path, monkeypatch, capsys, argv, match):
    monkeypatch.chdir(tmp_path)
    rng = np.random.default_rng(3)
    files = {
        "REC": str(workdir / "rec.csv"),
        "SHORT": str(
            write_record(
                Record(np.cumsum(rng.standard_normal(2500)), 0.02), tmp_path / "short.csv"
            )
        ),
        "CONST": str(write_record(Record(np.ones(5000), 0.02), tmp_path / "const.csv")),
        "BADJSON": "bad.json",
        "LIST": "list.json",
        "TEXT": "text.json",
        "EMPTY": "empty",
        "GARBAGE": "garbage",
    }
    x = np.zeros(9000)
    x[7] = np.nan
    (tmp_path / "nan.csv").write_text(
        "t,x\n" + "".join(f"{0.02 * i!r},{float(v)!r}\n" for i, v in enumerate(x))
    )
    files["NAN"] = "nan.csv"
    (tmp_path / "rec.txt").write_text("t,x\n")
    (tmp_path / "bad.json").write_text("{a1: 0.5")
    (tmp_path / "list.json").write_text("[0.5, 0.5]")
    (tmp_path / "text.json").write_text('{"a1": "half"}')
    (tmp_path / "empty").mkdir()
    (tmp_path / "garbage").mkdir()
    (tmp_path / "garbage" / "posterior.nc").write_text("not netCDF")
    argv = [files.get(a, a) for a in argv]
    assert cli.main(argv) == 2
    assert match in one_error_line(capsys)
    assert capsys.readouterr().out == ""
    assert not (tmp_path / "o").exists()


def test_version_and_help(capsys):
    with pytest.raises(SystemExit) as exc:
        cli.main(["--version"])
    assert exc.value.code == 0
    assert capsys.readouterr().out.strip() == f"hosid {__version__}"
    for command, option in (("estimate", "--omega-max"), ("fit", "--unconstrained")):
        with pytest.raises(SystemExit) as exc:
            cli.main([command, "--help"])
        assert exc.value.code == 0
        assert option in capsys.readouterr().out


def test_monitor_help_names_no_analysis_monitor_has_not(capsys):
    with pytest.raises(SystemExit) as exc:
        cli.main(["monitor", "--help"])
    assert exc.value.code == 0
    text = capsys.readouterr().out
    assert "--model MODEL" in text and "diagnose" not in text


def test_importing_python_m_hosid_runs_nothing(capsys):
    import importlib

    importlib.import_module("hosid.__main__")
    assert capsys.readouterr() == ("", "")


@pytest.mark.parametrize("argv", [["--no-such-option"], ["estimate", "does-not-exist.csv"]])
def test_python_m_hosid_exits_2_without_traceback(tmp_path, argv):
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


# ------------------------------------------------------------------ Ctrl-C, locks
def test_ctrl_c_keeps_the_chain_and_the_same_command_resumes_it(workdir, tmp_path):
    import signal
    import time

    out = tmp_path / "fit"
    argv = [sys.executable, "-m", "hosid", "fit", str(workdir / "rec.csv"), "--out", str(out)]
    argv += ["--no-progress", "--seed", "4", "--steps", "2500"]
    proc = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    chain = out / ".hosid-chain.h5"
    deadline = time.monotonic() + 120
    while not chain.exists() and time.monotonic() < deadline and proc.poll() is None:
        time.sleep(0.05)  # the chain is stored after its first 500 steps
    assert chain.exists(), "the fit stored no chain"
    children = Path(f"/proc/{proc.pid}/task/{proc.pid}/children")
    drawing = [int(p) for p in children.read_text().split()] if children.exists() else []
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 130
    assert all(_gone(p) for p in drawing)  # the figure process ends with the command
    lines = err.splitlines()
    assert len(lines) == 1 and "Traceback" not in err, err
    assert lines[0].startswith("hosid: interrupted; the chain so far is kept; resume with: ")
    resume = lines[0].split("resume with: ")[1]
    assert resume.startswith("hosid fit ") and f"--out {out}" in resume
    assert sorted(p.name for p in out.iterdir() if not p.name.startswith(".")) == []
    import h5py

    with h5py.File(chain) as f:
        kept = int(f["mcmc"].attrs["iteration"])
    assert kept >= 500
    # the same command completes the fit from the kept chain
    done = subprocess.run(argv, capture_output=True, text=True, timeout=300, check=False)
    assert done.returncode == 0, done.stderr
    summary = json.loads((out / "summary.json").read_text())
    assert summary["sampler"]["steps"] == 2500 > kept  # continued, not restarted
    assert not chain.exists()
    assert (out / "posterior.nc").exists() and (out / "report.html").exists()


def test_a_second_command_on_a_busy_folder_stops_at_once(workdir, tmp_path, capsys):
    from hosid.output.files import locked_dir

    out = tmp_path / "busy"
    with locked_dir(out, command="hosid fit other.csv --out busy"):
        (out / "theirs.txt").write_text("first")
        argv = ["fit", str(workdir / "rec.csv"), "--steps", "50", "--no-progress"]
        assert cli.main([*argv, "--out", str(out)]) == 2
        assert "is in use by 'hosid fit other.csv --out busy'" in one_error_line(capsys)
    assert (out / "theirs.txt").read_text() == "first"


def test_estimate_reads_a_single_acceleration_channel(tmp_path, capsys):
    """``hosid estimate REC.csv --measured acceleration`` on one channel: the one-element
    chain's estimate, printed (it raised an AttributeError computing a1eq for a system).
    """
    from hosid.model.chain import simulate_chain, write_chain_record
    from hosid.model.system import System

    single = System.single("paper", PAPER_PARAMS)
    rec = simulate_chain(single, duration=300.0, dt=0.02, rng=np.random.default_rng(4),
                         measured="acceleration")  # fmt: skip
    path = write_chain_record(rec, tmp_path / "acc.csv")
    assert cli.main(["estimate", str(path), "--measured", "acceleration"]) == 0
    out = capsys.readouterr().out
    assert "System(x; ground-x" in out and out.count("\na2 ") == 1
    # its linear terms' mode, sqrt(a2) / 2 pi = 0.796 Hz, with the delta method's sd
    mode = out.split("modes of the linear terms")[1].splitlines()[3].split()
    assert mode[0] == "1" and abs(float(mode[1]) / (5.0 / (2 * np.pi)) - 1) < 0.05
