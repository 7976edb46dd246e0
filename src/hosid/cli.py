"""Command line interface: ``hosid simulate``, ``estimate``, ``demo``, ``fit``, ``report``.

Bad input of any kind ends with exactly one line ``hosid: error: <message>``
on stderr and exit code 2, without a traceback.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any, NoReturn

import numpy as np

from hosid import __version__
from hosid.errors import HosidInputError
from hosid.records import Record, check_blocks, read_record, write_record

__all__ = ["PAPER_PARAMS", "main"]

#: Parameters of the paper's oscillator (section 7) with the S0 of Figures 6-8.
PAPER_PARAMS: dict[str, float] = {"a1": 0.5, "n1": 0.5, "a2": 25.0, "n2": 5.0, "S0": 100.0}
METHODS = ("moments", "J2", "J4A", "J4B", "paper")
WINDOWS = ("hann", "boxcar")
ESTIMATE_KEYS = ("a1", "n1", "a2", "n2", "S0", "a1eq")
DEMO_METHODS = ("moments", "J2", "paper", "J4A")
FIT_COSTS = ("J2", "J4A", "J4B")
#: Columns of the summary table ``hosid fit`` prints.
FIT_COLUMNS = ("mean", "sd", "q05", "q50", "q95", "r_hat", "ess_bulk")
EXIT_USAGE = 2


class _UsageError(Exception):
    """Raised by the parser instead of printing usage and exiting."""


class _Parser(argparse.ArgumentParser):
    """An ``ArgumentParser`` whose errors become one-line messages."""

    def error(self, message: str) -> NoReturn:
        """Raise instead of printing the usage and exiting."""
        raise _UsageError(message)


# --- argument types ---------------------------------------------------------------------


def _number(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"must be finite, got {text!r}")
    return value


def _positive(text: str) -> float:
    value = _number(text)
    if value <= 0:
        raise argparse.ArgumentTypeError(f"must be positive, got {text!r}")
    return value


def _nonnegative(text: str) -> float:
    value = _number(text)
    if value < 0:
        raise argparse.ArgumentTypeError(f"must be non-negative, got {text!r}")
    return value


def _seed(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not an integer: {text!r}") from None
    if value < 0:
        raise argparse.ArgumentTypeError(f"must be non-negative, got {text!r}")
    return value


def _count(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not an integer: {text!r}") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be at least 1, got {text!r}")
    return value


def _check_params(params: Mapping[str, float]) -> None:
    """Reject oscillators without a stationary response."""
    if params["a1"] + params["n1"] <= 0:
        raise HosidInputError("the oscillator needs damping: a1 + n1 must be positive")
    if params["n2"] == 0 and params["a2"] <= 0:
        raise HosidInputError("the oscillator needs a restoring force: a2 > 0 when n2 = 0")


def _check_sampling(duration: float, dt: float) -> None:
    n = round(duration / dt)
    if n < 16:
        raise HosidInputError(
            f"duration {duration:g} s at dt {dt:g} s gives {n} samples; at least 16 are needed"
        )


# --- output helpers ---------------------------------------------------------------------


def _jsonable(value: Any) -> Any:
    """Convert numpy values to plain Python and NaN/inf to ``None``."""
    if isinstance(value, Mapping):
        return {str(k): _jsonable(v) for k, v in value.items()}
    if isinstance(value, np.ndarray):
        return _jsonable(value.tolist())
    if isinstance(value, list | tuple):
        return [_jsonable(v) for v in value]
    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, Path):
        return str(value)
    return value


def _write_json(data: Any, path: Path) -> None:
    try:
        path.write_text(json.dumps(_jsonable(data), indent=2, allow_nan=False) + "\n")
    except OSError as exc:
        raise HosidInputError(f"cannot write {path}: {exc.strerror or exc}") from None


def _fmt(value: Any) -> str:
    if value is None:
        return "-"
    try:
        number = float(value)
    except (TypeError, ValueError):
        return str(value)
    return "-" if math.isnan(number) else f"{number:.4g}"


def _keys(*dicts: Mapping[str, Any]) -> list[str]:
    """Known estimate keys in order, then any extra keys the estimators return."""
    extra = [k for d in dicts for k in d if k not in ESTIMATE_KEYS]
    return [*ESTIMATE_KEYS, *dict.fromkeys(extra)]


def _table(header: Sequence[str], rows: Sequence[Sequence[str]]) -> str:
    """Render a plain text table with aligned columns."""
    widths = [max(len(r[i]) for r in [header, *rows]) for i in range(len(header))]
    lines = [
        "  ".join(c.ljust(w) for c, w in zip(row, widths, strict=True)).rstrip()
        for row in [header, *rows]
    ]
    lines.insert(1, "  ".join("-" * w for w in widths))
    return "\n".join(lines)


def _markdown(header: Sequence[str], rows: Sequence[Sequence[str]]) -> str:
    out = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    out += ["| " + " | ".join(row) + " |" for row in rows]
    return "\n".join(out)


# --- commands ---------------------------------------------------------------------------


def _simulate(params: Mapping[str, float], duration: float, dt: float, seed: int) -> Record:
    _check_params(params)
    _check_sampling(duration, dt)
    from hosid.simulate import simulate

    rng = np.random.default_rng(seed)
    return simulate(dict(params), duration=duration, dt=dt, rng=rng)


def _check_spectral(record: Record, block_seconds: float, omega_max: float) -> None:
    """Reject blocks shorter than two samples, too few blocks, or a band past Nyquist."""
    block_samples = round(block_seconds / record.dt)
    if block_samples < 2:
        raise HosidInputError(
            f"block of {block_seconds:g} s is shorter than two samples at dt={record.dt:g}"
        )
    check_blocks(record, block_samples)
    nyquist = math.pi / record.dt
    if omega_max > nyquist:
        raise HosidInputError(
            f"omega-max {omega_max:g} rad/s exceeds the Nyquist frequency {nyquist:.4g} rad/s"
        )


def _estimate(
    record: Record,
    method: str,
    window: str,
    block_seconds: float,
    omega_max: float,
    domain: str = "principal",
    form: str = "scaled",
) -> dict[str, Any]:
    _check_spectral(record, block_seconds, omega_max)
    from hosid.estimators import estimate

    return estimate(
        record,
        method=method,
        window=window,
        block_seconds=block_seconds,
        omega_max=omega_max,
        domain=domain,
        form=form,
    )


def _cmd_simulate(args: argparse.Namespace) -> int:
    out = Path(args.out)
    if out.suffix.lower() not in (".csv", ".npz"):
        raise HosidInputError(
            f"{out}: unknown file type {out.suffix or '(none)'!r}; use .csv or .npz"
        )
    params = {k: getattr(args, k) for k in PAPER_PARAMS}
    for k in ("b2", "mu", "m", "wc", "noise_sd"):
        if getattr(args, k, None) is not None:
            params[k] = getattr(args, k)
    record = _simulate(params, args.duration, args.dt, args.seed)
    write_record(record, out)
    sidecar = out.with_suffix(".truths.json")  # read back by `hosid fit` for its plots
    _write_json(params, sidecar)
    print(f"wrote {out}: {record.n} samples, dt={record.dt:g} s (true parameters: {sidecar})")
    return 0


def _cmd_estimate(args: argparse.Namespace) -> int:
    record = read_record(args.record)
    result = _estimate(
        record,
        args.method,
        args.window,
        args.block_seconds,
        args.omega_max,
        args.domain,
        args.form,
    )
    estimates = result.get("estimates", {})
    print(f"{record.name or args.record}: method {result.get('method', args.method)}")
    print(
        _table(["parameter", "estimate"], [[k, _fmt(estimates.get(k))] for k in _keys(estimates)])
    )
    if args.json is not None:
        _write_json(result, Path(args.json))
    return 0


def _a1eq_truth(params: Mapping[str, float], sigma_v: float) -> float:
    r"""Equivalent linear damping of a simulated record, eq (65):
    :math:`a_{1,eq} = a_1 + n_1 \sqrt{8/\pi}\,\sigma_v` with the simulated velocity's sd.
    """
    return params["a1"] + params["n1"] * math.sqrt(8 / math.pi) * sigma_v  # eq (65)


def _cmd_demo(args: argparse.Namespace) -> int:
    out = Path(args.out)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise HosidInputError(f"cannot create {out}: {exc.strerror or exc}") from None
    duration, dt = 2000.0, 0.02
    from hosid.simulate import simulate

    record, velocity = simulate(
        dict(PAPER_PARAMS),
        duration=duration,
        dt=dt,
        rng=np.random.default_rng(args.seed),
        return_velocity=True,
    )
    write_record(record, out / "demo_record.csv")
    truth = {**PAPER_PARAMS, "a1eq": _a1eq_truth(PAPER_PARAMS, float(np.std(velocity)))}
    settings = {"window": "hann", "block_seconds": 20.48, "omega_max": 8.0}
    results = {m: _estimate(record, m, **settings) for m in DEMO_METHODS}

    header = ["parameter", "truth", *DEMO_METHODS]
    est = {m: r.get("estimates", {}) for m, r in results.items()}
    rows = [
        [k, _fmt(truth.get(k)), *(_fmt(est[m].get(k)) for m in DEMO_METHODS)]
        for k in _keys(*est.values())
    ]
    print(
        f"paper oscillator, S0={PAPER_PARAMS['S0']:g}, {duration:g} s at dt={dt:g} s, "
        f"seed {args.seed}"
    )
    print(_table(header, rows))

    _write_json(
        {"seed": args.seed, "duration": duration, "dt": dt, "truth": truth, "results": results},
        out / "estimates.json",
    )
    report = "\n".join(
        [
            "# hosid demo",
            "",
            "Paper oscillator (Vasta & Roberts 1998, section 7) with "
            f"S0 = {PAPER_PARAMS['S0']:g},",
            f"{duration:g} s at dt = {dt:g} s, seed {args.seed}; Hann window, blocks of 20.48 s,",
            "frequencies up to 8 rad/s. The true a1eq uses the record's central-difference",
            "velocity in eq (65). A dash marks a parameter the method does not estimate.",
            "",
            _markdown(header, rows),
            "",
        ]
    )
    try:
        (out / "report.md").write_text(report)
    except OSError as exc:
        raise HosidInputError(f"cannot write {out / 'report.md'}: {exc.strerror or exc}") from None
    print(f"wrote {out}/demo_record.csv, {out}/estimates.json, {out}/report.md")

    # the Bayesian fit of the same record: posterior, corner plot, HTML report
    from hosid import results as _results

    print("sampling the J4A pseudo-posterior (calibration, then emcee) ...")
    tree = _run_fit(
        record,
        cost="J4A",
        form="scaled",
        constrained=True,
        n_walkers=16,
        n_steps=None,
        seed=args.seed,
        progress=True,
        backend=None,
        window="hann",
        block_seconds=20.48,
        omega_max=8.0,
        domain="principal",
        truths=dict(PAPER_PARAMS),
    )
    fit_dir = out / "fit"
    fit_dir.mkdir(parents=True, exist_ok=True)
    _results.save(tree, fit_dir / "posterior.nc")
    paths = _write_fit_report(tree, fit_dir)
    _print_summary(_results.summarize(tree, warn=False))
    print("wrote " + ", ".join(str(p) for p in paths))
    return 0


def _read_truths(path: Path) -> dict[str, float]:
    """Parameter values from a JSON object such as ``{"a1": 0.5, "n1": 0.5}``."""
    try:
        data = json.loads(path.read_text())
    except FileNotFoundError:
        raise HosidInputError(f"{path}: no such file") from None
    except OSError as exc:
        raise HosidInputError(f"cannot read {path}: {exc.strerror or exc}") from None
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise HosidInputError(f"{path}: not valid JSON ({exc})") from None
    if not isinstance(data, dict) or not data:
        raise HosidInputError(f"{path}: truths must be a JSON object of parameter values")
    truths = {}
    for key, value in data.items():
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise HosidInputError(f"{path}: truth {key!r} must be a number, got {value!r}")
        if not math.isfinite(value):
            raise HosidInputError(f"{path}: truth {key!r} must be finite, got {value!r}")
        truths[key] = float(value)
    return truths


def _sidecar_truths(record_path: Path) -> Path | None:
    """``REC.truths.json`` next to a record (``rec.truths.json`` or ``rec.csv.truths.json``)."""
    for path in (
        record_path.with_suffix(".truths.json"),
        record_path.with_name(record_path.name + ".truths.json"),
    ):
        if path.is_file():
            return path
    return None


def _make_dir(path: Path) -> None:
    if path.exists() and not path.is_dir():
        raise HosidInputError(f"{path}: exists and is not a directory")
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise HosidInputError(f"cannot create {path}: {exc.strerror or exc}") from None


def _run_fit(record: Record, **options: Any) -> Any:
    """``hosid.sampling.fit``, imported only when a fit is run."""
    try:
        from hosid import sampling
    except ModuleNotFoundError as exc:
        if exc.name != "hosid.sampling":
            raise
        raise HosidInputError("fitting needs hosid.sampling, which is missing") from None
    return sampling.fit(record, **options)


def _write_fit_report(tree: Any, out: Path) -> list[Path]:
    """Write the report of a fit into ``out``; return the fit's paths, ``posterior.nc`` first."""
    from hosid.report import FIGURES, write_report

    html_path = write_report(tree, out)
    return [
        out / "posterior.nc",
        html_path,
        out / "summary.json",
        *(out / f"{stem}.png" for stem, _, _ in FIGURES),
    ]


