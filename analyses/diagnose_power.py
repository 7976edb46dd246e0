"""Issue 15: the power of ``hosid diagnose`` against the information limit.

For each candidate effect, the share of records in which ``diagnose`` names it, against
its strength in units of its Cramer-Rao standard deviation
(``hosid.model.information.candidate_bound``: the full-state bound of a drift
coefficient, Whittle's bound of ``1/wc^2`` and ``noise_sd^2`` for the sampled record),
with the false-alarm rate on clean records and the confusion matrix.  Records come from
the independent simulator (``independent_sim.py``).

    python analyses/diagnose_power.py                  # the whole design (resumable)
    python analyses/diagnose_power.py --summary        # tables and figure from the CSV

Design (``design()``): the paper oscillator (``paper_S100``, base ``paper``: candidates
b2, mu, m, wc, noise_sd) and the ship-roll regime (base ``paper``) with each effect at 1,
2, 3, 5 and 10 sd; the paper oscillator linearized (``a1 = a1eq``, base ``linear``)
with a hidden quadratic damping or cubic stiffness at the same strengths; the strongly
nonlinear paper oscillator at ``S0 = 1000`` (``paper_S1000``, where the tail's linear
equivalent is least exact) at 3 and 5 sd; 20 clean records of each system; two
effects hidden together (b2 and mu at 5 sd each; 10 sd each too) in the paper and
ship-roll regimes, each at its strength times its bound *given the other*
(:func:`bound_keys`).  10 records a cell at 3 and 5 sd and with two effects, 5 at the
other strengths.

``run_one(row, seed_sequence)`` is a pure function of one design row and its seed;
``main`` is a resumable single-process loop that appends one CSV row per record
(``results/diagnose_power/power.csv``) and skips the rows already there; with ``--batch``
the records run as tasks of ``hosid batch simulate-study`` on a local dask cluster
(``diagnose_power_batch.py``: the same records, the same random numbers).
Record ``k`` of a cell is seeded by ``SeedSequence([seed, crc32(cell), k])``.  The
diagnosis uses the screened posterior for the gaps (``posterior="screen"``, the same
quasi-posterior the command samples with emcee) and no candidate gaps (report only).
"""

from __future__ import annotations

import argparse
import csv
import itertools
import json
import math
import sys
import time
import zlib
from collections.abc import Sequence
from pathlib import Path

import numpy as np
from independent_sim import _equivalent_damping
from independent_sim import simulate as independent_simulate
from regimes import BY_NAME

from hosid.check.diagnose import DEFAULT_REPLICATES
from hosid.check.evidence import COORDINATES

RESULTS = Path(__file__).resolve().parent / "results" / "diagnose_power"
SEED = 20251115
PAPER_EFFECTS = (
    "quadratic_stiffness",
    "coulomb_friction",
    "excitation_mean",
    "coloured_excitation",
    "measurement_noise",
)
FIELDS = (
    "cell",
    "regime",
    "system",
    "base",
    "hidden",
    "strength",
    "record",
    "named",
    "first",
    "n_named",
    "hit",
    "exact",
    "gaps",
    "shrank",
    "evidence",
    "estimates",
    "truth",
    "rounds_calibrated",
    "seconds",
    "replicates",
    "error",
)


def systems(regime: str) -> dict[str, tuple[str, dict]]:
    """``system -> (base, clean parameters)`` of a regime: its oscillator with base
    ``paper`` and (paper regime only) its linearization with base ``linear``.
    """
    r = BY_NAME[regime]
    out = {"paper": ("paper", dict(r.params))}
    if regime == "paper_S100":
        p = r.params
        out["linear"] = (
            "linear",
            {"a1": _equivalent_damping(p["a1"], p["n1"], p["S0"]), "a2": p["a2"], "S0": p["S0"]},
        )
    return out


