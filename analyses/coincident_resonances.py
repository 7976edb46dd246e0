r"""A shaping filter at the oscillator's resonance: what the estimate separates (issue 29).

With the force's filter peaked at the resonance (the excitation study's ``ship_at``:
``wf`` 0.6 rad/s against :math:`\sqrt{a_2}` = 0.592), the response spectrum is the
product of two resonances of nearly the same frequency,

.. math:: S_x(\omega) \approx \frac{S_0\,\omega_f^4}
    {|a_2 - \omega^2 + ic\omega|^2\,|\omega_f^2 - \omega^2 + 2i\zeta_f\omega_f\omega|^2},

which in the linear limit is symmetric in the two factors: it fixes the symmetric
functions of the two squared frequencies, :math:`s = a_2 + \omega_f^2` and
:math:`p = a_2\omega_f^2`, but the pair itself only as the roots of
:math:`z^2 - sz + p`, :math:`(s \pm \sqrt{s^2 - 4p})/2`, which near coincidence move
with the square root of the discriminant's noise: the roots repel (their split is
biased away from zero) and their scatter is not the curvature's.  The nonlinear terms
(``n1``, ``n2``) break the symmetry only weakly.

This script measures it: ``--records`` records of the model at the truth (hosid's
simulator, or ``--simulator independent``), the default estimate of
``paper,narrowband_excitation`` with its Laplace sd (no sampler, no settling), and per
parameter the mean and sd over records of the z-score (estimate - truth) / sd, then the
bias of :math:`s`, :math:`p`, :math:`a_2` and :math:`\omega_f^2` in units of their own
scatter over the records, and the equations' :math:`J` (minus twice the
quasi-log-likelihood) at the truth and at the estimate: at the truth a chi-square of
:math:`k` degrees of freedom where the equations and their weight are right, and
:math:`J(\theta_0) - J(\hat\theta)` one of :math:`p` (the parameters) where the fit is
regular; for each of ``--variants``:

- ``default``: the default equations and blocks;
- ``long_blocks``: blocks twice the default's length (204.8 s at the defaults: 19 blocks,
  fewer than the 24 :func:`hosid.spectra.blocks.choose_layout` allows, which this
  script lowers to 16 for that variant: what the blocks' resolution does);
- ``without_J2``, ``without_identities``: the default equations less one half;
- ``simulated_weight``: the default equations weighed with their covariance on 8
  records simulated at the estimate, as :func:`hosid.inference.estimate.estimate` does
  by default under a shaping filter (:mod:`hosid.inference.simulated`; the other
  variants weigh with the record's own blocks, ``simulations=0``).

One worker a record (``--workers``).
"""

from __future__ import annotations

import argparse
import multiprocessing
import sys
from collections.abc import Sequence
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np
from scipy import stats

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from excitation_study import SHIP  # noqa: E402

RESULTS = HERE / "results" / "coincident_resonances.md"
SEED = 20261128
MODEL = "paper,narrowband_excitation"


VARIANTS = ("default", "long_blocks", "without_J2", "without_identities", "simulated_weight")


def _settings(variant: str, state_T: float):
    """``(components, block_seconds)`` of ``variant`` (module docstring)."""
    from hosid.components.cumulant import ForceKurtosis
    from hosid.components.identities import Identities
    from hosid.components.level import Level
    from hosid.components.spectral import J2
    from hosid.spectra import blocks

    blocks.choose_layout.__kwdefaults__["min_blocks"] = (
        16 if variant == "long_blocks" else blocks.MIN_BLOCKS
    )
    if variant == "long_blocks":
        return None, 2.0 * state_T
    if variant == "without_J2":
        return [Identities(), Level(), ForceKurtosis()], None
    if variant == "without_identities":
        return [J2(with_level=True), Level(), ForceKurtosis()], None
    return None, None


def one(args) -> dict[str, tuple]:
    """Per variant, the estimate, its Laplace sd and the equations' :math:`J` at the truth
    and at the estimate, with their number, of one record (``args``: truth, index,
    settings, variants).
    """
    from independent_sim import simulate

    from hosid.inference import estimate
    from hosid.inference.correction import DEFAULT_SIMULATIONS
    from hosid.inference.estimate import prepare_state
    from hosid.model import Model

    truth, i, duration, dt, simulator, seed, variants = args
    model = Model.from_spec(MODEL)
    theta = np.array([truth[p] for p in model.param_names])
    rng = np.random.default_rng([seed, i])
    if simulator == "independent":
        record, _ = simulate(truth, duration=duration, dt=dt, rng=rng)
    else:
        record = model.simulate(theta, duration=duration, dt=dt, rng=rng)
    _settings("default", 0.0)  # the default block rule (a worker may have run another)
    T = prepare_state(record, model).layout.T
    out = {}
    for v in variants:
        components, block_seconds = _settings(v, T)
        sims = DEFAULT_SIMULATIONS if v == "simulated_weight" else 0
        est = estimate(
            record, model, components, settle=False, simulations=sims, block_seconds=block_seconds
        )
        J = (-2.0 * float(est.ql(theta)), -2.0 * float(est.ql(est.theta)), est.ql.k)
        out[v] = (est.theta, np.sqrt(np.diag(est.cov)), J)
    return out


def measure(truth, *, records, duration, dt, simulator, seed, workers, variants) -> dict:
    """Per variant, the z-scores and the symmetric functions' bias over ``records``."""
    from hosid.model import Model

    todo = [(truth, i, duration, dt, simulator, seed, variants) for i in range(records)]
    if workers == 1:
        res = list(map(one, todo))
    else:  # spawned: a forked child of a process that ran OpenMP kernels aborts
        with ProcessPoolExecutor(workers, mp_context=multiprocessing.get_context("spawn")) as ex:
            res = list(ex.map(one, todo))
    return {v: _summary(truth, [r[v] for r in res], Model.from_spec(MODEL)) for v in variants}


