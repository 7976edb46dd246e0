"""
Condition monitoring: ``hosid monitor``
=======================================

A structure watched for days: is its stiffness still what it was? ``hosid monitor``
follows the parameters over a long record (or a folder of consecutive files, or a file
that keeps growing, ``--follow``), window by window, and names the changes of the
structure or of the excitation with their time and size.

Here a record of 40 000 s (11 hours at 50 Hz) of the paper's oscillator whose linear
stiffness drops by 8 % after 25 000 s. The monitor runs as on the command line,

.. code-block:: console

    hosid simulate --duration 40000 --change-at 25000 --a2-after 23 --seed 4 --out day.npz
    hosid monitor day.npz --out mon/ --analysis estimate --workers 2

with ``--analysis estimate`` (each window's calibrated Laplace posterior, a second a
window) instead of the default emcee fit per window, to stay under a minute; the
monitor study of ``analyses/monitor_study.py`` uses the default.
"""

# %%
# The record and the monitor
# --------------------------
import csv
import subprocess
import sys
import tempfile
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

tmp = tempfile.TemporaryDirectory()
folder = Path(tmp.name)
hosid = [sys.executable, "-m", "hosid"]  # the hosid command of this interpreter


def run(*args):
    """Run a hosid command in the temporary folder and print what it says."""
    done = subprocess.run(
        hosid + list(args), cwd=folder, capture_output=True, text=True, check=True
    )
    print(done.stdout + done.stderr)


run("simulate", "--duration", "40000", "--change-at", "25000", "--a2-after", "23",
    "--seed", "4", "--out", "day.npz")  # fmt: skip
run("monitor", "day.npz", "--out", "mon", "--analysis", "estimate", "--workers", "2",
    "--no-progress")  # fmt: skip
print(sorted(p.name for p in (folder / "mon").iterdir()))

# %%
# The windows, the tracks and the change
# --------------------------------------
# The default window is about a twentieth of the record (between 10 and 100 blocks).
# ``tracks.csv`` holds one row per window and parameter (``start``, ``end``, ``mean``,
# ``sd``, ``q05``, ``q50``, ``q95`` ...); ``changes.csv`` one row per named change: the
# parameter, its time with an interval, its size (after minus before) with an interval,
# and whether it belongs to the structure (``drift``) or to the force (``excitation``).
with open(folder / "mon" / "tracks.csv", newline="") as fh:
    tracks = list(csv.DictReader(fh))
with open(folder / "mon" / "changes.csv", newline="") as fh:
    changes = list(csv.DictReader(fh))
for c in changes:
    print(
        f"{c['parameter']} ({c['kind']}): at {float(c['time']):.0f} s "
        f"[{float(c['time_lo']):.0f}, {float(c['time_hi']):.0f}], "
        f"size {float(c['size']):+.3g} [{float(c['size_lo']):+.3g}, {float(c['size_hi']):+.3g}]"
    )

# %%
# The monitor's own figure is ``mon/tracks.png``; here the same from the CSV files: each
# parameter's window means with their 90 % band, and the named change (its time
# interval shaded). The truth: ``a2`` 25 -> 23 at 25 000 s, nothing else.
params = list(dict.fromkeys(row["parameter"] for row in tracks))
fig, axes = plt.subplots(len(params), 1, figsize=(8, 1.6 * len(params) + 0.6), sharex=True,
                         layout="constrained")  # fmt: skip
for ax, p in zip(axes, params, strict=True):
    rows = [r for r in tracks if r["parameter"] == p and r["mean"]]
    mid = np.array([(float(r["start"]) + float(r["end"])) / 2 for r in rows]) / 3600
    ax.fill_between(mid, [float(r["q05"]) for r in rows], [float(r["q95"]) for r in rows],
                    alpha=0.3, lw=0)  # fmt: skip
    ax.plot(mid, [float(r["mean"]) for r in rows], "o-", ms=3)
    for c in changes:
        if c["parameter"] == p:
            ax.axvline(float(c["time"]) / 3600, color="C3")
            ax.axvspan(
                float(c["time_lo"]) / 3600, float(c["time_hi"]) / 3600, color="C3", alpha=0.15
            )
    ax.axvline(25000 / 3600, color="k", ls=":", lw=1)
    ax.set_ylabel(p)
axes[-1].set_xlabel("time (h); dotted: the true change")

# %%
# What else it does
# -----------------
# A rerun on the same folder resumes at the first unfinished window (each finished one
# is kept in ``mon/windows/``). ``--baseline fit/summary.json`` compares with a
# reference fit, ``--follow`` waits at the end of a growing CSV and prints a line per
# new window. How often the default monitor names a 5 % stiffness loss, a 30 % rise of
# the sea's level, or nothing in a stationary record, is measured by
# ``analyses/monitor_study.py`` (80 records; the *Measured* pages).
tmp.cleanup()
