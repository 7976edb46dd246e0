"""The paper's Figures 1-8 made by today's engine, and each claim beside what we measure.

    make paper                                        # = python analyses/paper_figures.py
    python analyses/paper_figures.py --quick --out D  # the tests' tiny settings

Records are the paper's oscillator (a1 = n1 = 0.5, a2 = 25, n2 = 5), 2000 s at
dt = 0.02 s, simulated by hosid; the paper's estimators (``paper_estimators.py``) use its
settings (Hann window, 20.48 s blocks, w <= 8 rad/s), hosid's default estimate and
posterior use their own defaults (the J2 band up to 6 w_n, the generator identities).

- Figures 1-2, 4-5: S0 = 25 ... 2500, 5 records a level: the stiffness by moments, by
  J2 and by J2 + J4A with every parameter free; a1eq and S0 by J2 with the moment
  stiffness (the paper's protocol); hosid's estimate; one posterior a level.
- Figure 3: the restoring force at S0 = 2500 by the spectral estimates at w <= 8 and
  12 rad/s, by moments and hosid's posterior band.
- Figure 6: (a1, n1) of 30 records at S0 = 100 by J2 alone, by J4A along the line of
  eq (65) (the paper's fourth order) and by hosid; one posterior's draws.
- Figures 7-8: the printed J2 and J4A over (a1, n1) with a2, n2, S0 at the truth, and
  the draws of unconstrained posteriors (default and J4A) over them.

Writes the PNGs, ``paper.csv`` (every point estimate), ``posteriors.csv`` and
``paper.md`` (each claim of the paper beside the number measured) into ``--out``
(default ``analyses/out/paper``; the committed copy is ``analyses/results/paper``).
Seeds: the records of each level are children of ``SeedSequence(seed)`` as in
:func:`records`; the same seed gives the same records and numbers.
"""

from __future__ import annotations

import argparse
import csv
import time
from collections.abc import Sequence
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
import paper_page
import paper_plots
from paper_estimators import OMEGA_MAX, PARAMS, SQRT_8_PI, cost_maps, point_estimates
from tqdm import tqdm

import hosid

HERE = Path(__file__).resolve().parent
OUT = HERE / "out" / "paper"
TRUTH = {"a1": 0.5, "n1": 0.5, "a2": 25.0, "n2": 5.0}
SWEEP = ("moments", "J2 free", "J2+J4A free", "J2", "hosid")
SCATTER = ("J2 split", "J4A line", "hosid")
QUANTILES = (0.05, 0.5, 0.95)


@dataclass(frozen=True)
class Settings:
    """Sizes of the run (the defaults are the paper's; :data:`QUICK` the tests')."""

    levels: tuple[float, ...] = (25.0, 50.0, 100.0, 250.0, 500.0, 1000.0, 2500.0)
    records: int = 5  # a level, Figures 1-2 and 4-5
    scatter: int = 30  # Figure 6
    scatter_S0: float = 100.0
    force_S0: float = 2500.0  # Figure 3
    duration: float = 2000.0
    dt: float = 0.02
    n_steps: int | None = None  # the fits' stop rule when None
    grid: tuple[int, int] = (161, 101)  # Figures 7-8
    seed: int = 19980101


QUICK = Settings(
    levels=(100.0, 2500.0), records=1, scatter=2, duration=600.0, n_steps=300, grid=(21, 11)
)


def records(s: Settings, S0: float, n: int, key: int):
    """``n`` records (and their true velocities) at level ``S0``; ``key`` picks the
    child of ``SeedSequence(seed)`` (levels 0.., Figure 3 100, Figure 6 101).
    """
    ss = np.random.SeedSequence(s.seed).spawn(key + 1)[key]
    params = {**TRUTH, "S0": S0}
    out = []
    for k, child in enumerate(ss.spawn(n)):
        rec, v = hosid.simulate(
            params,
            duration=s.duration,
            dt=s.dt,
            rng=np.random.default_rng(child),
            name=f"S0={S0:g} #{k}",
            return_velocity=True,
        )
        out.append((rec, true_a1eq(float(np.std(v)))))
    return out


def true_a1eq(sigma_v: float) -> float:
    """Eq (65) at the simulated velocity's sd."""
    return TRUTH["a1"] + TRUTH["n1"] * SQRT_8_PI * sigma_v


def fit(rec, s: Settings, seed: int, **kwargs):
    """A posterior with hosid's defaults (``kwargs`` override), no progress bar."""
    return hosid.fit(rec, n_steps=s.n_steps, seed=seed, progress=False, with_map=False, **kwargs)


def quantiles(tree, names=(*PARAMS, "a1eq")) -> dict[str, float]:
    """``{name_q05, name_q50, name_q95}`` of the posterior draws."""
    post = tree["posterior"]
    out = {}
    for p in names:
        q = np.quantile(post[p].values.ravel(), QUANTILES)
        out.update(
            {f"{p}_q{round(100 * a):02d}": float(v) for a, v in zip(QUANTILES, q, strict=True)}
        )
    return out