def design(records: int = 10, clean: int = 20, extra: int = 5) -> list[dict]:
    """The cells of the study (module docstring): one dict per cell.  ``records`` for the
    strengths the issue checks (3 and 5 sd) and the two-effect cells, ``clean`` for
    clean records, ``extra`` for the other strengths (1, 2 and 10 sd).
    """
    cells = []

    def add(regime, system, effects, n):
        hidden = "+".join(effects) or "none"
        strength = max(effects.values()) if effects else 0.0
        cells.append(
            {
                "cell": f"{hidden}:{strength:g}@{regime}/{system}",
                "regime": regime,
                "system": system,
                "effects": dict(effects),
                "records": n,
            }
        )

    every = (1, 2, 3, 5, 10)
    for regime, strengths in (
        ("paper_S100", every),
        ("ship_roll", every),
        ("paper_S1000", (3, 5)),
    ):
        add(regime, "paper", {}, clean)
        for e in PAPER_EFFECTS:
            for k in strengths:
                add(regime, "paper", {e: k}, records if k in (3, 5) else extra)
        if regime != "paper_S1000":
            add(regime, "paper", {"quadratic_stiffness": 5, "coulomb_friction": 5}, records)
            add(regime, "paper", {"quadratic_stiffness": 10, "coulomb_friction": 10}, extra)
    add("paper_S100", "linear", {}, clean)
    for e in ("quadratic_damping", "cubic_stiffness"):
        for k in every:
            add("paper_S100", "linear", {e: k}, records if k in (3, 5) else extra)
    return cells


def bound_keys(cell: dict) -> list[tuple[str, str, str]]:
    """The bounds a cell's truth needs: each effect's own; with two or more effects also
    each one's bound *given the others* (``"quadratic_stiffness given
    coulomb_friction=5"``), because an effect changes the information about another (ship
    roll: Coulomb friction at 5 sd doubles the bound of the quadratic stiffness, 0.0100 ->
    0.0192).
    """
    r, s, eff = cell["regime"], cell["system"], cell["effects"]
    keys = [(r, s, e) for e in eff]
    if len(eff) > 1:
        keys += [(r, s, joint_key(e, eff)) for e in eff]
    return keys


def joint_key(effect: str, effects: dict) -> str:
    """The bound key of ``effect`` given the other effects at their strengths."""
    others = ",".join(f"{o}={k:g}" for o, k in sorted(effects.items()) if o != effect)
    return f"{effect} given {others}"


def _set(p: dict, effect: str, u: float) -> None:
    if effect == "coloured_excitation":
        p["wc"] = 1.0 / math.sqrt(u)
    elif effect == "measurement_noise":
        p["noise_sd"] = math.sqrt(u)
    else:
        p[COORDINATES[effect].param] = u


def truth(cell: dict, bounds: dict) -> dict[str, float]:
    """The simulated parameters of a cell: each effect at its strength times its bound
    (with other effects: its bound given them, :func:`bound_keys`).
    """
    params = systems(cell["regime"])[cell["system"]][1]
    p = {"n1": 0.0, "n2": 0.0, **params}  # the independent simulator wants every key
    eff = cell["effects"]
    for e, k in eff.items():
        key = joint_key(e, eff) if len(eff) > 1 else e
        _set(p, e, k * bounds[(cell["regime"], cell["system"], key)])
    return p


def run_one(row: dict, ss: np.random.SeedSequence) -> dict:
    """Simulate one record of a design row and diagnose it: one result row.

    ``row``: a cell of :func:`design` with ``record``, ``truth`` (simulated parameters),
    ``base``, ``duration``, ``dt`` and ``replicates``.
    """
    from hosid.check.diagnose import diagnose

    t0 = time.perf_counter()
    sim_ss, diag_ss = ss.spawn(2)
    try:
        rec, _ = independent_simulate(
            row["truth"], duration=row["duration"], dt=row["dt"], rng=np.random.default_rng(sim_ss)
        )
        d = diagnose(
            rec, row["base"], rng=np.random.default_rng(diag_ss), replicates=row["replicates"],
            posterior="screen", candidate_gaps=False,
        )  # fmt: skip
    except Exception as exc:  # a failed record is a row too (counted, not hidden)
        error = f"{type(exc).__name__}: {exc}"
        return result_row(row, seconds=time.perf_counter() - t0, error=error)
    return result_row(
        row,
        named=d.named_effects,
        gaps=d.gaps,
        evidence=d.rounds[0].numbers(),
        estimates={s.effect: s.posterior()["mean"] for s in d.steps},
        rounds_calibrated=sum(r.calibrated for r in d.rounds),
        seconds=time.perf_counter() - t0,
    )