def _print_summary(summary: Mapping[str, Any]) -> None:
    kind = "constrained" if summary.get("constrained") else "unconstrained"
    seconds = summary.get("fit_seconds")
    timing = f", {_fmt(seconds)} s" if seconds is not None else ""
    print(
        f"{summary.get('record') or 'record'}: {summary.get('cost')} cost, {kind}, "
        f"{summary.get('n_walkers')} walkers x {summary.get('n_draws')} draws{timing}"
    )
    params = summary["parameters"]
    rows = [[k, *(_fmt(row.get(c)) for c in FIT_COLUMNS)] for k, row in params.items()]
    print(_table(["parameter", *FIT_COLUMNS], rows))
    failures = summary.get("diagnostic_failures") or []
    if failures:
        print(
            "hosid: warning: convergence diagnostics failed: " + "; ".join(failures),
            file=sys.stderr,
        )


def _cmd_fit(args: argparse.Namespace) -> int:
    n_params = len(PAPER_PARAMS)
    if args.walkers < 2 * n_params or args.walkers % 2:
        raise HosidInputError(
            f"--walkers must be even and at least {2 * n_params} "
            f"(twice the {n_params} parameters), got {args.walkers}"
        )
    backend = args.backend
    if backend is not None and Path(backend).suffix.lower() not in (".h5", ".hdf5"):
        raise HosidInputError(f"{backend}: the backend must be an HDF5 file (.h5 or .hdf5)")
    record_path = Path(args.record)
    record = read_record(record_path)
    _check_spectral(record, args.block_seconds, args.omega_max)
    truths_path = Path(args.truths) if args.truths is not None else _sidecar_truths(record_path)
    truths = _read_truths(truths_path) if truths_path is not None else None
    out = Path(args.out)
    _make_dir(out)

    tree = _run_fit(
        record,
        cost=args.cost,
        form=args.form,
        constrained=not args.unconstrained,
        n_walkers=args.walkers,
        n_steps=args.steps,
        seed=args.seed,
        progress=not args.no_progress,
        backend=backend,
        window=args.window,
        block_seconds=args.block_seconds,
        omega_max=args.omega_max,
        domain=args.domain,
        truths=truths,
    )
    from hosid import results

    results.save(tree, out / "posterior.nc")
    paths = _write_fit_report(tree, out)
    _print_summary(results.summarize(tree, warn=False))
    print("wrote " + ", ".join(str(p) for p in paths))
    return 0


