"""Throughput and memory of ``hosid monitor`` on one day at 50 Hz (4.32 million samples).

Simulates a day of the paper oscillator at dt = 0.02 s (seed 7; written as CSV, the
format an operator's logger gives; about 110 MB), then times, each as its own process
with the peak resident memory of its whole process tree (the command, the dask
scheduler and its workers, sampled every 0.2 s with psutil):

* the baseline: ``hosid batch fit`` of one window cut from the same record (a 2048 s
  record: the monitor's default window on this record), with ``--workers 1``;
* ``hosid monitor DAY.csv --out DIR --workers 2`` with its defaults.

It prints both, the monitor's time over the baseline's times the number of windows
(the share of ideal serial cost; 0.5 is perfect use of 2 workers) and its memory over
the baseline's.  The issue asks for under 10 minutes and under 2 GB.

    python benchmarks/monitor_day.py                  # one day
    python benchmarks/monitor_day.py --hours 2        # a quick look
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Sequence
from pathlib import Path

import numpy as np

import hosid
from hosid.record import Record, write_record

HOSID = [sys.executable, "-m", "hosid"]


def tree_rss(pid: int) -> int:
    """Resident memory (bytes) of a process and all its descendants."""
    import psutil

    try:
        proc = psutil.Process(pid)
        procs = [proc, *proc.children(recursive=True)]
    except psutil.NoSuchProcess:
        return 0
    total = 0
    for p in procs:
        try:
            total += p.memory_info().rss
        except psutil.NoSuchProcess:
            pass
    return total


def timed(cmd: Sequence[str]) -> tuple[float, int, str]:
    """Wall time, peak process-tree memory and output of ``cmd``."""
    t0 = time.perf_counter()
    p = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    peak = [0]

    def watch() -> None:
        while p.poll() is None:
            peak[0] = max(peak[0], tree_rss(p.pid))
            time.sleep(0.2)

    th = threading.Thread(target=watch, daemon=True)
    th.start()
    out, _ = p.communicate()
    th.join()
    if p.returncode:
        raise SystemExit(f"{' '.join(cmd)} failed ({p.returncode}):\n{out}")
    return time.perf_counter() - t0, peak[0], out


def main(argv: Sequence[str] | None = None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--hours", type=float, default=24.0)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--keep", type=Path, default=None, help="folder to keep the files in")
    args = ap.parse_args(argv)
    load0 = os.getloadavg()
    with tempfile.TemporaryDirectory() as tmp:
        folder = args.keep or Path(tmp)
        folder.mkdir(parents=True, exist_ok=True)
        day = folder / "day.csv"
        t0 = time.perf_counter()
        rec = hosid.simulate(hosid.PAPER_PARAMS, duration=args.hours * 3600, dt=0.02,
                             rng=np.random.default_rng(7))  # fmt: skip
        write_record(rec, day)
        one = folder / "one.npz"
        write_record(Record(rec.x[: round(2048 / 0.02)], 0.02), one)
        n = rec.n
        del rec
        sim = time.perf_counter() - t0
        base = [*HOSID, "batch", "fit", str(one), "--out", str(folder / "one")]
        base_t, base_m, _ = timed([*base, "--workers", "1", "--no-progress"])
        mon = [*HOSID, "monitor", str(day), "--out", str(folder / "mon")]
        mon_t, mon_m, out = timed([*mon, "--workers", str(args.workers), "--no-progress"])
    done = [ln for ln in out.splitlines() if ln[:1].isdigit() and " windows (" in ln]
    windows = int(done[-1].split()[0]) if done else 0
    res = {
        "samples": n,
        "simulate_and_write_s": sim,
        "baseline_fit_s": base_t,
        "baseline_peak_GB": base_m / 1e9,
        "monitor_s": mon_t,
        "monitor_peak_GB": mon_m / 1e9,
        "windows": windows,
        "time_share_of_serial": mon_t / (windows * base_t) if windows else float("nan"),
        "memory_ratio": mon_m / base_m,
        "load_before": load0,
    }
    for k, v in res.items():
        print(f"{k:24s} {v}")
    print(done[-1] if done else out)
    return res


if __name__ == "__main__":
    main()
