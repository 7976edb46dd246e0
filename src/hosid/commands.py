"""The commands behind ``hosid``: what each one reads, runs and writes.

:mod:`hosid.cli` parses the arguments and maps errors; every function here takes the
parsed ``argparse.Namespace`` and returns an exit code.
"""

from __future__ import annotations

import json
import os
import sys
from pathlib import Path

import numpy as np

from hosid.errors import HosidInputError
from hosid.output.console import fmt, print_fit, table
from hosid.system_commands import locate_system, simulate_system, system_file

#: Old ``--method`` names of ``hosid estimate`` and the cost they now mean.
METHODS = {
    "default": None,
    "J2": "J2",
    "J4A": "J4A",
    "J4B": "J4B",
    "paper": "J4A",
    "moments": "J2",
}
#: The chain a ``hosid fit`` keeps in its ``--out`` folder until the fit is written.
CHAIN_NAME = ".hosid-chain.h5"


def _read(path: str, measured: str | None = None):
    """The record of ``path``; with ``measured`` (``--measured``) every channel declared
    a displacement or an acceleration (an error when the file says otherwise).
    """
    from hosid.record import read_record

    record = read_record(Path(path))
    return record if measured is None else record.select(record.channels, measured=measured)


def _model(args):
    """The model of ``--model`` (or a ``.toml`` file's system), with ``--excitation-shape``."""
    if getattr(args, "excitation_shape", None) is None:
        return system_file(args.model)
    from hosid.model.measured import with_shape

    return with_shape(args.model, args.excitation_shape)


# --- commands -------------------------------------------------------------------------
def cmd_simulate(args) -> int:
    """``hosid simulate``: write a simulated record and its true parameters."""
    from hosid.model.change import Change
    from hosid.model.simulate import simulate
    from hosid.output.files import write_atomic
    from hosid.record import write_record

    out = Path(args.out)
    if out.suffix.lower() not in (".csv", ".npz"):
        raise HosidInputError(
            f"{out}: unknown file type {out.suffix or '(none)'!r}; use .csv or .npz"
        )
    _check_writable(out)
    if getattr(args, "system", None) or getattr(args, "measured", None) == "acceleration":
        return simulate_system(args, out)
    params = {k: getattr(args, k) for k in ("a1", "n1", "a2", "n2", "S0")}
    params.update(
        {
            k: getattr(args, k)
            for k in ("b2", "mu", "m", "wc", "wb", "rolloff", "wf", "zf", "rate", "noise_sd")
            if getattr(args, k) is not None
        }
    )
    _, change = Change.split(vars(args), options=True)  # --change-at, --ramp, --*-after
    record = simulate(
        params,
        duration=args.duration,
        dt=args.dt,
        rng=np.random.default_rng(args.seed),
        name=out.stem,
        change=change,
    )
    tmp = out.with_name(f".{out.stem}.{os.getpid()}.tmp{out.suffix}")
    try:
        write_record(record, tmp)
        os.replace(tmp, out)
    finally:
        tmp.unlink(missing_ok=True)
    sidecar = out.with_suffix(".truths.json")
    truths = {**params, **(change.flat() if change else {})}
    write_atomic(sidecar, json.dumps(truths, indent=2) + "\n")
    said = f" (true parameters: {sidecar})" + (f"; {change.describe(params)}" if change else "")
    print(f"wrote {out}: {record.n} samples, dt={record.dt:g} s{said}")
    return 0


def _estimate_modes(est, cov) -> list | None:
    """A system's modes of its linear terms at the estimate (delta method), printed."""
    from hosid.model.modal import estimate_modes, small_slopes
    from hosid.model.system import System

    if not isinstance(est.model, System):
        return None
    modes = estimate_modes(est.model, est.theta, cov, small_slopes(est.model))
    rows = [[str(j + 1), *(fmt(m[k][s]) for k in ("frequency_hz", "damping_ratio")
                           for s in ("mean", "sd"))] for j, m in enumerate(modes)]  # fmt: skip
    print("modes of the linear terms (small amplitude; sd by the delta method):")
    print(table(["mode", "f (Hz)", "sd", "zeta", "sd"], rows) if rows else "none underdamped")
    return modes


