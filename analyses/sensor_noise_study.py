r"""The building's twin with its sensors' noise: bias and coverage of the spectral matrix's
estimate (issue 33).

A uniform five-storey shear chain driven at the roof (unit masses, storey stiffness
135.7 and damping 1.5, first mode 0.528 Hz at 1.86 %: the twin of ``building.py``), 409.6 s
of floor accelerations at 20 Hz, each floor with a white noise of the sd the building's
sensors show at its first mode (``NOISE_SD``, from ``building.py``'s twin).  Each record
is estimated with ``sensor_noise = true`` (:mod:`hosid.components.chain_spectral_matrix`)
and its Laplace covariance; per parameter and for the first two modes' frequency and
damping ratio (delta method), the z of the truth, its mean and sd over the records, and
how often the 90 % interval holds the truth.

    python analyses/sensor_noise_study.py [--records 20] [--out results/]
"""

from __future__ import annotations

import argparse
import csv
import math
import time
from collections.abc import Sequence
from pathlib import Path

import numpy as np

import hosid
from hosid.model.linear_chain import modes
from hosid.model.modal import estimate_modes, small_slopes

ROOT = Path(__file__).resolve().parent
DOFS = ("x1", "x2", "x3", "x4", "x5")
DT, DURATION, SEED = 0.05, 409.6, 20261129
#: Each floor's sensor noise sd (m/s^2) on the twin of ``building.py``.
NOISE_SD = (0.0430, 0.0831, 0.0416, 0.0423, 0.1770)
STIFFNESS, DAMPING, LEVEL = 135.7, 1.5, 1e-3
Z90 = 1.6448536269514722


def twin() -> hosid.System:
    """The twin's system with its values (module docstring)."""
    values = {f"N[{d}]": sd**2 * DT / (2 * math.pi) for d, sd in zip(DOFS, NOISE_SD, strict=True)}
    elements = []
    for a, b in zip(("ground", *DOFS[:-1]), DOFS, strict=True):
        elements.append(((a, b), ("linear",)))
        values |= {f"a1[{a}-{b}]": DAMPING, f"a2[{a}-{b}]": STIFFNESS}
    values |= {f"mass[{d}]": 1.0 for d in DOFS[1:]} | {"S0[x5]": LEVEL}
    return hosid.System(DOFS, elements, driven=("x5",), measured="acceleration",
                        sensor_noise=True, excitation="white", values=values)  # fmt: skip


def modal(system, theta) -> np.ndarray:
    """The first two modes' frequencies (Hz) and damping ratios."""
    m = modes(system, theta)
    return np.r_[m.frequency_hz[:2], m.zeta[:2]]


def one(system, k: int) -> dict:
    """The z of every quantity on record ``k``."""
    truth = system.vector()
    seed = np.random.SeedSequence([SEED, k])
    rec = hosid.simulate_chain(system, duration=DURATION, dt=DT, rng=np.random.default_rng(seed))
    t0 = time.perf_counter()
    est = hosid.estimate(rec, system)
    sd = np.sqrt(np.diag(est.cov))
    got = estimate_modes(system, est.theta, est.cov, small_slopes(system))[:2]
    mean = np.array([m[k]["mean"] for k in ("frequency_hz", "damping_ratio") for m in got])
    msd = np.array([m[k]["sd"] for k in ("frequency_hz", "damping_ratio") for m in got])
    z = np.r_[(est.theta - truth) / sd, (mean - modal(system, truth)) / msd]
    return {"record": k, "seconds": time.perf_counter() - t0, "z": z}


def main(argv: Sequence[str] | None = None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--records", type=int, default=20)
    ap.add_argument("--out", type=Path, default=ROOT / "results")
    a = ap.parse_args(argv)
    system = twin()
    names = [*system.param_names, "f1", "f2", "zeta1", "zeta2"]
    runs = []
    for k in range(a.records):
        runs.append(one(system, k))
        print(f"record {k}: {runs[-1]['seconds']:.0f} s", flush=True)
    Z = np.array([r["z"] for r in runs])
    rows = [{"quantity": n, "mean_z": float(Z[:, i].mean()), "sd_z": float(Z[:, i].std(ddof=1)),
             "cover90": float(np.mean(np.abs(Z[:, i]) < Z90))}
            for i, n in enumerate(names)]  # fmt: skip
    a.out.mkdir(parents=True, exist_ok=True)
    with (a.out / "sensor_noise.csv").open("w", newline="") as fh:
        w = csv.DictWriter(fh, list(rows[0]), lineterminator="\n")
        w.writeheader()
        w.writerows(rows)
    drift = [r for r in rows if r["quantity"][:2] in ("a1", "a2")]
    L = ["# The building's twin with its sensors' noise: the spectral matrix's estimate", "",
         f"`python analyses/sensor_noise_study.py --records {a.records}`: {a.records} records "
         f"of {DURATION} s, `hosid.estimate` with `sensor_noise = true`, Laplace intervals "
         f"(median {np.median([r['seconds'] for r in runs]):.0f} s a record). z: (estimate - "
         "truth) / sd.", "",
         "| quantity | mean z | sd z | 90 % cover |", "|---|---|---|---|"]  # fmt: skip
    L += [f"| {r['quantity']} | {r['mean_z']:+.2f} | {r['sd_z']:.2f} | {r['cover90']:.2f} |"
          for r in rows]  # fmt: skip
    L += [
        "",
        f"Storeys' coefficients pooled: 90 % cover "
        f"{np.mean([r['cover90'] for r in drift]):.3f} over {len(drift)} x {a.records}.",
    ]
    (a.out / "sensor_noise.md").write_text("\n".join(L) + "\n")
    print("\n".join(L))
    return {"rows": rows, "runs": runs}


if __name__ == "__main__":
    main()