def _cmd_diagnose(args: argparse.Namespace) -> int:
    from hosid.diagnose import diagnose, write_report
    from hosid.terms import Model

    record = read_record(Path(args.record))
    base = Model.from_spec(args.model)
    candidates = None
    if args.candidates is not None:
        candidates = [c.strip() for c in args.candidates.split(",") if c.strip()]
    out = Path(args.out)
    _make_dir(out)
    diag = diagnose(
        record,
        base,
        rng=np.random.default_rng(args.seed),
        candidates=candidates,
        replicates=args.replicates,
        threshold=args.threshold,
        shrink=args.shrink,
        progress=not args.no_progress,
    )
    paths = write_report(diag, out)
    rep = diag.report()
    base_names = " + ".join(rep["base"])
    print(f"base {base_names}: gap {rep['gap_before']:.2f} (z = {rep['z_before']:.1f})")
    for c in rep["candidates"]:
        if c["gap_after"] is None or "error" in c:
            print(f"  + {c['effect']:<20s} failed: {c['error']}")
        else:
            print(f"  + {c['effect']:<20s} gap {c['gap_after']:.2f}  (x{c['shrink']:.2f})")
    print(f"named effect: {rep['named_effect'] or 'none'} - {rep['decision']}")
    print("wrote " + ", ".join(str(p) for p in paths))
    return 0