def cmd_estimate(args) -> int:
    """``hosid estimate``: the calibrated mode, its sd and 90 % interval, no sampling."""
    from hosid.inference import components_for, estimate
    from hosid.inference.calibrate import calibrate
    from hosid.model.system import System

    record = _read(args.record, args.measured)
    if args.json:
        _check_writable(Path(args.json))
    checks = _checked(args, record)
    cost = args.cost if args.method is None else METHODS[args.method]
    band = None if args.omega_max is None else (0.0, args.omega_max)
    comps = components_for(cost, band=band, form=args.form, domain=args.domain)
    est = estimate(
        record,
        _model(args),
        comps,
        block_seconds=args.block_seconds,
        force=args.force,
        unit=args.unit,
        checks=checks,
    )
    cal = calibrate(est)  # the adjusted curvature, widened when Hansen's test rejects
    names = list(est.model.param_names)
    values = est.theta.tolist()
    cov = cal.cov
    if not isinstance(est.model, System) and est.model.has("a1"):  # a system: per element
        g = np.array(
            [t.damping_factor(est.sigma_v) for t in est.model.drift_terms]
            + [0.0] * (len(est.theta) - est.model.n_drift)
        )
        names.append("a1eq")
        values.append(float(g @ est.theta))
        k = len(est.theta)
        G = np.vstack([np.eye(k), g])
        cov = G @ cov @ G.T
    sd = np.sqrt(np.diag(cov))
    z = 1.6448536269514722  # the 95 % quantile of N(0, 1)
    label = "default"  # a system's by name: its record may call for the spectral matrix
    if isinstance(est.model, System):
        label = ", ".join(m.component for m in est.ql.moments)
    print(
        f"{record.name or args.record}: {est.model!r}, {cost or label} components; "
        f"Hansen J = {fmt(est.test['J'])} on {est.test['df']} df "
        f"(p = {fmt(est.test['p_value'])})"
    )
    rows = [
        [n, fmt(v), fmt(s), fmt(v - z * s), fmt(v + z * s)]
        for n, v, s in zip(names, values, sd, strict=True)
    ]
    print(table(["parameter", "estimate", "sd", "5%", "95%"], rows))
    modes = _estimate_modes(est, cal.cov)
    if args.json:
        from hosid.output.files import write_atomic
        from hosid.output.results import jsonable

        data = {
            "record": record.name,
            "model": list(est.model.names),
            "cost": cost,
            "unit": args.unit,
            "estimates": dict(zip(names, values, strict=True)),
            "sd": dict(zip(names, sd.tolist(), strict=True)),
            "interval90": {
                n: [v - z * s, v + z * s] for n, v, s in zip(names, values, sd, strict=True)
            },
            "uncertainty": "calibrated curvature (Godambe) of the quasi-likelihood at its mode",
            "calibration": cal.describe(),
            "hansen": est.test,
            "checks": [c.as_dict() for c in [*est.checks, cal.check()]],
            "state": est.state.describe(),
            **({"modes": modes} if modes is not None else {}),
        }
        write_atomic(Path(args.json), json.dumps(jsonable(data), indent=2) + "\n")
    return 0


def _check_writable(path: Path) -> None:
    """Fail before any work when ``path`` cannot be written."""
    if path.is_dir():
        raise HosidInputError(f"{path}: is a directory, not a file")
    if not path.parent.is_dir():
        raise HosidInputError(f"cannot write {path}: no folder {path.parent}")


def _check_out(path: str) -> None:
    """Fail before any work when ``--out`` cannot become a directory."""
    out = Path(path)
    if out.exists() and not out.is_dir():
        raise HosidInputError(f"{out}: exists and is not a directory")


def _checked(args, record):
    """The record's checks (:func:`hosid.screen.check_record`); a failure ends the command
    with :class:`~hosid.errors.RecordRejected` (exit 3) unless ``--force``.
    """
    from hosid.screen import check_record, reject_failures

    checks = check_record(record, unit=args.unit)
    reject_failures(checks, force=args.force)
    for c in checks:
        if c.status != "pass":
            print(f"hosid: {c.status}: {c.name}: {c.message}", file=sys.stderr)
    return checks


def _write_fit(tree, stage: Path, figures) -> list[str]:
    """``posterior.nc`` and the report, the figures drawn by ``figures`` meanwhile
    (:class:`hosid.output.render.FigureProcesses`) when it runs.
    """
    from hosid.output.report import write_report
    from hosid.output.results import save

    images = figures.handed(tree)
    save(tree, stage / "posterior.nc")
    return ["posterior.nc", *(p.name for p in write_report(tree, stage, images=images))]


def _fit_into(out: Path, record, *, command: str, backend: str | None, extra=None, **options):
    """Fit ``record`` into the locked, staged folder ``out`` (:mod:`hosid.output.files`).

    The chain is kept in ``--backend`` or in ``out/.hosid-chain.h5`` until the fit is
    written, so that the same command resumes it after Ctrl-C.  The figures are drawn
    in processes started before the fit (:mod:`hosid.output.render`).  ``extra(stage)``
    writes more files into the same commit and returns their names.
    """
    from hosid.inference import fit
    from hosid.inference.structure import resolve
    from hosid.output.files import locked_dir, staged
    from hosid.output.render import FigureProcesses, corner_size
    from hosid.progress import Stages

    corner = corner_size(resolve(options.get("system"), options.get("model")))
    stages = Stages("hosid fit", enabled=bool(options.pop("progress", True)))
    try:
        with locked_dir(out, command=command), FigureProcesses(corner=corner) as figures:
            chain = Path(backend) if backend else out / CHAIN_NAME
            stages.stage("estimate")
            try:
                tree = fit(record, backend=chain, progress=stages, **options)
            except HosidInputError as exc:
                if backend or "holds a chain of another" not in str(exc):
                    raise
                chain.unlink()  # an interrupted run with other settings: start afresh
                tree = fit(record, backend=chain, progress=stages, **options)
            stages.stage("report")
            with staged(out, command=command) as stage:
                names = _write_fit(tree, stage, figures) + (extra(stage) if extra else [])
            if not backend:
                chain.unlink(missing_ok=True)
    finally:
        stages.close()
    print_fit(json.loads((out / "summary.json").read_text(encoding="utf-8")))
    print("wrote " + ", ".join(str(out / n) for n in names))
    return 0


