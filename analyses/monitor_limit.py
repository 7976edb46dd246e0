r"""The change test at the information limit (issue 31): how often could *any* window fit
name a 5 % loss of stiffness, given the windows' Cramer-Rao bound?

``monitor_study.py`` measures ``hosid monitor`` on simulated 40 000 s records.  This
analysis replaces each window's posterior by an oracle: a Gaussian estimate centred on
the window's true parameters (the mixture :math:`\theta_0 + f_i(\tau)(\theta_1 - \theta_0)`
of a window straddling the step, :func:`hosid.monitor.changes.share_after`) with the
full-state Cramer-Rao covariance of a window of that length
(:func:`hosid.model.information.cramer_rao`, at the parameters before and after the
step, mixed alike), divided by ``--efficiency``.  The windows are the monitor's defaults
on these records: back to back, and on the ship's records a last one ending with the
record that overlaps the one before; errors of overlapping windows are correlated as the
change test assumes (:func:`hosid.monitor.changes.overlap_correlation`), others
independent.  The same change test
(:func:`hosid.monitor.joint.joint_changes`, default alpha and level) then runs on these
tracks.  Windows estimated at the bound are the best this test can be given: at
efficiency 1 the oracle's rates are, up to the Gaussian approximation, the most
``monitor_study.py`` could show with these windows and change times.

Cases, as in ``monitor_study.py``: the paper oscillator (20 windows of 1986.56 s) and
the ship-roll-like one (10 of 4096 s, the last from 35 904 s); an a2 step of -5 % at a
time uniform in [20 000, 36 000] s; a2 steps of K bound-sd of one window; stationary
records.  S0 is left out: the full state fixes it exactly.

    python analyses/monitor_limit.py                  # -> results/monitor/limit.md, .csv
    python analyses/monitor_limit.py --efficiency 0.8 --cases paper_a2 ship_a2
                                                      # -> limit-efficiency0.8.md, .csv
"""

from __future__ import annotations

import argparse
import csv
import multiprocessing
import sys
import time
from collections.abc import Sequence
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from monitor_study import CHANGE_BETWEEN, DURATION, SEED, SYSTEMS, WINDOW  # noqa: E402

from hosid.model.information import cramer_rao  # noqa: E402
from hosid.monitor.changes import overlap_correlation, share_after  # noqa: E402
from hosid.monitor.joint import joint_changes  # noqa: E402
from hosid.monitor.source import Piece  # noqa: E402
from hosid.monitor.windows import Layout, windows  # noqa: E402

#: workers are spawned: a forked child of a process that ran OpenMP kernels aborts
SPAWN = multiprocessing.get_context("spawn")

RESULTS = HERE / "results" / "monitor"
#: a2's relative step of the Done-when, and the power curve's steps in bound-sd per window
LOSS = 0.05
SIZES = (1.0, 2.0, 3.0, 4.0)
#: the long simulation of the bound (s)
SIM_DURATION = 80000.0
FIELDS = ["case", "system", "size_sd", "step_sd", "records", "efficiency", "named", "first",
          "alone", "time_in", "size_in", "any", "wrong_first", "seconds"]  # fmt: skip


def bound(system: str, a2: float, rng, sim_duration) -> tuple[list[str], np.ndarray]:
    """The drift coefficients' names and their bound for one window at linear stiffness
    ``a2`` (from a simulation of ``sim_duration`` s)."""
    params, dt = SYSTEMS[system]
    b = cramer_rao("paper", {**params, "a2": a2}, duration=WINDOW[system], rng=rng, dt=dt,
                   sim_duration=sim_duration)  # fmt: skip
    return list(b.names), b.cov


def layout(system: str) -> tuple[np.ndarray, np.ndarray]:
    """The monitor's default windows over a record of this system (its own rule,
    :func:`hosid.monitor.windows.windows`: back to back, and a last one ending with the
    record where at least a quarter window is left)."""
    dt = SYSTEMS[system][1]
    samples = round(WINDOW[system] / dt)
    piece = Piece(0.0, np.zeros(round(DURATION / dt)), True)
    ws = list(windows([piece], Layout(samples, samples, dt, WINDOW[system] / 24)))
    return np.array([w.start for w in ws]), np.array([w.end for w in ws])