def _cmd_report(args: argparse.Namespace) -> int:
    from hosid import results

    out = Path(args.dir)
    path = out / "posterior.nc"
    try:
        tree = results.load(path)
    except HosidInputError:
        raise
    except (OSError, ValueError) as exc:
        raise HosidInputError(f"{path}: cannot read ({exc})") from None
    if "posterior" not in tree.children:
        raise HosidInputError(f"{path}: not a hosid fit (no posterior group)")
    paths = _write_fit_report(tree, out)
    print("wrote " + ", ".join(str(p) for p in paths[1:]))
    return 0


# --- parser -----------------------------------------------------------------------------


def _spectral_options(parser: argparse.ArgumentParser) -> None:
    """``--window``, ``--block-seconds``, ``--omega-max``, ``--domain``."""
    parser.add_argument("--window", choices=WINDOWS, default="hann")
    parser.add_argument(
        "--block-seconds",
        type=_positive,
        default=20.48,
        help="block length in seconds, default 20.48",
    )
    parser.add_argument(
        "--omega-max", type=_positive, default=8.0, help="highest frequency used, rad/s, default 8"
    )
    parser.add_argument(
        "--domain",
        choices=("principal", "reduced", "full"),
        default="principal",
        help="trispectral domain: eq (39), eq (64) or all triples; default principal",
    )


