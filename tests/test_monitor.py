"""hosid monitor: reading by chunks, windows, resuming after a kill, following a file,
errors; the tracks and the change test end to end on short simulated records.
"""

from __future__ import annotations

import csv
import itertools
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from hosid.cli import main
from hosid.errors import HosidInputError
from hosid.model.simulate import simulate
from hosid.monitor import source as source_mod
from hosid.monitor.source import Source
from hosid.monitor.windows import choose_layout, count, windows
from hosid.record import Record, write_record

HOSID = [sys.executable, "-m", "hosid"]
#: 24 blocks of the paper oscillator's 20.48 s: the shortest window a fit takes.
WINDOW = 491.52


@pytest.fixture(scope="module")
def record(tmp_path_factory) -> Path:
    """3000 s of the paper oscillator (6 windows of 491.52 s)."""
    path = tmp_path_factory.mktemp("mon") / "rec.csv"
    rec = simulate({"a1": 0.5, "n1": 0.5, "a2": 25, "n2": 5, "S0": 100}, duration=3000.0,
                   dt=0.02, rng=np.random.default_rng(5))  # fmt: skip
    write_record(rec, path)
    return path


def _windows(src, layout):
    return [w for w in windows(src.pieces(), layout) if w is not None]


def test_every_format_gives_the_same_windows(record, tmp_path, monkeypatch):
    """CSV, .npz with dt, compressed .npz with t, and a folder of three CSV parts give
    the same windows, sample for sample, also when read in small chunks."""
    from hosid.record import read_record

    rec = read_record(record)
    np.savez(tmp_path / "a.npz", x=rec.x, dt=rec.dt)
    np.savez_compressed(tmp_path / "b.npz", x=rec.x, t=np.arange(rec.n) * rec.dt)
    parts = tmp_path / "parts"
    parts.mkdir()
    lines = record.read_text().splitlines(True)
    cuts = [1, 40001, 90001, len(lines)]
    for k, (a, b) in enumerate(itertools.pairwise(cuts)):
        (parts / f"part{k + 8}.csv").write_text(lines[0] + "".join(lines[a:b]))  # 8, 9, 10
    src = Source(record)
    layout = choose_layout(src, window=WINDOW, block_seconds=20.48)
    ref = _windows(src, layout)
    assert len(ref) == count(rec.n, layout) == 6
    monkeypatch.setattr(source_mod, "CHUNK", 7777)  # windows straddle chunks
    for other in (tmp_path / "a.npz", tmp_path / "b.npz", parts):
        got = _windows(Source(other), layout)
        assert len(got) == len(ref)
        for w, r in zip(got, ref, strict=True):
            assert w.start == pytest.approx(r.start, abs=1e-6)
            np.testing.assert_array_equal(w.x, r.x)


def test_no_window_spans_a_gap(tmp_path):
    """A jump in the time column starts a new run; windows restart after it."""
    dt, n = 0.1, 1000
    t = np.concatenate([np.arange(n) * dt, 500.0 + np.arange(n) * dt])
    x = np.sin(np.arange(2 * n) * 0.3)
    path = tmp_path / "gap.csv"
    np.savetxt(path, np.column_stack([t, x]), delimiter=",", header="t,x", comments="")
    src = Source(path)
    from hosid.monitor.windows import Layout

    layout = Layout(samples=300, step=300, dt=dt, block_seconds=1.0)
    ws = _windows(src, layout)
    # each run's last 10 s (a third of a window) get a window ending with the run
    assert [round(w.start, 6) for w in ws] == [0, 30, 60, 70, 500, 530, 560, 570]
    assert all(w.end <= 100.0 + 1e-9 or w.start >= 500.0 for w in ws)
    np.testing.assert_array_equal(ws[3].x, x[700:1000])
    assert count(n, layout) == 4
    bare = [w for w in windows(src.pieces(), layout, tail=False) if w is not None]
    assert [round(w.start, 6) for w in bare] == [0, 30, 60, 500, 530, 560]