def cmd_fit(args) -> int:
    """``hosid fit``: sample the posterior; write posterior.nc and the report."""
    backend = args.backend
    if backend is not None and Path(backend).suffix.lower() not in (".h5", ".hdf5"):
        raise HosidInputError(f"{backend}: the backend must be an HDF5 file (.h5 or .hdf5)")
    record = _read(args.record, args.measured)
    from hosid.record import read_truths

    truths = read_truths(Path(args.record), args.truths)
    _check_out(args.out)
    checks = _checked(args, record)
    return _fit_into(
        Path(args.out),
        record,
        command=args.command_line,
        backend=backend,
        truths=truths,
        checks=checks,
        force=args.force,
        unit=args.unit,
        model=_model(args),
        cost=args.cost,
        constrained=not args.unconstrained,
        n_walkers=args.walkers,
        n_steps=args.steps,
        seed=args.seed,
        progress=not args.no_progress,
        block_seconds=args.block_seconds,
        omega_max=args.omega_max,
        form=args.form,
        domain=args.domain,
    )


def cmd_diagnose(args) -> int:
    """``hosid diagnose``: name the effect that closes the gap; write its report."""
    from hosid.check.diagnose import diagnose
    from hosid.check.report import changes_text
    from hosid.output.diagnosis import write_diagnosis
    from hosid.output.files import output_dir
    from hosid.output.results import save

    record = _read(args.record, args.measured)
    _check_out(args.out)
    checks = _checked(args, record)
    candidates = None
    if args.candidates is not None:
        candidates = [c.strip() for c in args.candidates.split(",") if c.strip()]
    from hosid.model.system import System

    model = _model(args)
    if isinstance(model, System):  # a system file: locate the missing effect
        return locate_system(args, record, model, checks, candidates)
    with output_dir(args.out, command=args.command_line) as stage:
        diag = diagnose(
            record,
            model,
            rng=np.random.default_rng(args.seed),
            candidates=candidates,
            replicates=args.replicates,
            alpha=args.alpha,
            threshold=args.threshold,
            max_effects=args.max_effects,
            posterior=args.posterior,
            progress=not args.no_progress,
        )
        diag.record_checks = list(checks)
        names = []
        if diag.final.tree is not None:
            tree = diag.final_tree
            tree.attrs["checks_json"] = json.dumps([c.as_dict() for c in diag.checks()])
            save(tree, stage / "posterior.nc")
            names.append("posterior.nc")
        names += [p.name for p in write_diagnosis(diag, stage)]
    out = Path(args.out)
    rep = diag.report()
    gaps = " -> ".join(fmt(g) for g in rep["gaps"])
    print(f"base {' + '.join(rep['base'])}: gap {gaps}")
    print(f"named: {', then '.join(rep['named_effects']) or 'none'} - {rep['decision']}")
    for st in rep["steps"]:
        print(f"+ {st['effect']} changes: {changes_text(st['changes'])}")
    print("wrote " + ", ".join(str(out / n) for n in names))
    return 0


def cmd_report(args) -> int:
    """``hosid report``: rewrite a fit's report from its posterior.nc."""
    from hosid.output.files import output_dir
    from hosid.output.render import FigureProcesses
    from hosid.output.report import write_report
    from hosid.output.results import load

    out = Path(args.dir)
    with FigureProcesses() as figures:  # they import matplotlib while the fit loads
        tree = load(out / "posterior.nc")
        with output_dir(out, command=args.command_line, keep=("posterior.nc",)) as stage:
            names = [p.name for p in write_report(tree, stage, images=figures.handed(tree))]
    print("wrote " + ", ".join(str(out / n) for n in names))
    return 0


def cmd_demo(args) -> int:
    """``hosid demo``: simulate the paper oscillator and fit it."""
    from hosid.model.simulate import PAPER_PARAMS, simulate
    from hosid.record import write_record

    _check_out(args.out)
    record = simulate(
        PAPER_PARAMS,
        duration=2000.0,
        dt=0.02,
        rng=np.random.default_rng(args.seed),
        name="demo_record",
    )
    print(f"paper oscillator {PAPER_PARAMS}, 2000 s at dt = 0.02 s, seed {args.seed}")

    def extra(stage: Path) -> list[str]:
        return [write_record(record, stage / "demo_record.csv").name]

    return _fit_into(
        Path(args.out),
        record,
        command=args.command_line,
        backend=None,
        extra=extra,
        truths=dict(PAPER_PARAMS),
        seed=args.seed,
        progress=not args.no_progress,
    )
