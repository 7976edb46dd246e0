r"""A system driven by a narrow-band force: the shaped force's estimate against the white one's.

A two-dof chain (modes 2.4 and 5.9 rad/s) driven at its top by white noise through the
shaping filter :math:`\omega_f = 4` rad/s, :math:`\zeta_f = 0.3` (between its modes), each
acceleration channel with a white sensor noise (:math:`N = 0.01`), 2000 s at 20 Hz: the
records of ``tests/test_system_excitation.py``, with seeds of their own.  Each record is
estimated with the force's shape (``excitation = "narrowband_excitation"``) and with a
white force (the sensors' noise modelled in both: the channels' spectral matrix), and each
parameter's and each mode's z (estimate minus truth over its Laplace sd; the modes by the
delta method, :func:`hosid.model.modal.estimate_modes`) is kept: its mean and sd over the
records and the share of 90 % intervals holding the truth.  Only the estimate is measured
(a fit of each record would take minutes more).

    python analyses/system_excitation_study.py [--records 20]   # results/system_excitation.md
"""

from __future__ import annotations

import argparse
import csv
import dataclasses
import time
from collections.abc import Sequence
from pathlib import Path

import numpy as np

import hosid
from hosid.model.modal import estimate_modes, small_slopes

ROOT = Path(__file__).resolve().parent
SEED = 20261129
DURATION, DT = 2000.0, 0.05
Z90 = 1.6448536269514729
ELEMENTS = [(("ground", "x1"), ("linear",)), (("x1", "x2"), ("linear",))]
VALUES = {
    "a1[ground-x1]": 0.3, "a2[ground-x1]": 20.0, "a1[x1-x2]": 0.2, "a2[x1-x2]": 10.0,
    "mass[x2]": 0.8, "S0[x2]": 1.0, "wf": 4.0, "zf": 0.3, "N[x1]": 0.01, "N[x2]": 0.01,
}  # fmt: skip
MODAL = ("f1", "f2", "zeta1", "zeta2")


def systems() -> tuple[hosid.System, hosid.System]:
    """The shaped chain with its values, and the white one to estimate with."""
    shaped = hosid.System(("x1", "x2"), ELEMENTS, driven=("x2",), measured="acceleration",
                          sensor_noise=True, excitation="narrowband_excitation",
                          values=VALUES)  # fmt: skip
    return shaped, dataclasses.replace(shaped, excitation=(), values=())


def modal(system, theta, cov) -> tuple[np.ndarray, np.ndarray]:
    """The first two modes' frequencies (Hz) and damping ratios, and their sds (NaN for a
    mode the estimate does not have: overdamped)."""
    keys = ("frequency_hz", "damping_ratio")
    got = estimate_modes(system, theta, cov, small_slopes(system))[:2]
    got += [{k: {"mean": np.nan, "sd": np.nan} for k in keys}] * (2 - len(got))
    return (np.array([m[k]["mean"] for k in keys for m in got]),
            np.array([m[k]["sd"] for k in keys for m in got]))  # fmt: skip


def one(shaped, white, k: int) -> dict:
    """The z of every quantity on record ``k``, under the shaped and the white force."""
    rng = np.random.default_rng(np.random.SeedSequence([SEED, k]))
    rec = hosid.simulate_chain(shaped, duration=DURATION, dt=DT, rng=rng)
    truth = shaped.vector()
    true_modes = modal(shaped, truth, np.zeros((truth.size, truth.size)))[0]
    out = {"record": k}
    for name, system in (("shaped", dataclasses.replace(shaped, values=())), ("white", white)):
        t0 = time.perf_counter()
        est = hosid.estimate(rec, system)
        mean, sd = modal(system, est.theta, est.cov)
        keep = [shaped.index(n) for n in system.param_names]
        z = (est.theta - truth[keep]) / np.sqrt(np.diag(est.cov))
        out[name] = dict(zip([*system.param_names, *MODAL], np.r_[z, (mean - true_modes) / sd],
                             strict=True))  # fmt: skip
        out[f"{name}_seconds"] = time.perf_counter() - t0
    return out


def table(runs: list[dict]) -> list[dict]:
    """Per force model and quantity: mean and sd of z, and 90 % coverage."""
    rows = []
    for model in ("shaped", "white"):
        for q in runs[0][model]:
            z = np.array([r[model][q] for r in runs])
            z = z[np.isfinite(z)]  # a mode the estimate lacks (overdamped) is left out
            rows.append({"model": model, "quantity": q, "records": int(z.size),
                         "mean_z": float(np.mean(z)) if z.size else float("nan"),
                         "sd_z": float(np.std(z, ddof=1)) if z.size > 1 else float("nan"),
                         "cover90": float(np.mean(np.abs(z) < Z90))})  # fmt: skip
    return rows


def write(rows: list[dict], runs: list[dict], out: Path) -> Path:
    """``system_excitation.csv`` and ``.md``."""
    out.mkdir(parents=True, exist_ok=True)
    with (out / "system_excitation.csv").open("w", newline="") as fh:
        w = csv.DictWriter(fh, list(rows[0]), lineterminator="\n")
        w.writeheader()
        w.writerows(rows)
    secs = {m: np.mean([r[f"{m}_seconds"] for r in runs]) for m in ("shaped", "white")}
    L = ["# A two-dof chain under a narrow-band force: shaped against white (estimates)", "",
         f"`python analyses/system_excitation_study.py --records {len(runs)}`: {len(runs)} "
         f"records of {DURATION:.0f} s, seed {SEED}; mean estimate time {secs['shaped']:.0f} s "
         f"(shaped), {secs['white']:.0f} s (white). z = (estimate - truth) / Laplace sd "
         "(modes: delta method); cover90 the share of |z| < 1.645; records: those where the "
         "estimate has the mode (underdamped).", "",
         "| model | quantity | records | mean z | sd z | cover90 |",
         "|---|---|---|---|---|---|"]  # fmt: skip
    L += [f"| {r['model']} | {r['quantity']} | {r['records']} | {r['mean_z']:+.2f} | "
          f"{r['sd_z']:.2f} | {r['cover90']:.2f} |" for r in rows]  # fmt: skip
    (out / "system_excitation.md").write_text("\n".join(L) + "\n")
    return out / "system_excitation.md"


def main(argv: Sequence[str] | None = None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--records", type=int, default=20)
    ap.add_argument("--out", type=Path, default=ROOT / "results")
    a = ap.parse_args(argv)
    shaped, white = systems()
    runs = []
    for k in range(a.records):
        runs.append(one(shaped, white, k))
        print(f"record {k}: {runs[-1]['shaped_seconds']:.0f} s", flush=True)
    rows = table(runs)
    print(write(rows, runs, a.out).read_text())
    return {"rows": rows, "runs": runs}


if __name__ == "__main__":
    main()