def build_parser() -> argparse.ArgumentParser:
    """Build the ``hosid`` argument parser.

    Returns
    -------
    argparse.ArgumentParser
        Parser whose ``error`` raises instead of exiting.
    """
    parser = _Parser(
        prog="hosid",
        allow_abbrev=False,
        description=(
            "Output-only identification of x'' + a1 x' + n1 x'|x'| + a2 x + n2 x^3 = f(t) "
            "from higher-order spectra (Vasta & Roberts 1998)."
        ),
    )
    parser.add_argument("--version", action="version", version=f"hosid {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")

    sim = sub.add_parser("simulate", help="simulate a response record", allow_abbrev=False)
    for name, kind in (
        ("a1", _nonnegative),
        ("n1", _nonnegative),
        ("a2", _number),
        ("n2", _nonnegative),
        ("S0", _positive),
    ):
        sim.add_argument(
            f"--{name}",
            type=kind,
            default=PAPER_PARAMS[name],
            help=f"default {PAPER_PARAMS[name]:g}",
        )
    for name, kind, text in (
        ("b2", _number, "quadratic stiffness b2 x^2"),
        ("mu", _nonnegative, "Coulomb friction mu sign(x')"),
        ("m", _number, "mean force m"),
        ("wc", _positive, "corner (rad/s) of a first-order low-pass on the force"),
        ("noise_sd", _positive, "sd of white measurement noise on x"),
    ):
        sim.add_argument(
            f"--{name.replace('_', '-')}", dest=name, type=kind, help=f"{text}; default none"
        )
    sim.add_argument("--duration", type=_positive, default=2000.0, help="seconds, default 2000")
    sim.add_argument("--dt", type=_positive, default=0.02, help="seconds, default 0.02")
    sim.add_argument("--seed", type=_seed, default=0, help="default 0")
    sim.add_argument("--out", required=True, help="output file, .csv or .npz")
    sim.set_defaults(func=_cmd_simulate)

    est = sub.add_parser("estimate", help="estimate parameters from a record", allow_abbrev=False)
    est.add_argument("record", help="record file, .csv (columns t,x) or .npz")
    est.add_argument("--method", choices=METHODS, default="paper")
    _spectral_options(est)
    est.add_argument(
        "--form",
        choices=("scaled", "literal"),
        default="scaled",
        help="well-scaled costs (default) or the paper's printed forms",
    )
    est.add_argument("--json", metavar="FILE", help="also write the result as JSON")
    est.set_defaults(func=_cmd_estimate)

    demo = sub.add_parser(
        "demo", help="simulate the paper oscillator and estimate it", allow_abbrev=False
    )
    demo.add_argument("--out", default="demo-out", help="output directory, default demo-out")
    demo.add_argument("--seed", type=_seed, default=2026, help="default 2026")
    demo.set_defaults(func=_cmd_demo)

    fit = sub.add_parser(
        "fit", help="sample the posterior of the parameters (emcee)", allow_abbrev=False
    )
    fit.add_argument("record", help="record file, .csv (columns t,x) or .npz")
    fit.add_argument("--cost", choices=FIT_COSTS, required=True, help="cost behind the likelihood")
    fit.add_argument(
        "--form",
        choices=("scaled", "literal"),
        default="scaled",
        help="well-scaled costs (default) or the paper's printed forms",
    )
    fit.add_argument(
        "--unconstrained",
        action="store_true",
        help="drop the eq-65 constraint a1eq > 0 (positive equivalent damping)",
    )
    fit.add_argument(
        "--walkers",
        type=_count,
        default=24,
        help="number of walkers, even and at least twice the parameters; default 24",
    )
    fit.add_argument(
        "--steps", type=_count, default=None, help="steps per walker; default automatic"
    )
    fit.add_argument("--seed", type=_seed, default=0, help="default 0")
    fit.add_argument("--backend", metavar="FILE.h5", help="also store the chain in an HDF5 file")
    fit.add_argument("--no-progress", action="store_true", help="no progress bar")
    _spectral_options(fit)
    fit.add_argument(
        "--truths",
        metavar="FILE.json",
        help="true parameter values (default: REC.truths.json next to the record, if any)",
    )
    fit.add_argument("--out", required=True, metavar="DIR", help="output directory")
    fit.set_defaults(func=_cmd_fit)

    dia = sub.add_parser(
        "diagnose",
        help="find the gap between a model and the record and name the missing effect",
        allow_abbrev=False,
    )
    dia.add_argument("record", help="record file, .csv (columns t,x) or .npz")
    dia.add_argument(
        "--model",
        default="paper",
        metavar="BASE",
        help="base model: linear, paper, or comma-separated term names; default paper",
    )
    dia.add_argument(
        "--candidates",
        metavar="LIST",
        help="comma-separated effects to try; default every candidate not in BASE",
    )
    dia.add_argument(
        "--replicates", type=_count, default=20, help="replicates per model; default 20"
    )
    dia.add_argument(
        "--threshold",
        type=float,
        default=3.0,
        help="robust z of the base gap above its null for significance; default 3",
    )
    dia.add_argument(
        "--shrink",
        type=float,
        default=0.75,
        help="the named effect must cut the gap to this fraction or less; default 0.75",
    )
    dia.add_argument("--seed", type=_seed, default=0, help="default 0")
    dia.add_argument("--no-progress", action="store_true", help="no progress bar")
    dia.add_argument("--out", required=True, metavar="DIR", help="output directory")
    dia.set_defaults(func=_cmd_diagnose)

    rep = sub.add_parser(
        "report", help="rewrite the report of a fit from DIR/posterior.nc", allow_abbrev=False
    )
    rep.add_argument("dir", metavar="DIR", help="directory of a fit (holding posterior.nc)")
    rep.set_defaults(func=_cmd_report)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run the ``hosid`` command line.

    Parameters
    ----------
    argv : sequence of str, optional
        Arguments without the program name; ``sys.argv[1:]`` by default.

    Returns
    -------
    int
        Exit code: 0 on success, 2 on bad input (after one line on stderr).
    """
    try:
        parser = build_parser()
        args = parser.parse_args(argv)
        if args.command is None:
            parser.error(
                "a command is required: simulate, estimate, demo, fit, diagnose or report"
            )
        func: Callable[[argparse.Namespace], int] = args.func
        return func(args)
    except (_UsageError, HosidInputError) as exc:
        message = " ".join(str(exc).split())
        print(f"hosid: error: {message}", file=sys.stderr)
        return EXIT_USAGE


if __name__ == "__main__":
    sys.exit(main())
