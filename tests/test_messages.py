"""Every row of the README's table of bad input, run as written.

The table between ``<!-- messages -->`` and ``<!-- /messages -->`` gives a command, the
one line it must print on stderr (``...`` for the parts that depend on the file) and
its exit code; the files it names are made here.  The thresholds table is checked
against the numbers the code uses, so that the README cannot drift from them.
"""

from __future__ import annotations

import contextlib
import io
import re
import shlex
from pathlib import Path

import numpy as np
import pytest

from hosid import cli
from hosid.inference.calibrate import HANSEN_P
from hosid.inference.chains import ChainFile
from hosid.inference.system_estimate import NOISE_SHARE
from hosid.model import PAPER_PARAMS, simulate
from hosid.output.files import locked_dir
from hosid.record import Record, write_record
from hosid.record.channel_checks import DUPLICATE_CORRELATION, HELD_SHARE
from hosid.screen import THRESHOLDS
from hosid.spectra.blocks import MIN_BLOCKS, MIN_PERIODS
from hosid.spectra.integrate import BAND_RISE
from hosid.verdicts import ESS_MIN, RHAT_MAX

README = Path(__file__).resolve().parents[1] / "README.md"


def _table(marker: str) -> list[list[str]]:
    text = README.read_text(encoding="utf-8")
    body = text.split(f"<!-- {marker} -->")[1].split(f"<!-- /{marker} -->")[0]
    rows = [ln.strip() for ln in body.strip().splitlines()[2:]]
    return [[c.strip() for c in r.strip("|").split("|")] for r in rows if r]


ROWS = _table("messages")


@pytest.fixture(scope="module")
def files(tmp_path_factory) -> Path:
    d = tmp_path_factory.mktemp("messages")
    rng = np.random.default_rng(11)
    good = simulate(PAPER_PARAMS, duration=500.0, rng=np.random.default_rng(12))
    write_record(good, d / "rec.csv")
    (d / "folder.csv").mkdir()
    (d / "adir").mkdir()  # a folder without a suffix is named a folder too
    (d / "rec.txt").write_text("t,x\n0,1\n")  # a file of an unknown type
    (d / "garbage.npz").write_bytes(b"\x00garbage" * 50)
    (d / "nocol.csv").write_text("time,x\n0,1\n0.02,2\n")
    (d / "text.csv").write_text("t,x\n0,1\n0.02,abc\n")
    (d / "badseg.csv").write_text("t,x,segment\n0,1,0\n0.02,2,0\n0.04,3,x\n")
    (d / "nan.csv").write_text(
        "t,x\n" + "".join(f"{0.02 * i:.2f},{'nan' if i == 5 else 0.1 * i}\n" for i in range(40))
    )
    t = [0.02 * i for i in range(100)] + [10.0 + 0.02 * i for i in range(100)]
    (d / "jump.csv").write_text("t,x\n" + "".join(f"{a:.2f},{i % 7}\n" for i, a in enumerate(t)))
    write_record(Record(good.x[:2000], good.dt), d / "short.csv")
    n, dt = 30_000, 0.02
    write_record(Record(np.full(n, 0.3), dt), d / "const.csv")
    write_record(Record(rng.standard_normal(n), dt), d / "noise.csv")
    write_record(Record(np.sin(4.0 * dt * np.arange(n)), dt), d / "tone.csv")
    write_record(Record(np.cumsum(rng.standard_normal(n)), dt), d / "walk.csv")
    s = float(np.std(good.x))
    write_record(Record(np.clip(good.x, -1.5 * s, 1.5 * s), good.dt), d / "clipped.csv")
    ChainFile(d / "other.h5", {"record": "another"}, 32, 5).save()
    return d


def _pattern(expected: str) -> re.Pattern:
    parts = [re.escape(p) for p in expected.split("...")]
    return re.compile("^" + ".*".join(parts) + "$")


@pytest.mark.parametrize(("what", "command", "stderr", "code"), ROWS, ids=[r[0] for r in ROWS])
def test_readme_message(files, monkeypatch, what, command, stderr, code):
    monkeypatch.chdir(files)
    argv = shlex.split(command.strip("`"))
    assert argv[0] == "hosid"
    err = io.StringIO()
    with contextlib.ExitStack() as stack:
        if "busy" in argv:
            stack.enter_context(
                locked_dir(files / "busy", command="hosid fit other.csv --out busy")
            )
        stack.enter_context(contextlib.redirect_stderr(err))
        stack.enter_context(contextlib.redirect_stdout(io.StringIO()))
        got = cli.main(argv[1:])
    lines = err.getvalue().splitlines()
    assert got == int(code), err.getvalue()
    assert len(lines) == 1, err.getvalue()
    assert _pattern(stderr.strip("`")).match(lines[0]), (lines[0], stderr)
    assert not (files / "o").exists()  # nothing written on failure


def test_the_readme_quotes_the_thresholds_the_code_uses():
    rows = {r[0]: r for r in _table("thresholds")}

    def num(cell: str) -> float | None:
        cell = cell.replace("<=", "").replace(">=", "").replace("<", "").strip()
        return float(cell) if cell else None

    for check, key in [
        ("sampling", "sampling"),
        ("trend", "trend"),
        ("clipping", "clipping"),
        ("quantisation", "quantisation"),
        ("offset", "levels"),
        ("oscillator: flatness", "flatness"),
        ("oscillator: variation", "variation"),
        ("oscillator: line share", "line_share"),
        ("oscillator: wander", "wander"),
    ]:
        _, _, warn, fail = rows[check]
        assert (num(warn), num(fail)) == THRESHOLDS[key], check
    assert f"{MIN_BLOCKS} blocks of {MIN_PERIODS:.0f}" in rows["length"][1]
    assert num(rows["calibration"][2]) == HANSEN_P
    assert num(rows["channels: duplicate"][3]) == DUPLICATE_CORRELATION
    assert num(rows["channels: resampled"][3]) == HELD_SHARE
    assert num(rows["channels: integration"][3]) == BAND_RISE
    assert num(rows["sensor_noise"][2]) == NOISE_SHARE
    assert rows["convergence"][2] == f">= {RHAT_MAX} / < {ESS_MIN:.0f}"