def test_follow_reads_appended_lines(tmp_path):
    """A followed CSV yields the lines appended while it waits (a last line without its
    newline waits for the rest), and stops when told."""
    path = tmp_path / "grow.csv"
    path.write_text("t,x\n" + "".join(f"{k * 0.1:.1f},{np.sin(k):.6f}\n" for k in range(500)))
    looks = []

    def stop() -> bool:
        looks.append(1)
        with path.open("a") as fh:
            if len(looks) == 1:
                fh.write("".join(f"{k * 0.1:.1f},{np.sin(k):.6f}\n" for k in range(500, 899)))
                fh.write("89.9,0.5")  # half written
            elif len(looks) == 2:
                fh.write("1\n")
        return len(looks) > 3

    from hosid.monitor.windows import Layout

    layout = Layout(samples=300, step=150, dt=0.1, block_seconds=1.0)
    got = list(
        windows(Source(path).pieces(follow=True, poll=0.001, stop=stop), layout, tail=False)
    )
    ws = [w for w in got if w is not None]
    assert None in got  # the idle looks are passed on
    assert [round(w.start, 6) for w in ws] == [0, 15, 30, 45, 60]
    assert ws[-1].x[-1] == pytest.approx(0.51)  # the completed line


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["nofile.csv"], "no such file"),
        (["rec.txt"], "unknown file type"),
        (["REC", "--window", "100"], "use a longer --window"),
        (["REC", "--window", "100", "--block-seconds", "20.48"], "a fit needs 24"),
        (["REC", "--step", "5000", "--window", "600"], "--step must lie between"),
    ],
)
def test_bad_input_is_one_line_and_no_folder(record, tmp_path, capsys, args, message):
    (tmp_path / "rec.txt").write_text("x")
    args = [str(record) if a == "REC" else a for a in args]
    out = tmp_path / "out"
    os.chdir(tmp_path)
    assert main(["monitor", *args, "--out", str(out), "--no-progress"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and message in err
    assert not out.exists()


def _rows(out: Path) -> list[dict]:
    with (out / "tracks.csv").open() as fh:
        return list(csv.DictReader(fh))


def test_killed_monitor_resumes_and_does_every_window_once(record, tmp_path):
    """SIGKILL after the first window, rerun: the second run fits only the windows not
    done, every window appears once in the tracks, and other settings are refused."""
    out = tmp_path / "m"
    cmd = [*HOSID, "monitor", str(record), "--out", str(out), "--analysis", "estimate",
           "--window", str(WINDOW), "--workers", "1", "--no-progress"]  # fmt: skip
    p = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    tasks = out / "windows" / "tasks"
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline and not (tasks.is_dir() and any(tasks.iterdir())):
        time.sleep(0.2)
    p.send_signal(signal.SIGKILL)
    p.wait()
    done_before = len(list(tasks.iterdir()))
    assert 1 <= done_before < 6
    res = subprocess.run(cmd, capture_output=True, text=True, timeout=300)
    assert res.returncode == 0, res.stderr
    rows = _rows(out)
    starts = [r["start"] for r in rows if r["parameter"] == "a2"]
    assert len(starts) == len(set(starts)) == 6
    assert len(list(tasks.iterdir())) == 6  # one stored result a window
    summary = json.loads((out / "monitor.json").read_text())
    assert summary["windows"] == 6 and summary["failed_windows"] == []
    assert summary["correlation"] == "pooled"  # which correlation the change test gave
    again = subprocess.run([*cmd[:-3], "--step", "245.76", "--no-progress"],
                           capture_output=True, text=True)  # fmt: skip
    assert again.returncode == 2 and "other layout" in again.stderr


def test_rejected_window_is_marked_not_dropped(tmp_path):
    """A window of a dead sensor keeps its rows (status, no numbers) and the test skips it."""
    rec = simulate({"a1": 0.5, "n1": 0.5, "a2": 25, "n2": 5, "S0": 100}, duration=2000.0,
                   dt=0.02, rng=np.random.default_rng(8))  # fmt: skip
    x = rec.x.copy()
    n = round(WINDOW / 0.02)
    x[n : 2 * n] = 0.0  # window 1: a dead channel
    path = tmp_path / "dead.npz"
    write_record(Record(x, 0.02), path)
    from hosid.monitor.run import monitor

    res = monitor(path, tmp_path / "m", window=WINDOW, block_seconds=20.48,
                  analysis="estimate", workers=1, progress=False, echo=lambda s: None)  # fmt: skip
    assert res.tracks.failed == [1]
    rows = [r for r in _rows(tmp_path / "m") if r["start"] == repr(float(WINDOW))]
    assert rows and all(r["status"] != "ok" and r["mean"] == "" for r in rows)
    assert not res.changes


def test_baseline_must_be_a_summary(tmp_path, record, capsys):
    bad = tmp_path / "s.json"
    bad.write_text('{"x": 1}')
    code = main(["monitor", str(record), "--out", str(tmp_path / "o"), "--baseline", str(bad)])
    assert code == 2 and "summary.json" in capsys.readouterr().err
    with pytest.raises(HosidInputError, match="no such file"):
        from hosid.monitor.tracks import read_baseline

        read_baseline(tmp_path / "none.json")


@pytest.mark.parametrize(
    ("after", "kind"),
    [({"a2": 21.0}, "drift"), ({"S0": 150.0}, "excitation")],
)
def test_a_step_is_named_with_its_time_and_size(tmp_path, after, kind):
    """A step of the stiffness (or of the force's level alone) in the middle of 4000 s is
    named as that parameter alone, its time and size intervals holding the truth."""
    from hosid.model.change import Change
    from hosid.monitor.run import monitor

    params = {"a1": 0.5, "n1": 0.5, "a2": 25, "n2": 5, "S0": 100}
    rec = simulate(params, duration=4423.68, dt=0.02, rng=np.random.default_rng(21),
                   change=Change(at=2100.0, after=after))  # fmt: skip
    path = tmp_path / "step.npz"
    write_record(rec, path)
    res = monitor(path, tmp_path / "m", window=WINDOW, block_seconds=20.48, analysis="estimate",
                  workers=1, progress=False, echo=lambda s: None)  # fmt: skip
    ((p, v),) = after.items()
    assert [c.parameter for c in res.changes] == [p]
    c = res.changes[0]
    assert c.time_lo <= 2100.0 <= c.time_hi
    assert c.size_lo <= v - params[p] <= c.size_hi
    assert res.tracks.kinds[p] == kind
    with (tmp_path / "m" / "changes.csv").open() as fh:
        (row,) = list(csv.DictReader(fh))
    assert row["parameter"] == p and row["kind"] == kind and row["role"] == "first"
    # the kept tracks (with each window's correlations) give the same test without a refit
    from hosid.monitor.tracks import Tracks

    kept = Tracks.read(tmp_path / "m")
    np.testing.assert_allclose(kept.corr, res.tracks.corr, rtol=1e-12)
    again = kept.changes(alpha=0.01, level=0.95, seed=0)
    assert [(x.parameter, x.time, x.size) for x in again] == [(c.parameter, c.time, c.size)]