def run_rows(todo: Sequence[dict], writer: csv.DictWriter, fh, seed: int) -> None:
    """:func:`run_one` on each row, one CSV row flushed a record (seeds: module doc)."""
    for i, row in enumerate(todo):
        ss = np.random.SeedSequence([seed, zlib.crc32(row["cell"].encode()), row["record"]])
        res = run_one(row, ss)
        writer.writerow(res)
        fh.flush()
        print(
            f"[{i + 1}/{len(todo)}] {row['cell']} #{row['record']}: named "
            f"{res.get('named') or res['error']} ({res['seconds']} s)",
            flush=True,
        )


def result_row(
    row: dict,
    *,
    named: Sequence[str] = (),
    gaps: Sequence[float] = (),
    evidence: dict | None = None,
    estimates: dict | None = None,
    rounds_calibrated: int = 0,
    seconds: float,
    error: str = "",
) -> dict:
    """The study's row of one diagnosed record (:data:`FIELDS`), whichever way it ran
    (:func:`run_one` here, or a task of ``hosid batch``: ``diagnose_power_batch.py``).
    ``evidence``: the first round's ``{effect: [z, D, p, adjusted p]}``.
    """
    hidden = sorted(row["effects"])
    out = {k: row[k] for k in ("cell", "regime", "system", "base", "record")}
    out.update(
        hidden="+".join(hidden) or "none",
        strength=max(row["effects"].values(), default=0.0),
        truth=json.dumps({k: round(v, 8) for k, v in row["truth"].items()}),
        replicates=row["replicates"],
        seconds=round(seconds, 1),
        error=error,
    )
    if error:
        return out
    named = list(named)
    ev = {}  # a value JSON could not hold (an infinite z) comes back as None
    for c, e in (evidence or {}).items():
        z, D, p, pa = (math.nan if v is None else float(v) for v in e)
        ev[c] = [round(z, 3), round(D, 3), float(f"{p:.4g}"), round(pa, 4)]
    out.update(
        named="+".join(named) or "none",
        first=named[0] if named else "none",
        n_named=len(named),
        hit=int(set(hidden) <= set(named)) if hidden else int(not named),
        exact=int(set(hidden) == set(named)),
        gaps=";".join(f"{g:.3f}" for g in gaps),
        shrank=int(all(b < a for a, b in itertools.pairwise(gaps))) if named else "",
        evidence=json.dumps(ev),
        estimates=json.dumps({e: round(v, 8) for e, v in (estimates or {}).items()}),
        rounds_calibrated=rounds_calibrated,
    )
    return out


def rows_of(cells: Sequence[dict], bounds: dict, *, records: int | None, replicates: int,
            duration: float | None) -> list[dict]:  # fmt: skip
    """One design row per record of every cell."""
    rows = []
    for cell in cells:
        r = BY_NAME[cell["regime"]]
        base = systems(cell["regime"])[cell["system"]][0]
        n = cell["records"] if records is None else min(records, cell["records"])
        for k in range(n):
            rows.append(
                {
                    **cell,
                    "base": base,
                    "record": k,
                    "truth": truth(cell, bounds),
                    "duration": duration or r.duration,
                    "dt": r.dt,
                    "replicates": replicates,
                }
            )
    return rows


