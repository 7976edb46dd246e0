r"""The information limit of 2- and 3-degree-of-freedom chains (issue 32, item 6).

With the whole state observed continuously for T = 2000 s, the Fisher matrix of the
element coefficients is I = T sum_{d driven} E[Phi_d Phi_d^T] / (2 pi S0_d), the masses
and force levels known (:mod:`hosid.model.chain_information`); E is estimated from one
long simulation (hosid's chain simulator, dt = 0.02, 10 sub-steps; 40 000 s = 20 T),
with a jackknife over 20 consecutive batches for the Monte Carlo error of each sd.

The systems (also written as system files beside the results):

- ``chain2``: x1 on the ground through the paper's element (a1 0.3, n1 0.1, a2 25,
  n2 5), x2 on x1 through a hardening spring with viscous damping (a1 0.2, a2 15,
  n2 10); m2 = 0.8; both driven, S0 = 2.
- ``chain3``: ``chain2`` plus x3 on x2 through a spring with viscous and quadratic
  damping (a1 0.2, n1 0.1, a2 10); m3 = 0.6; all driven, S0 = 2.

At S0 = 2 the nonlinear terms carry a large share of their elements' forces (quadratic
damping 60-80 % of the equivalent damping a1 + n1 sqrt(8/pi) sd(r'), cubic stiffness
adding 35-115 % to the linear one at the rms relative displacement, 3 n2 var(r) / a2)
while the modes stay apart: linear modes 3.1 and 7.0 rad/s
(chain2), 2.3, 5.3 and 7.4 rad/s (chain3), equivalent-linear ones below 10 rad/s, all
under a tenth of the Nyquist frequency (15.7 rad/s).  ``paper`` (the single oscillator
at S0 = 100 through the one-element chain) checks the path against NOTES.md.

    python analyses/chain_bound.py                 # -> results/chain_bound.md, .csv
    python analyses/chain_bound.py --quick --out D # the tests' tiny settings
"""

from __future__ import annotations

import argparse
import csv
import math
import time
import tomllib
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from hosid.model.chain import simulate_chain
from hosid.model.chain_information import bound_from_state
from hosid.model.linear_chain import modes
from hosid.model.system import System
from hosid.model.system_file import system_from_dict

RESULTS = Path(__file__).resolve().parent / "results"
PAPER = {"a1": 0.5, "n1": 0.5, "a2": 25.0, "n2": 5.0, "S0": 100.0}
#: NOTES.md, last section: sd of a1, n1, a2, n2 of the paper oscillator, S0 = 100, T = 2000 s.
NOTES = (0.221, 0.0192, 0.90, 0.236)

_BASE = """
[[element]]
between = ["ground", "x1"]
terms = ["linear_damping", "quadratic_damping", "linear_stiffness", "cubic_stiffness"]

[[element]]
between = ["x1", "x2"]
terms = ["linear_damping", "linear_stiffness", "cubic_stiffness"]
"""
_BASE_VALUES = """
"a1[ground-x1]" = 0.3
"n1[ground-x1]" = 0.1
"a2[ground-x1]" = 25.0
"n2[ground-x1]" = 5.0
"a1[x1-x2]" = 0.2
"a2[x1-x2]" = 15.0
"n2[x1-x2]" = 10.0
"mass[x2]" = 0.8
"S0[x1]" = 2.0
"S0[x2]" = 2.0
"""
SYSTEMS = {
    "chain2": 'dofs = ["x1", "x2"]\n' + _BASE + "\n[values]" + _BASE_VALUES,
    "chain3": 'dofs = ["x1", "x2", "x3"]\n'
    + _BASE
    + """
[[element]]
between = ["x2", "x3"]
terms = ["linear_damping", "quadratic_damping", "linear_stiffness"]

[values]"""
    + _BASE_VALUES
    + """"a1[x2-x3]" = 0.2
"n1[x2-x3]" = 0.1
"a2[x2-x3]" = 10.0
"mass[x3]" = 0.6
"S0[x3]" = 2.0
""",
}
FIELDS = (
    "system", "coefficient", "value", "sd", "sd_se", "rel_sd",
    "duration", "dt", "sim_duration", "seed",
)  # fmt: skip


def system(name: str) -> System:
    """The system ``name`` (``paper`` or a key of :data:`SYSTEMS`) with its values."""
    if name == "paper":
        return System.single("paper", PAPER)
    return system_from_dict(tomllib.loads(SYSTEMS[name]), name)


