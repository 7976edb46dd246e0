r"""Power and false alarms of ``hosid diagnose`` on a chain: a hidden cubic spring located
(issue 33, item 3).

The base is an all-linear 2-degree-of-freedom chain (``results/locate_power_base.toml``:
a spring and a dashpot from the ground to ``x1`` and between ``x1`` and ``x2``, ``x2``'s
mass 0.8, both dofs driven at S0 = 2).  The records come from the independent chain
simulator (``independent_chain_sim.py``, BAOAB, not hosid's Heun method), 2000 s at
dt = 0.02, displacements:

- ``clean``: the linear chain itself (what a false alarm is measured on);
- ``cubic_<element>``: the chain with a cubic spring ``n2`` in that element, at each of
  ``--strengths`` (default 2, 3, 5) times the full-state bound sd of ``n2`` at its null
  (:func:`hosid.model.chain_information.bound_from_state`: the linear chain simulated for
  40 000 s with hosid's simulator, ``n2 = 0`` in the extended system, T = 2000 s,
  masses and levels known); the records of one case share their seeds across the
  strengths (common random numbers: the power curve moves with the strength alone).

Each record goes through :func:`hosid.check.locate.locate` with its defaults (the
engine of ``hosid diagnose REC --model BASE.toml``: quadratic damping and cubic stiffness
in each element, Bonferroni at alpha = 0.05 over the pairs of a round, rounds until none
is supported).  A record
counts as located when the cubic spring of the right element is named, as a false alarm
when a clean record names anything.  Two processes; ``results/locate_power.csv`` (every
record's pairs and z) and ``results/locate_power.md``.

    python analyses/locate_power.py                  # 20 records a case and strength, 40 clean
    python analyses/locate_power.py --records 2 --clean 2 --strengths 5   # a quick look
"""

from __future__ import annotations

import argparse
import csv
import math
import multiprocessing
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

import independent_chain_sim  # noqa: E402

from hosid.check.locate import extended, locate  # noqa: E402
from hosid.model.chain import simulate_chain  # noqa: E402
from hosid.model.chain_information import bound_from_state  # noqa: E402
from hosid.model.system import System  # noqa: E402

#: workers are spawned: a forked child of a process that ran OpenMP kernels aborts
SPAWN = multiprocessing.get_context("spawn")

RESULTS = HERE / "results"
SEED = 20261127
BASE = """dofs = ["x1", "x2"]
[[element]]
between = ["ground", "x1"]
terms = ["linear_damping", "linear_stiffness"]
[[element]]
between = ["x1", "x2"]
terms = ["linear_damping", "linear_stiffness"]
[values]
"a1[ground-x1]" = 0.3
"a2[ground-x1]" = 25.0
"a1[x1-x2]" = 0.2
"a2[x1-x2]" = 15.0
"mass[x2]" = 0.8
"S0[x1]" = 2.0
"S0[x2]" = 2.0
"""
#: hidden case -> the element (index) that has the cubic spring
HIDDEN = {"cubic_x1-x2": 1, "cubic_ground-x1": 0}


def base_system() -> System:
    """The all-linear chain with its values (:data:`BASE`)."""
    path = RESULTS / "locate_power_base.toml"
    path.write_text(BASE)
    return System.from_toml(path)


def bound_sd(base: System, k: int, seed: int) -> float:
    """The full-state bound sd of ``n2`` in element ``k`` at ``n2 = 0`` (module docstring)."""
    ext = extended(base, "cubic_stiffness", k)
    values = {**dict(base.values), f"n2[{ext.elements[k].label}]": 0.0}
    th = ext.vector(values)
    _, q, v = simulate_chain(ext, th, duration=40000.0, dt=0.02,
                             rng=np.random.default_rng(seed), return_state=True)  # fmt: skip
    bound = bound_from_state(ext, th, q, v, duration=2000.0)
    return float(bound.sd[f"n2[{ext.elements[k].label}]"])


def one(job: tuple) -> dict:
    """Simulate one record and locate its effect."""
    case, strength, i, truth_values, seed, measured = job
    base = base_system()
    truth = base
    if case != "clean":
        truth = extended(base, "cubic_stiffness", HIDDEN[case])
    rec = independent_chain_sim.simulate(truth, truth.vector(truth_values), duration=2000.0,
                                         dt=0.02, rng=np.random.default_rng(seed),
                                         measured=measured)  # fmt: skip
    t0 = time.perf_counter()
    loc = locate(rec, base)
    first = loc.rounds[0]
    want = None if case == "clean" else f"cubic_stiffness in {truth.elements[HIDDEN[case]].label}"
    named = loc.named_effects
    return {
        "case": case,
        "strength": strength,
        "record": i,
        "named": ";".join(named),
        "right": (not named) if want is None else (named[:1] == [want]),
        "extra": len(named) - (1 if want is not None and named[:1] == [want] else 0),
        "seconds": round(time.perf_counter() - t0, 2),
        **{f"z[{w.label}]": round(w.z, 3) for w in first.weighed},
    }