def draws(tree, names=("a1", "n1", "a1eq")) -> dict[str, np.ndarray]:
    """The posterior's draws of ``names``, flattened."""
    return {p: tree["posterior"][p].values.ravel() for p in names}


def run(s: Settings, out: Path) -> dict:
    """Every figure's numbers; writes the figures, the tables and ``paper.md``."""
    t0 = time.perf_counter()
    n_total = len(s.levels) * (s.records + 1) + 2 + s.scatter + 1 + 3
    bar = tqdm(total=n_total, desc="paper figures", unit="step")
    rows, posts = [], []
    fig3_rec = None
    for i, S0 in enumerate(s.levels):
        recs = records(s, S0, s.records, i)
        for k, (rec, a1eq) in enumerate(recs):
            for name, e in point_estimates(rec, SWEEP).items():
                rows.append(
                    {
                        "figure": "1-2,4-5",
                        "S0_true": S0,
                        "record": k,
                        "estimator": name,
                        "a1eq_true": a1eq,
                        **e,
                    }
                )
            bar.update()
        tree = fit(recs[0][0], s, seed=1000 + i)
        posts.append(
            {"figure": "1-2,4-5", "S0_true": S0, "a1eq_true": recs[0][1], **quantiles(tree)}
        )
        if S0 == s.force_S0:
            fig3_rec = recs[0]
        bar.update()
    # Figure 3: one record at S0 = 2500 (the sweep's first when it has that level)
    rec3, _ = fig3_rec or records(s, s.force_S0, 1, 100)[0]
    force = {"x_max": float(np.max(np.abs(rec3.x - np.mean(rec3.x))))}
    for w in (OMEGA_MAX, 12.0):
        est = point_estimates(rec3, ("J2 free", "J2+J4A free"), omega_max=w)
        for name, e in est.items():
            force[f"{name}, w <= {w:g}"] = (e["a2"], e["n2"])
    bar.update()
    force["moments"] = tuple(
        point_estimates(rec3, ("moments",))["moments"][p] for p in ("a2", "n2")
    )
    tree3 = fit(rec3, s, seed=2000)
    force["draws"] = (
        tree3["posterior"]["a2"].values.ravel(),
        tree3["posterior"]["n2"].values.ravel(),
    )
    bar.update()
    # Figure 6: the damping split over records at S0 = 100
    scat = records(s, s.scatter_S0, s.scatter, 101)
    for k, (rec, a1eq) in enumerate(scat):
        for name, e in point_estimates(rec, SCATTER).items():
            rows.append(
                {
                    "figure": "6",
                    "S0": s.scatter_S0,
                    "record": k,
                    "estimator": name,
                    "a1eq_true": a1eq,
                    **e,
                }
            )
        bar.update()
    rec6 = scat[0][0]
    tree6 = fit(rec6, s, seed=3000)
    posts.append(
        {"figure": "6", "S0_true": s.scatter_S0, "a1eq_true": scat[0][1], **quantiles(tree6)}
    )
    bar.update()
    # Figures 7-8: the printed costs over (a1, n1), the unconstrained posteriors
    truth = {**TRUTH, "S0": s.scatter_S0}
    maps = cost_maps(rec6, truth, np.linspace(-8, 8, s.grid[0]), np.linspace(-1, 1, s.grid[1]))
    bar.update()
    free = {
        "default": draws(fit(rec6, s, seed=4000, constrained=False)),
        "J4A": draws(fit(rec6, s, seed=4001, constrained=False, cost="J4A")),
    }
    bar.update(2)
    bar.close()
    result = {
        "settings": s,
        "rows": rows,
        "posteriors": posts,
        "force": force,
        "fig6_draws": draws(tree6),
        "a1eq6": scat[0][1],
        "sigma_v6": (scat[0][1] - TRUTH["a1"]) / (TRUTH["n1"] * SQRT_8_PI),
        "maps": maps,
        "free": free,
        "seconds": time.perf_counter() - t0,
    }
    write(result, out)
    return result


def _write_csv(path: Path, rows: Sequence[dict]) -> None:
    fields = list(dict.fromkeys(k for r in rows for k in r))
    with path.open("w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=fields)
        w.writeheader()
        for r in rows:
            w.writerow({k: (f"{v:.6g}" if isinstance(v, float) else v) for k, v in r.items()})


def write(result: dict, out: Path) -> None:
    """The figures, ``paper.csv``, ``posteriors.csv`` and ``paper.md`` into ``out``."""
    out.mkdir(parents=True, exist_ok=True)
    _write_csv(out / "paper.csv", result["rows"])
    _write_csv(out / "posteriors.csv", result["posteriors"])
    paper_plots.draw_all(result, out)
    (out / "paper.md").write_text(paper_page.markdown(result))


def main(argv: Sequence[str] | None = None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="tiny settings (the tests')")
    ap.add_argument("--out", type=Path, default=OUT, help="output folder")
    ap.add_argument("--seed", type=int, default=Settings.seed)
    args = ap.parse_args(argv)
    s = replace(QUICK if args.quick else Settings(), seed=args.seed)
    result = run(s, args.out)
    print(f"wrote {args.out} in {result['seconds']:.0f} s")
    return result


if __name__ == "__main__":
    main()