def equivalent(s: System, q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Gaussian-equivalent linear values: a1 + n1 sqrt(8/pi) sd(r'), a2 + 3 n2 var(r)."""
    th = s.vector()
    B = s.incidence
    sr, srd = (q @ B.T).std(axis=0), (v @ B.T).std(axis=0)
    eq = th.copy()
    cols = s.columns
    for c, (e, t) in enumerate(cols):
        lin = {"quadratic_damping": "linear_damping", "cubic_stiffness": "linear_stiffness"}
        if t.name in lin:
            i = next(k for k, (e2, t2) in enumerate(cols) if e2 == e and t2.name == lin[t.name])
            gain = (
                math.sqrt(8 / math.pi) * srd[e]
                if t.name == "quadratic_damping"
                else 3 * sr[e] ** 2
            )
            eq[i] += th[c] * gain
    return eq


def compute(name: str, *, seed: int, sim_duration: float, duration: float, dt: float) -> dict:
    """The bound of one system: rows (one a coefficient) and the system's description."""
    t0 = time.perf_counter()
    s = system(name)
    key = ["paper", *SYSTEMS].index(name)
    rng = np.random.default_rng(np.random.SeedSequence(seed).spawn(key + 1)[key])
    _, q, v = simulate_chain(
        s, duration=sim_duration, dt=dt, rng=rng, measured="displacement", return_state=True
    )
    bound = bound_from_state(s, s.vector(), q, v, duration=duration)
    th = s.vector()
    sd, se = bound.sd, bound.sd_se
    rows = [
        {
            "system": name,
            "coefficient": c,
            "value": th[k],
            "sd": sd[c],
            "sd_se": se[k],
            "rel_sd": sd[c] / abs(th[k]),
            "duration": duration,
            "dt": dt,
            "sim_duration": sim_duration,
            "seed": seed,
        }
        for k, c in enumerate(bound.names)
    ]
    corr = bound.cov / np.sqrt(np.outer(np.diag(bound.cov), np.diag(bound.cov)))
    np.fill_diagonal(corr, 0.0)
    i, j = np.unravel_index(np.argmax(np.abs(corr)), corr.shape)
    lin, eqv = modes(s), modes(s, equivalent(s, q, v))
    return {
        "rows": rows,
        "linear": (lin.omega, lin.zeta),
        "equivalent": (eqv.omega, eqv.zeta),
        "sigma": (bound.sigma_q, bound.sigma_v),
        "corr": (bound.names[i], bound.names[j], float(corr[i, j])),
        "seconds": time.perf_counter() - t0,
    }


def _fmt(values) -> str:
    return ", ".join(f"{x:.3g}" for x in values)


def write(results: dict, out: Path, *, sim_duration: float, seed: int, argv: str) -> None:
    """``chain_bound.csv`` (one row a coefficient), ``chain_bound.md``, the system files."""
    out.mkdir(parents=True, exist_ok=True)
    with (out / "chain_bound.csv").open("w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=FIELDS)
        w.writeheader()
        for r in results.values():
            w.writerows(r["rows"])
    for name, text in SYSTEMS.items():
        (out / f"chain_bound_{name}.toml").write_text(text.lstrip())
    text = [
        "# Information limit of the chains (full state observed)",
        "",
        f"`python analyses/chain_bound.py{argv}` (seed {seed}). I = T sum over driven dofs "
        "of E[Phi_d Phi_d^T] / (2 pi S0_d): the whole state (q, q') observed continuously "
        "for T = 2000 s, masses and force levels known (hosid.model.chain_information). "
        f"E from one simulation of {sim_duration:g} s at dt = 0.02 (hosid's chain "
        "simulator, 10 Heun sub-steps). sd = sqrt(diag I^-1); MC se: jackknife over 20 "
        "consecutive batches. Systems: `chain_bound_chain2.toml`, `chain_bound_chain3.toml` "
        "(module docstring of analyses/chain_bound.py).",
        "",
        "| system | coefficient | value | sd | sd / value | MC se of sd |",
        "|---|---|---|---|---|---|",
    ]
    for r in results.values():
        for row in r["rows"]:
            text.append(
                f"| {row['system']} | {row['coefficient']} | {row['value']:g} | "
                f"{row['sd']:.3g} | {row['rel_sd']:.3g} | {row['sd_se']:.2g} |"
            )
    text += ["", "## The systems' response", ""]
    text += ["| system | sd q | sd q' | linear modes (rad/s; zeta) | equivalent-linear modes "
             "| largest corr |", "|---|---|---|---|---|---|"]  # fmt: skip
    for name, r in results.items():
        (w0, z0), (w1, z1), (sq, sv) = r["linear"], r["equivalent"], r["sigma"]
        a, b, c = r["corr"]
        text.append(
            f"| {name} | {_fmt(sq)} | {_fmt(sv)} | {_fmt(w0)}; {_fmt(z0)} | {_fmt(w1)}; "
            f"{_fmt(z1)} | {a}, {b}: {c:.2f} |"
        )
    if "paper" in results:
        got = [row["sd"] for row in results["paper"]["rows"]]
        text += [
            "",
            "Equivalent-linear: a1 + n1 sqrt(8/pi) sd(r'), a2 + 3 n2 var(r) per element at the "
            "simulated sds. Check: the paper oscillator (S0 = 100) as the one-element chain, "
            f"sd a1, n1, a2, n2 = {_fmt(got)}; NOTES.md: {_fmt(NOTES)}.",
        ]
    (out / "chain_bound.md").write_text("\n".join(text) + "\n")


def main(argv: Sequence[str] | None = None) -> dict:
    """Compute the bounds and write the results."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--systems", nargs="+", default=["paper", *SYSTEMS])
    ap.add_argument("--seed", type=int, default=20260320)
    ap.add_argument("--sim-duration", type=float, default=40000.0)
    ap.add_argument("--quick", action="store_true", help="300 s simulations (the tests')")
    ap.add_argument("--out", type=Path, default=RESULTS)
    args = ap.parse_args(argv)
    sim = 300.0 if args.quick else args.sim_duration
    results = {}
    for name in args.systems:
        results[name] = compute(name, seed=args.seed, sim_duration=sim, duration=2000.0, dt=0.02)
        sds = ", ".join(f"{r['coefficient']} {r['sd']:.3g}" for r in results[name]["rows"])
        print(f"{name}: {sds} ({results[name]['seconds']:.1f} s)", flush=True)
    shown = " --quick" if args.quick else ""
    write(results, args.out, sim_duration=sim, seed=args.seed, argv=shown)
    return results


if __name__ == "__main__":
    main()