def main(argv=None) -> list[dict]:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--records", type=int, default=20, help="records a case and strength")
    ap.add_argument("--clean", type=int, default=40, help="clean records")
    ap.add_argument("--strengths", default="2,3,5", help="n2 in bound sds, comma-separated")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--measured", choices=("displacement", "acceleration"),
                    default="displacement", help="what the records' channels hold; "
                    "acceleration: results/locate_power_acceleration.md, .csv")  # fmt: skip
    args = ap.parse_args(argv)
    args.strengths = [float(v) for v in args.strengths.split(",")]
    t0 = time.perf_counter()
    base = base_system()
    seeds = np.random.SeedSequence(SEED)
    sds = {case: bound_sd(base, k, 11 + k) for case, k in HIDDEN.items()}
    jobs = []
    for c, case in enumerate(["clean", *HIDDEN]):
        n = args.clean if case == "clean" else args.records
        seq = seeds.spawn(c + 1)[c].spawn(n)
        for strength in [0.0] if case == "clean" else args.strengths:
            values = dict(base.values)
            if case != "clean":
                label = base.elements[HIDDEN[case]].label
                values[f"n2[{label}]"] = strength * sds[case]
            jobs += [(case, strength, i, values, s, args.measured) for i, s in enumerate(seq)]
    with ProcessPoolExecutor(args.workers, mp_context=SPAWN) as pool:
        rows = list(pool.map(one, jobs))
    write(rows, sds, args, time.perf_counter() - t0)
    return rows


def write(rows: list[dict], sds: dict, args, seconds: float) -> None:
    """``results/locate_power.csv`` and ``.md``."""
    keys = list(dict.fromkeys(k for r in rows for k in r))
    stem = "locate_power" + ("" if args.measured == "displacement" else f"_{args.measured}")
    with open(RESULTS / f"{stem}.csv", "w", newline="") as f:
        w = csv.DictWriter(f, keys)
        w.writeheader()
        w.writerows(rows)
    lines = [
        "# Locating a hidden cubic spring in a 2-dof chain (issue 33, item 3)",
        "",
        f"`python analyses/locate_power.py {' '.join(sys.argv[1:])}`".rstrip() + ": "
        f"independent simulator (BAOAB), 2000 s at dt = 0.02, {args.measured} channels, base "
        "`locate_power_base.toml` (all linear), `hosid.check.locate.locate` with its "
        "defaults (quadratic damping and cubic stiffness in each element, Bonferroni at "
        "alpha = 0.05 over a round's pairs, rounds until none is supported); "
        f"{seconds / 60:.1f} min on {args.workers} processes.",
        "",
        "| case | n2 (bound sd) | n2 | records | located | another pair named too | "
        "a wrong pair named first | nothing named | mean z of the true pair | "
        "mean s a record |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    groups = sorted({(r["case"], r["strength"]) for r in rows},
                    key=lambda g: (["clean", *HIDDEN].index(g[0]), g[1]))  # fmt: skip
    for case, strength in groups:
        rs = [r for r in rows if r["case"] == case and r["strength"] == strength]
        right = sum(r["right"] for r in rs)
        nothing = sum(not r["named"] for r in rs)
        extra = sum(r["right"] and r["extra"] > 0 for r in rs)
        wrong = len(rs) - nothing - (0 if case == "clean" else right)
        if case == "clean":
            zt, v = "-", "0"
        else:
            zt = f"{np.mean([r[f'z[cubic_stiffness in {base_label(case)}]'] for r in rs]):+.2f}"
            v = f"{strength * sds[case]:.4g}"
        secs = np.mean([r["seconds"] for r in rs])
        located = "-" if case == "clean" else right
        lines.append(f"| {case} | {strength:g} | {v} | {len(rs)} | {located} | {extra} | "
                     f"{wrong} | {nothing} | {zt} | {secs:.1f} |")  # fmt: skip
    clean = [r for r in rows if r["case"] == "clean"]
    top = [max(abs(v) for k, v in r.items() if k.startswith("z[")) for r in clean]
    lines += [
        "",
        "located: the first pair named is the cubic spring of the right element; on the "
        "clean records every pair named is a false alarm (a wrong pair).  Bound sd of n2 "
        "at its null: "
        + ", ".join(f"{c} {v:.4g}" for c, v in sds.items())
        + ".  Over the clean records the largest |z| of the four pairs: median "
        f"{np.median(top) if top else math.nan:.2f}.",
    ]
    (RESULTS / f"{stem}.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


def base_label(case: str) -> str:
    """The element label of a hidden case."""
    return case.split("_", 1)[1]


if __name__ == "__main__":
    main()
