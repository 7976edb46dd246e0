"""hosid batch end to end on 12 records of 2000 s (slow: about 10 minutes on 2 cores).

The checks of issue 14, with the command line as a user runs it:

* ``--workers 1`` and ``--workers 2`` give identical results tables (every column but the
  times, to the last digit);
* a ``dask scheduler`` and two ``dask worker`` processes started by hand give the same
  table;
* a corrupt record gets an error row and every other record its result;
* a batch killed (SIGKILL) halfway and rerun finishes with every record done once, the
  rerun skipping the finished ones.
"""

import csv
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

import hosid
from hosid.batch.table import TIMES
from hosid.record import write_record

pytestmark = pytest.mark.slow

BIN = Path(sys.executable).parent
N_RECORDS = 12


def _table(out: Path) -> list[dict]:
    with (out / "results.csv").open() as fh:
        return [{k: v for k, v in r.items() if k not in TIMES} for r in csv.DictReader(fh)]


def _hosid(*args: str, **kwargs) -> subprocess.CompletedProcess:
    return subprocess.run(
        [str(BIN / "hosid"), *args], capture_output=True, text=True, check=False, **kwargs
    )


@pytest.fixture(scope="module")
def batch(tmp_path_factory):
    """12 paper-oscillator records (2000 s, dt 0.02) and a corrupt one, as a manifest."""
    folder = tmp_path_factory.mktemp("records")
    for i in range(N_RECORDS):
        rec = hosid.simulate(
            hosid.PAPER_PARAMS, duration=2000.0, dt=0.02, rng=np.random.default_rng(100 + i)
        )
        write_record(rec, folder / f"rec{i:02d}.npz")
    (folder / "corrupt.csv").write_text("t,x\n0,0.1\n0.02,0.2\n0.04,abc\n")
    manifest = folder / "batch.txt"
    manifest.write_text("rec*.npz\ncorrupt.csv\n")
    return manifest


@pytest.fixture(scope="module")
def one_worker(batch, tmp_path_factory):
    out = tmp_path_factory.mktemp("w1") / "out"
    r = _hosid("batch", "fit", str(batch), "--out", str(out), "--workers", "1", "--seed", "5")
    assert r.returncode == 0, r.stderr
    return _table(out)


def test_two_workers_same_table_and_error_row(batch, one_worker, tmp_path):
    rows = one_worker
    assert len(rows) == N_RECORDS + 1
    assert [r["status"] for r in rows] == ["ok"] * N_RECORDS + ["error"]
    assert "corrupt.csv" in rows[-1]["message"]
    out = tmp_path / "out"
    r = _hosid("batch", "fit", str(batch), "--out", str(out), "--workers", "2", "--seed", "5")
    assert r.returncode == 0, r.stderr
    assert _table(out) == rows


def test_hand_started_cluster_same_table(batch, one_worker, tmp_path):
    sf = tmp_path / "scheduler.json"
    procs = [
        subprocess.Popen(
            [
                str(BIN / "dask"),
                "scheduler",
                "--scheduler-file",
                str(sf),
                "--no-dashboard",
                "--port",
                "0",
            ],
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
        )
    ]
    try:
        for _ in range(600):
            if sf.is_file() and sf.stat().st_size:
                break
            time.sleep(0.1)
        for _ in range(2):
            procs.append(
                subprocess.Popen(
                    [
                        str(BIN / "dask"),
                        "worker",
                        "--scheduler-file",
                        str(sf),
                        "--nthreads",
                        "1",
                        "--no-dashboard",
                    ],
                    stdout=subprocess.DEVNULL,
                    stderr=subprocess.DEVNULL,
                )
            )
        address = json.loads(sf.read_text())["address"]
        out = tmp_path / "out"
        r = _hosid(
            "batch", "fit", str(batch), "--out", str(out), "--scheduler", address, "--seed", "5"
        )
        assert r.returncode == 0, r.stderr
        assert _table(out) == one_worker
    finally:
        for p in reversed(procs):
            p.terminate()
        for p in procs:
            p.wait(timeout=30)


def test_killed_halfway_and_rerun(batch, one_worker, tmp_path):
    out = tmp_path / "out"
    cmd = [
        str(BIN / "hosid"),
        "batch",
        "fit",
        str(batch),
        "--out",
        str(out),
        "--workers",
        "2",
        "--seed",
        "5",
    ]
    proc = subprocess.Popen(
        cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True
    )
    try:
        while len(list((out / "tasks").glob("*.json"))) < N_RECORDS // 2:
            assert proc.poll() is None, "the batch ended before half of it was done"
            time.sleep(0.2)
        proc.send_signal(signal.SIGKILL)
        proc.wait(timeout=30)
    finally:
        try:
            os.killpg(proc.pid, signal.SIGKILL)  # the workers, should any outlive it
        except ProcessLookupError:
            pass
    done = len(list((out / "tasks").glob("*.json")))
    assert N_RECORDS // 2 <= done < N_RECORDS
    r = _hosid(*cmd[1:], "--no-progress")
    assert r.returncode == 0, r.stderr
    assert f"({done} done before, {N_RECORDS - done} run now" in r.stdout
    assert len(list((out / "tasks").glob("*.json"))) == N_RECORDS
    assert _table(out) == one_worker