def priority(row: dict) -> tuple:
    """Run order, so that a stopped run has what the issue checks first: clean records,
    5 sd and two effects; then 3 sd; then the rest.  Within a level, passes of 5 records
    over every cell.
    """
    effects = row["effects"]
    k = max(effects.values(), default=0)
    if not effects or k == 5:
        level = 0
    elif k in (3, 5):
        level = 1
    else:
        level = 2
    return (level, row["record"] // 5, row["cell"], row["record"])


def read_csv(path: Path) -> list[dict]:
    if not path.exists():
        return []
    with open(path, newline="") as fh:
        return list(csv.DictReader(fh))


def _commit() -> str:
    """The working tree's commit (``unknown`` outside git), with ``+changes`` if dirty."""
    import subprocess

    def git(*args):
        r = subprocess.run(["git", *args], capture_output=True, text=True, cwd=RESULTS.parent)
        return r.stdout.strip() if r.returncode == 0 else ""

    head = git("rev-parse", "--short", "HEAD") or "unknown"
    return head + ("+changes" if git("status", "--porcelain", "--", "../src") else "")


def main(argv: Sequence[str] | None = None) -> int:
    """Run (or resume) the study, then write the summary."""
    from diagnose_power_summary import summarize

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cells", nargs="*", default=None, help="cell names (default: all)")
    ap.add_argument("--records", type=int, default=None, help="at most this many a cell")
    ap.add_argument("--replicates", type=int, default=DEFAULT_REPLICATES)
    ap.add_argument("--duration", type=float, default=None, help="override (tests only)")
    ap.add_argument("--seed", type=int, default=SEED)
    ap.add_argument("--summary", action="store_true", help="tables and figure only")
    ap.add_argument("--batch", action="store_true", help="run through hosid batch (dask)")
    ap.add_argument("--workers", type=int, default=None, help="--batch: local workers")
    ap.add_argument("--out", type=Path, default=RESULTS)
    a = ap.parse_args(argv)
    a.out.mkdir(parents=True, exist_ok=True)
    cells = design()
    if a.cells is not None:
        unknown = set(a.cells) - {c["cell"] for c in cells}
        if unknown:
            print(f"unknown cells {sorted(unknown)}", file=sys.stderr)
            return 2
        cells = [c for c in cells if c["cell"] in a.cells]
    path = a.out / "power.csv"
    bounds_path = a.out / "bounds.json"
    stored = json.loads(bounds_path.read_text()) if bounds_path.exists() else {}
    bounds = {tuple(k.split("|")): v for k, v in stored.items()}
    need = {k for c in cells for k in bound_keys(c)} - set(bounds)
    if need and not a.summary:
        from diagnose_power_bounds import compute_bounds

        bounds = compute_bounds(sorted(need), seed=a.seed, known=bounds)
        bounds_path.write_text(json.dumps({"|".join(k): v for k, v in bounds.items()}, indent=1))
    if not a.summary:
        if not (a.out / "COMMIT").exists():  # the code the study's records were run with
            (a.out / "COMMIT").write_text(_commit() + "\n")
        done = {(r["cell"], int(r["record"])) for r in read_csv(path)}
        todo = [
            r
            for r in rows_of(
                cells, bounds, records=a.records, replicates=a.replicates, duration=a.duration
            )
            if (r["cell"], r["record"]) not in done
        ]
        todo.sort(key=priority)
        new = not path.exists() or path.stat().st_size == 0
        with open(path, "a", newline="") as fh:
            w = csv.DictWriter(fh, FIELDS)
            if new:
                w.writeheader()
            if a.batch and todo:
                import diagnose_power_batch as batch

                batch.run(todo, a.out, replicates=a.replicates, seed=a.seed, workers=a.workers)
                w.writerows(batch.collect(todo, a.out))
                todo = []
            run_rows(todo, w, fh, a.seed)
    summarize(read_csv(path), bounds, a.out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