def _summary(truth, res, model) -> dict:
    """The z-scores and the symmetric functions' bias of one variant."""
    names = list(model.param_names)
    theta = np.array([truth[p] for p in names])
    est = np.array([r[0] for r in res])
    sd = np.array([r[1] for r in res])
    z = (est - theta) / sd
    J0, J1, k = (np.array([r[2][j] for r in res]) for j in range(3))
    a2, w2 = est[:, names.index("a2")], est[:, names.index("wf")] ** 2
    a2_0, w2_0 = theta[names.index("a2")], theta[names.index("wf")] ** 2
    funcs = {
        "s = a2 + wf^2": (a2 + w2, a2_0 + w2_0),
        "p = a2 wf^2": (a2 * w2, a2_0 * w2_0),
        "a2": (a2, a2_0),
        "wf^2": (w2, w2_0),
    }
    sym = {
        k: {"bias/scatter": (v.mean() - t) / v.std(ddof=1), "scatter/truth": v.std(ddof=1) / t}
        for k, (v, t) in funcs.items()
    }
    return {
        "names": names, "z_mean": z.mean(0), "z_sd": z.std(0, ddof=1), "sym": sym,
        "covered": np.mean(np.abs(z) < 1.6449, axis=0),
        "mean_sd": dict(zip(names, sd.mean(0), strict=True)),
        "J": {"k": int(k[0]), "at truth": J0.mean(), "at estimate": J1.mean(),
              "difference": (J0 - J1).mean(), "above chi2 0.99": np.mean(
                  J0 - J1 > stats.chi2.ppf(0.99, len(names)))},
    }  # fmt: skip


def write(results: dict, settings: dict, out: Path) -> Path:
    """Per variant the z table and the symmetric functions' table, in ``out``."""
    n = settings["records"]
    se = 1 / np.sqrt(n)
    lines = [
        "# A shaping filter and the resonance: what the estimate separates (issue 29)",
        "",
        f"`python analyses/coincident_resonances.py {' '.join(settings['argv'])}` "
        f"({settings['simulator']} simulator, {n} records of {settings['duration']:g} s at "
        f"dt {settings['dt']:g}, seed {settings['seed']}; ship-roll-like oscillator, wf "
        f"{settings['wf']:g}, zf {settings['zf']:g}): the estimate of `{MODEL}` and its "
        "Laplace sd, no sampler (variants: the module docstring).  z = (estimate - truth) "
        f"/ sd; a calibrated estimate has z mean 0 (se {se:.2f}) and sd 1.  Below: the "
        "symmetric functions of the two squared frequencies against the pair itself, bias "
        f"in units of the estimates' own scatter over the records (se {se:.2f}).",
    ]
    for variant, result in results.items():
        head = "| parameter | z mean | z sd | mean sd | 90 % covered |"
        lines += ["", f"## {variant}", "", head]
        lines.append("|---|---|---|---|---|")
        rows = zip(
            result["names"], result["z_mean"], result["z_sd"], result["covered"], strict=True
        )
        for p, m, s, c in rows:
            lines.append(f"| {p} | {m:+.2f} | {s:.2f} | {result['mean_sd'][p]:.4g} | {c:.2f} |")
        lines += ["", "| quantity | bias / scatter | scatter / truth |", "|---|---|---|"]
        for k, v in result["sym"].items():
            lines.append(f"| {k} | {v['bias/scatter']:+.2f} | {v['scatter/truth']:.4f} |")
        J, p = result["J"], len(result["names"])
        lines += [
            "",
            f"The equations' J (k = {J['k']}, {p} parameters), mean over the records: at the "
            f"truth {J['at truth']:.1f} (a chi-square of {J['k']} degrees of freedom: "
            f"{J['k']}), at the estimate {J['at estimate']:.1f} ({J['k'] - p}); their "
            f"difference {J['difference']:.1f} ({p} for a regular fit), beyond its "
            f"chi-square's 99 % point in {J['above chi2 0.99']:.2f} of the records (0.01).",
        ]
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text("\n".join(lines) + "\n")
    return out


def main(argv: Sequence[str] | None = None) -> Path:
    """CLI (module docstring)."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--records", type=int, default=24)
    ap.add_argument("--duration", type=float, default=4000.0)
    ap.add_argument("--dt", type=float, default=0.1)
    ap.add_argument("--wf", type=float, default=0.6)
    ap.add_argument("--zf", type=float, default=0.1)
    ap.add_argument("--simulator", choices=("hosid", "independent"), default="hosid")
    ap.add_argument("--variants", nargs="+", choices=VARIANTS, default=list(VARIANTS))
    ap.add_argument("--seed", type=int, default=SEED)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--out", type=Path, default=RESULTS)
    argv = sys.argv[1:] if argv is None else list(argv)
    args = ap.parse_args(argv)
    if args.records < 2:
        ap.error("--records must be at least 2")
    truth = {**SHIP, "wf": args.wf, "zf": args.zf}
    shown = [a for k, a in enumerate(argv) if "--out" not in (a, argv[k - 1] if k else "")]
    settings = {**vars(args), "argv": shown}
    results = measure(
        truth, records=args.records, duration=args.duration, dt=args.dt,
        simulator=args.simulator, seed=args.seed, workers=args.workers,
        variants=tuple(args.variants),
    )  # fmt: skip
    path = write(results, settings, args.out)
    print(path.read_text())
    return path


if __name__ == "__main__":
    main()
