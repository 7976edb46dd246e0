"""The commands behind ``hosid``: what each one reads, runs and writes.

:mod:`hosid.cli` parses the arguments and maps errors; every function here takes the
parsed ``argparse.Namespace`` and returns an exit code.
"""

from __future__ import annotations

import json
import math
import sys
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from hosid.errors import HosidInputError

#: Old ``--method`` names of ``hosid estimate`` and the cost they now mean.
METHODS = {
    "default": None,
    "J2": "J2",
    "J4A": "J4A",
    "J4B": "J4B",
    "paper": "J4A",
    "moments": "J2",
}
FIT_COLUMNS = ("mean", "sd", "q05", "q50", "q95", "r_hat", "ess_bulk")


def _fmt(value) -> str:
    if value is None:
        return "-"
    try:
        number = float(value)
    except (TypeError, ValueError):
        return str(value)
    return "-" if math.isnan(number) else f"{number:.4g}"


def _table(header: Sequence[str], rows: Sequence[Sequence[str]]) -> str:
    widths = [max(len(r[i]) for r in [header, *rows]) for i in range(len(header))]
    lines = [
        "  ".join(c.ljust(w) for c, w in zip(r, widths, strict=True)).rstrip()
        for r in [header, *rows]
    ]
    lines.insert(1, "  ".join("-" * w for w in widths))
    return "\n".join(lines)


def _read(path: str):
    from hosid.record import read_record

    return read_record(Path(path))


def _truths(args, record_path: Path) -> dict | None:
    path = Path(args.truths) if getattr(args, "truths", None) else None
    if path is None:
        for cand in (
            record_path.with_suffix(".truths.json"),
            record_path.with_name(record_path.name + ".truths.json"),
        ):
            if cand.is_file():
                path = cand
                break
    if path is None:
        return None
    try:
        data = json.loads(path.read_text())
    except FileNotFoundError:
        raise HosidInputError(f"{path}: no such file") from None
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise HosidInputError(f"{path}: not valid JSON ({exc})") from None
    ok = (
        isinstance(data, dict)
        and data
        and all(
            isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v)
            for v in data.values()
        )
    )
    if not ok:
        raise HosidInputError(f"{path}: truths must be a JSON object of finite numbers")
    return {k: float(v) for k, v in data.items()}


def _out_dir(path: str) -> Path:
    from hosid.output.files import make_dir

    _check_out(path)
    return make_dir(path)


def _print_fit(summary: dict) -> None:
    params = summary["parameters"]
    print(
        f"{summary.get('record') or 'record'}: {' + '.join(summary.get('model') or [])}, "
        f"components {', '.join(summary.get('components') or [])}; "
        f"{summary['n_walkers']} walkers x {summary['n_draws']} draws, "
        f"{_fmt(summary.get('fit_seconds'))} s"
    )
    rows = [[k, *(_fmt(r.get(c)) for c in FIT_COLUMNS)] for k, r in params.items()]
    print(_table(["parameter", *FIT_COLUMNS], rows))
    if summary.get("diagnostic_failures"):
        print(
            "hosid: warning: convergence diagnostics failed: "
            + "; ".join(summary["diagnostic_failures"]),
            file=sys.stderr,
        )


# --- commands -------------------------------------------------------------------------
def cmd_simulate(args) -> int:
    """``hosid simulate``: write a simulated record and its true parameters."""
    from hosid.model.simulate import simulate
    from hosid.record import write_record

    out = Path(args.out)
    if out.suffix.lower() not in (".csv", ".npz"):
        raise HosidInputError(
            f"{out}: unknown file type {out.suffix or '(none)'!r}; use .csv or .npz"
        )
    params = {k: getattr(args, k) for k in ("a1", "n1", "a2", "n2", "S0")}
    params.update(
        {
            k: getattr(args, k)
            for k in ("b2", "mu", "m", "wc", "noise_sd")
            if getattr(args, k) is not None
        }
    )
    record = simulate(
        params,
        duration=args.duration,
        dt=args.dt,
        rng=np.random.default_rng(args.seed),
        name=out.stem,
    )
    write_record(record, out)
    sidecar = out.with_suffix(".truths.json")
    sidecar.write_text(json.dumps(params, indent=2) + "\n")
    print(f"wrote {out}: {record.n} samples, dt={record.dt:g} s (true parameters: {sidecar})")
    return 0


