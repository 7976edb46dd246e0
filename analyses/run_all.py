"""Run every figure script with its full settings into one output directory.

    python analyses/run_all.py                 # all scripts, analyses/out/
    python analyses/run_all.py --jobs 1        # one script at a time (default: 2 at a time)
    python analyses/run_all.py --quick --only fig07_08_contours --out /tmp/x

Each script runs in its own process (``python analyses/<script>.py --out DIR``); the
run stops with a non-zero exit code if any script fails, after the others finish.
Writes ``run_all.log`` (per-script wall time) into the output directory.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

HERE = Path(__file__).resolve().parent
#: Slowest first, so that parallel runs finish together.
SCRIPTS = (
    "diagnose_confusion",
    "beyond_coverage",
    "fig01_02_stiffness",
    "beyond_record_length",
    "fig06_damping_scatter",
    "fig03_restoring_force",
    "beyond_peer_drift",
    "fig04_05_J2_sweep",
    "fig07_08_contours",
    "modelfit_coverage",
    "diagnose_workflow",
)


def run_one(name: str, out: Path, quick: bool, env: dict) -> tuple[str, int, float]:
    cmd = [sys.executable, str(HERE / f"{name}.py"), "--out", str(out)]
    if quick:
        cmd.append("--quick")
    t0 = time.perf_counter()
    with (out / f"{name}.log").open("w") as log:
        rc = subprocess.call(cmd, stdout=log, stderr=subprocess.STDOUT, env=env)
    secs = time.perf_counter() - t0
    print(f"{name}: {'ok' if rc == 0 else f'FAILED (exit {rc})'} in {secs:.0f} s", flush=True)
    return name, rc, secs


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=HERE / "out")
    ap.add_argument(
        "--jobs",
        type=int,
        default=min(2, os.cpu_count() or 1),
        help="scripts run at the same time (default: 2 where there are 2 cores)",
    )
    ap.add_argument("--quick", action="store_true", help="tiny settings (for the tests)")
    ap.add_argument("--only", nargs="+", choices=SCRIPTS, default=list(SCRIPTS))
    a = ap.parse_args(argv)
    a.out.mkdir(parents=True, exist_ok=True)
    env = dict(os.environ)
    if a.jobs > 1:
        env.setdefault("NUMBA_NUM_THREADS", "1")
    t0 = time.perf_counter()
    names = [s for s in SCRIPTS if s in a.only]
    with ThreadPoolExecutor(max_workers=max(1, a.jobs)) as pool:
        done = list(pool.map(lambda n: run_one(n, a.out, a.quick, env), names))
    total = time.perf_counter() - t0
    lines = [f"{n}\t{'ok' if rc == 0 else f'exit {rc}'}\t{s:.0f} s" for n, rc, s in done]
    lines.append(f"total\t\t{total:.0f} s (jobs = {a.jobs})")
    (a.out / "run_all.log").write_text("\n".join(lines) + "\n")
    print(f"all done in {total:.0f} s; outputs in {a.out}")
    failed = [n for n, rc, _ in done if rc]
    if failed:
        print(f"failed: {', '.join(failed)} (see {a.out}/<script>.log)", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