def one_case(case: str, system: str, size_sd: float | None, records: int, efficiency: float,
             key: int, sim_duration: float = SIM_DURATION) -> dict:  # fmt: skip
    """Rates of one case over ``records`` oracle records (``size_sd`` None: the -5 % step;
    0: stationary); the bound from a simulation of ``sim_duration`` s."""
    t0 = time.perf_counter()
    params, _ = SYSTEMS[system]
    rng = np.random.default_rng(np.random.SeedSequence(SEED, spawn_key=(900, key)))
    a2 = params["a2"]
    names, c0 = bound(system, a2, rng, sim_duration)
    ia = names.index("a2")
    step = -LOSS * a2 if size_sd is None else -size_sd * float(np.sqrt(c0[ia, ia]))
    c1 = bound(system, a2 + step, rng, sim_duration)[1] if step else c0
    starts, ends = layout(system)
    n = starts.size
    rho = overlap_correlation(starts, ends)
    th0 = np.array([params[k] for k in names])
    th1 = th0.copy()
    th1[ia] += step
    counts = dict.fromkeys(FIELDS[6:13], 0)
    for _ in range(records):
        tau = float(rng.uniform(*CHANGE_BETWEEN))
        f = share_after(starts, ends, tau) if step else np.zeros(n)
        C = np.array([((1 - fi) * c0 + fi * c1) / efficiency for fi in f])
        L = np.linalg.cholesky(C)
        full = np.einsum("ij,iab,jcb->iajc", rho, L, L).reshape(n * len(names), -1)
        noise = (np.linalg.cholesky(full) @ rng.standard_normal(full.shape[0])).reshape(n, -1)
        Y = th0 + f[:, None] * (th1 - th0) + noise
        changes, _ = joint_changes(starts, ends, Y, C, names, rng=rng)
        named = {c.parameter: c for c in changes}
        primary = [c.parameter for c in changes if c.role != "alternative"]
        counts["any"] += bool(changes)
        if not step:
            continue
        counts["wrong_first"] += any(p != "a2" for p in primary)
        if "a2" in named:
            c = named["a2"]
            counts["named"] += 1
            counts["first"] += "a2" in primary
            counts["alone"] += len(named) == 1
            counts["time_in"] += c.time_lo <= tau <= c.time_hi
            counts["size_in"] += c.size_lo <= step <= c.size_hi
    return {"case": case, "system": system, "size_sd": "" if size_sd is None else size_sd,
            "step_sd": round(step / float(np.sqrt(c0[ia, ia])), 3), "records": records,
            "efficiency": efficiency, **counts,
            "seconds": round(time.perf_counter() - t0, 1)}  # fmt: skip


def design(records: int) -> list[tuple]:
    out = []
    for k, system in enumerate(SYSTEMS):
        out.append((f"{system}_a2", system, None, records, 10 * k))
        out.append((f"{system}_none", system, 0.0, 2 * records, 10 * k + 1))
        out += [(f"{system}_a2_{s:g}sd", system, s, records, 10 * k + 2 + j)
                for j, s in enumerate(SIZES)]  # fmt: skip
    return out


def write(rows: list[dict], out: Path) -> Path:
    out.mkdir(parents=True, exist_ok=True)
    eff = rows[0]["efficiency"]
    stem = "limit" if eff == 1.0 else f"limit-efficiency{eff:g}"
    with (out / f"{stem}.csv").open("w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=FIELDS, lineterminator="\n")
        w.writeheader()
        w.writerows(rows)
    lines = [
        "# The change test at the information limit (issue 31)", "",
        f"`python analyses/monitor_limit.py`: each window's estimate drawn from a Gaussian at "
        f"the window's true parameters with the full-state Cramer-Rao covariance / {eff:g} "
        "(the monitor's default windows: paper 20 of 1986.56 s, ship 10 "
        "of 4096 s, the last ending with the record; 40 000 s; the step at a time uniform "
        "in [20 000, 36 000] s), then "
        "`hosid.monitor.joint.joint_changes` with its defaults (alpha 0.01, 95 % intervals). "
        "Fractions of records. `named`: a2 in the changes (as an alternative too); `first`: "
        "named by the test, not as an alternative; `wrong, first`: another parameter named "
        "not as an alternative; `any`: any change named (the false-alarm rate of stationary "
        "records).", "",
        "| case | step | bound-sd | records | named | first | alone | time interval holds | size "
        "interval holds | wrong, first | any |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]  # fmt: skip
    for r in rows:
        n = r["records"]
        step = "-5 %" if r["size_sd"] == "" else f"{r['size_sd']:g} bound-sd"
        if r["size_sd"] == 0.0:
            step = "none"
        fr = {k: r[k] / n for k in ("named", "first", "alone", "time_in", "size_in",
                                    "wrong_first", "any")}  # fmt: skip
        lines.append(
            f"| {r['case']} | {step} | {r['step_sd']:+.2f} | {n} | {fr['named']:.3f} | "
            f"{fr['first']:.3f} | "
            f"{fr['alone']:.3f} | {fr['time_in']:.3f} | {fr['size_in']:.3f} | "
            f"{fr['wrong_first']:.3f} | {fr['any']:.3f} |"
        )
    path = out / f"{stem}.md"
    path.write_text("\n".join(lines) + "\n")
    return path


def main(argv: Sequence[str] | None = None) -> Path:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--records", type=int, default=400, help="per case (stationary: twice)")
    ap.add_argument("--efficiency", type=float, default=1.0, help="bound variance / variance")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--cases", nargs="+", help="only these cases (default all)")
    ap.add_argument("--sim-duration", type=float, default=SIM_DURATION, help="of the bound (s)")
    ap.add_argument("--out", type=Path, default=RESULTS)
    args = ap.parse_args(argv)
    todo = [row for row in design(args.records) if not args.cases or row[0] in args.cases]
    with ProcessPoolExecutor(args.workers, mp_context=SPAWN) as pool:
        futures = [
            pool.submit(one_case, *row[:4], args.efficiency, row[4], args.sim_duration)
            for row in todo
        ]
        rows = []
        for f in futures:
            rows.append(f.result())
            print(f"{rows[-1]['case']}: {rows[-1]['seconds']:.0f} s", flush=True)
    path = write(rows, args.out)
    print(path.read_text())
    return path


if __name__ == "__main__":
    main()