def cmd_estimate(args) -> int:
    """``hosid estimate``: the calibrated mode and its sd, no sampling."""
    from hosid.inference import components_for, estimate

    record = _read(args.record)
    cost = args.cost if args.method is None else METHODS[args.method]
    band = None if args.omega_max is None else (0.0, args.omega_max)
    comps = components_for(cost, band=band, form=args.form, domain=args.domain)
    est = estimate(record, args.model, comps, block_seconds=args.block_seconds)
    sd = est.sd
    print(
        f"{record.name or args.record}: {est.model!r}, {cost or 'default'} components; "
        f"Hansen J = {_fmt(est.test['J'])} on {est.test['df']} df "
        f"(p = {_fmt(est.test['p_value'])})"
    )
    rows = [[k, _fmt(v), _fmt(sd[k])] for k, v in est.values.items()]
    if est.model.has("a1"):
        c = est.model.drift_terms
        g = np.array(
            [t.damping_factor(est.sigma_v) for t in c] + [0.0] * (len(est.theta) - len(c))
        )
        rows.append(["a1eq", _fmt(g @ est.theta), _fmt(math.sqrt(g @ est.cov @ g))])
    print(_table(["parameter", "estimate", "sd"], rows))
    if args.json:
        from hosid.output.results import jsonable

        data = {
            "record": record.name,
            "model": list(est.model.names),
            "cost": cost,
            "estimates": est.values,
            "sd": sd,
            "hansen": est.test,
            "state": est.state.describe(),
        }
        try:
            Path(args.json).write_text(json.dumps(jsonable(data), indent=2) + "\n")
        except OSError as exc:
            raise HosidInputError(f"cannot write {args.json}: {exc.strerror or exc}") from None
    return 0


def _check_out(path: str) -> None:
    """Fail before any work when ``--out`` cannot become a directory."""
    out = Path(path)
    if out.exists() and not out.is_dir():
        raise HosidInputError(f"{out}: exists and is not a directory")


def _fit_and_report(record, out: Path, *, truths=None, **options) -> int:
    from hosid.inference import fit
    from hosid.output.report import write_report
    from hosid.output.results import save

    tree = fit(record, truths=truths, **options)
    out = _out_dir(str(out))
    save(tree, out / "posterior.nc")
    paths = write_report(tree, out)
    _print_fit(json.loads((out / "summary.json").read_text(encoding="utf-8")))  # summarized once
    print("wrote " + ", ".join(str(p) for p in [out / "posterior.nc", *paths]))
    return 0


def cmd_fit(args) -> int:
    """``hosid fit``: sample the posterior; write posterior.nc and the report."""
    backend = args.backend
    if backend is not None and Path(backend).suffix.lower() not in (".h5", ".hdf5"):
        raise HosidInputError(f"{backend}: the backend must be an HDF5 file (.h5 or .hdf5)")
    record = _read(args.record)
    truths = _truths(args, Path(args.record))
    _check_out(args.out)
    return _fit_and_report(
        record,
        Path(args.out),
        truths=truths,
        model=args.model,
        cost=args.cost,
        constrained=not args.unconstrained,
        n_walkers=args.walkers,
        n_steps=args.steps,
        seed=args.seed,
        progress=not args.no_progress,
        backend=backend,
        block_seconds=args.block_seconds,
        omega_max=args.omega_max,
        form=args.form,
        domain=args.domain,
    )


def cmd_diagnose(args) -> int:
    """``hosid diagnose``: name the effect that closes the gap; write its report."""
    from hosid.check.diagnose import diagnose
    from hosid.output.diagnosis import write_diagnosis
    from hosid.output.results import save

    record = _read(args.record)
    _check_out(args.out)
    candidates = None
    if args.candidates is not None:
        candidates = [c.strip() for c in args.candidates.split(",") if c.strip()]
    diag = diagnose(
        record,
        args.model,
        rng=np.random.default_rng(args.seed),
        candidates=candidates,
        replicates=args.replicates,
        alpha=args.alpha,
        threshold=args.threshold,
        max_effects=args.max_effects,
        posterior=args.posterior,
        progress=not args.no_progress,
    )
    out = _out_dir(args.out)
    paths = []
    if diag.final.tree is not None:
        paths.append(save(diag.final_tree, out / "posterior.nc"))
    paths += write_diagnosis(diag, out)
    rep = diag.report()
    gaps = " -> ".join(_fmt(g) for g in rep["gaps"])
    print(f"base {' + '.join(rep['base'])}: gap {gaps}")
    print(f"named: {', then '.join(rep['named_effects']) or 'none'} - {rep['decision']}")
    print("wrote " + ", ".join(str(p) for p in paths))
    return 0


def cmd_report(args) -> int:
    """``hosid report``: rewrite a fit's report from its posterior.nc."""
    from hosid.output.report import write_report
    from hosid.output.results import load

    out = Path(args.dir)
    tree = load(out / "posterior.nc")
    paths = write_report(tree, out)
    print("wrote " + ", ".join(str(p) for p in paths))
    return 0


def cmd_demo(args) -> int:
    """``hosid demo``: simulate the paper oscillator and fit it."""
    from hosid.model.simulate import PAPER_PARAMS, simulate
    from hosid.record import write_record

    out = _out_dir(args.out)
    record = simulate(
        PAPER_PARAMS,
        duration=2000.0,
        dt=0.02,
        rng=np.random.default_rng(args.seed),
        name="demo_record",
    )
    write_record(record, out / "demo_record.csv")
    print(f"paper oscillator {PAPER_PARAMS}, 2000 s at dt = 0.02 s, seed {args.seed}")
    return _fit_and_report(
        record, out, truths=dict(PAPER_PARAMS), seed=args.seed, progress=not args.no_progress
    )
