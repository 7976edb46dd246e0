r"""The Silverbox circuit, output only, against its input-output reference (issue 16).

The Silverbox (``hosid.datasets.load_silverbox``) is measured with input ``V1`` (u) and
output ``V2`` (y).  The *reference* uses both: a least-squares fit of

    y'' + c y' + k1 y + k2 y^2 + k3 y^3 = g u + b

over the steady-state multisine periods, with exact spectral derivatives (each period is
periodic, so the derivative of its DFT is exact below the Nyquist frequency).  In the
output-only model's names: a1 = c, n1 = 0, a2 = k1, n2 = k3, a1eq = c, and S0 = g^2 times
the two-sided level of u in its band (the mean of its spectrum from 0 to the highest
excited line; the level of its lowest lines is reported too, since hosid's S0 under a
coloured excitation is the level at zero frequency).  A second reference fit adds
quadratic damping d y'|y'| to see whether the circuit's damping is linear.

hosid sees only ``V2``: the periods are written as the CSV the project owners use
(columns t, x, segment; the time jumps between periods as in the file) and fitted with
the defaults, as ``hosid fit REC --out DIR`` does; ``hosid diagnose`` follows.  Results go
to ``results/silverbox/``: ``table.md`` (reference, estimate and 90 % interval of every
parameter, for all ten periods and for each half), ``summary.json`` and
``silverbox.png`` (the intervals against the reference, and the restoring force).

    python analyses/silverbox.py                       # all ten periods and both halves
    python analyses/silverbox.py --file PATH --parts all --no-diagnose

The data file is read from ``--file`` or ``$HOSID_SILVERBOX`` (default
``../shared/data/silverbox/Schroeder80mV.mat`` next to the project); it is never copied
into the project.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from hosid.datasets import Silverbox, load_silverbox
from hosid.record import Record, read_record

ROOT = Path(__file__).resolve().parent
RESULTS = ROOT / "results" / "silverbox"
DEFAULT_FILE = ROOT.parent.parent / "shared" / "data" / "silverbox" / "Schroeder80mV.mat"
PARTS = {"all": slice(0, None), "first half": slice(0, 5), "second half": slice(5, None)}
PARAMS = ("a1eq", "a2", "n2", "S0", "a1", "n1")


def data_file() -> Path:
    """The Silverbox file: ``$HOSID_SILVERBOX`` or the shared default."""
    return Path(os.environ.get("HOSID_SILVERBOX", str(DEFAULT_FILE)))


def derivatives(y: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """Exact derivatives of one period of a periodic signal (no Nyquist term)."""
    n = y.size
    Y = np.fft.rfft(y)
    if n % 2 == 0:
        Y[-1] = 0.0
    w = 2.0 * math.pi * np.fft.rfftfreq(n, dt)
    return np.fft.irfft(1j * w * Y, n), np.fft.irfft(-(w**2) * Y, n)


def input_level(inputs, dt: float) -> dict[str, float]:
    """Two-sided spectral level of u in its band (mean over the band) and of its lowest
    lines, and the band edge (the highest excited line), from the periods' DFTs.
    """
    n = inputs[0].size
    P = np.mean([np.abs(np.fft.rfft(u - u.mean())) ** 2 for u in inputs], axis=0)
    P = P * dt / (2.0 * math.pi * n)  # two-sided PSD per rad/s on the DFT bins
    w = 2.0 * math.pi * np.fft.rfftfreq(n, dt)
    lines = np.flatnonzero(P > 1e-2 * P.max())  # (a spur at 250 Hz reaches 1.2e-3)
    edge = float(w[lines[-1]])
    band = (w > 0) & (w <= edge)
    return {
        "level_band": float(P[band].mean()),
        "level_low": float(P[band][: max(8, band.sum() // 50)].mean()),
        "edge_rad_s": edge,
    }


def reference(sb: Silverbox, *, quadratic_damping: bool = False) -> dict[str, float]:
    """The input-output least-squares reference (module docstring)."""
    dt = sb.record.dt
    rows, rhs = [], []
    for y, u in zip(sb.record.split(sb.record.x), sb.inputs, strict=True):
        yd, ydd = derivatives(y, dt)
        cols = [-yd] + ([-yd * np.abs(yd)] if quadratic_damping else [])
        rows.append(np.column_stack([*cols, -y, -(y**2), -(y**3), u, np.ones_like(y)]))
        rhs.append(ydd)
    A, r = np.vstack(rows), np.concatenate(rhs)
    theta, *_ = np.linalg.lstsq(A, r, rcond=None)
    names = ["c", *(["d"] if quadratic_damping else []), "k1", "k2", "k3", "g", "b"]
    ref = dict(zip(names, theta.tolist(), strict=True))
    resid = r - A @ theta
    level = input_level(sb.inputs, dt)
    sigma_v = float(np.std(A[:, 0]))
    mu = float(np.mean(sb.record.x))
    ref.update(
        {
            "residual_rms": float(np.std(resid)),
            "acceleration_rms": float(np.std(r)),
            "a1": ref["c"],
            "n1": ref.get("d", 0.0),
            "a1eq": ref["c"] + ref.get("d", 0.0) * math.sqrt(8 / math.pi) * sigma_v,
            "a2": ref["k1"],
            "n2": ref["k3"],
            "S0": ref["g"] ** 2 * level["level_band"],
            "S0_low": ref["g"] ** 2 * level["level_low"],
            "edge_rad_s": level["edge_rad_s"],
            "output_mean": mu,
            # what centring x = y - mean(y) does to the linear stiffness
            "a2_centred": ref["k1"] + 2 * ref["k2"] * mu + 3 * ref["k3"] * mu**2,
            # the mean force of the paper's model plus excitation_mean on the raw output
            # (x'' + a1 x' + a2 x + n2 x^3 - m = f, E f = 0): the offset b, the input's
            # mean and the mean of the quadratic stiffness the model lacks
            "m": ref["g"] * float(np.mean(np.concatenate(sb.inputs)))
            + ref["b"]
            - ref["k2"] * float(np.mean(sb.record.x**2)),
        }
    )
    return ref


def owners_csv(sb: Silverbox, parts: slice, path: Path) -> Path:
    """The periods as the owners' CSV: t (as in the file), x, segment (1, 2, ...)."""
    dt = sb.record.dt
    with path.open("w") as fh:
        fh.write("t,x,segment\n")
        pieces = sb.record.split(sb.record.x)[parts]
        for k, (start, y) in enumerate(zip(sb.starts[parts], pieces, strict=True)):
            t = (start + np.arange(y.size)) * dt
            fh.writelines(
                f"{float(ti)!r},{float(yi)!r},{k + 1}\n" for ti, yi in zip(t, y, strict=True)
            )
    return path


def part(sb: Silverbox, parts: slice) -> Silverbox:
    """The periods ``parts`` of ``sb``."""
    pieces = sb.record.split(sb.record.x)[parts]
    rec = Record.from_segments(pieces, sb.record.dt, sb.record.name)
    return Silverbox(rec, sb.inputs[parts], sb.starts[parts], sb.period)


def fit_part(record: Record, *, seed: int) -> tuple[dict, dict]:
    """hosid's default fit (what ``hosid fit REC`` runs): summary rows and attrs."""
    from hosid.inference import fit
    from hosid.output.results import attr, summarize

    t0 = time.perf_counter()
    tree = fit(record, seed=seed, progress=False, with_map=False)
    seconds = time.perf_counter() - t0
    summary = summarize(tree, warn=False)
    post = tree["posterior"]
    extra = {}
    if "rolloff" in post:  # the model's mean level over its band, S0 atan(r) / r
        r = np.sqrt(np.maximum(np.asarray(post["rolloff"]).ravel(), 1e-12))
        band = np.asarray(post["S0"]).ravel() * np.arctan(r) / r
        extra["S0_band"] = {
            "mean": float(band.mean()),
            "q05": float(np.quantile(band, 0.05)),
            "q95": float(np.quantile(band, 0.95)),
        }
    info = {
        "fit_seconds": seconds,
        "model": attr(tree, "model"),
        "notes": attr(tree, "record_notes"),
        "state": attr(tree, "state"),
        "hansen": attr(tree, "calibration", {}).get("hansen"),
        "draws": {
            k: np.asarray(post[k]).ravel()[:: max(1, post[k].size // 4000)].tolist()
            for k in ("a2", "n2")
        },
    }
    return {**summary["parameters"], **extra}, info


def _row(name: str, reference: float, s: dict) -> dict:
    return {
        "parameter": name,
        "reference": reference,
        "estimate": s["mean"],
        "q05": s["q05"],
        "q95": s["q95"],
        "holds": bool(s["q05"] <= reference <= s["q95"]),
        "error_percent": 100.0 * (s["mean"] - reference) / reference if reference else math.nan,
    }


def table(ref: dict, params: dict, ref_d: dict | None = None) -> list[dict]:
    """One row per parameter: reference, estimate (posterior mean) and 90 % interval;
    ``a1`` and ``n1`` against the reference with quadratic damping ``ref_d`` too; ``S0``
    (the model's level at zero frequency) against the reference level of the band and of
    its lowest lines, and the model's mean level over its band.
    """
    rows = [_row(p, ref[p], params[p]) for p in PARAMS if p in params]
    if ref_d is not None:  # the circuit's damping is not quite linear
        rows += [_row(f"{p} (vs quadratic damping)", ref_d[p], params[p]) for p in ("a1", "n1")]
    if "S0" in params:
        rows.append(_row("S0 (vs the lowest lines)", ref["S0_low"], params["S0"]))
    if "S0_band" in params:
        rows.append(_row("S0 (band mean)", ref["S0"], params["S0_band"]))
    return rows


def run_diagnose(csv: Path, out: Path, *, seed: int, ref: dict | None = None) -> dict:
    """``hosid diagnose`` on the owners' CSV: its decision (or its error), the gap after
    each step, every named parameter's posterior against the reference where it has
    one, what each named model changes, and the time.
    """
    from hosid.check.diagnose import diagnose
    from hosid.check.report import changes_text

    t0 = time.perf_counter()
    try:
        d = diagnose(read_record(csv), "paper", rng=np.random.default_rng(seed))
    except Exception as exc:  # the analysis reports what the command says
        return {"error": f"{type(exc).__name__}: {exc}", "seconds": time.perf_counter() - t0}
    rep = d.report()
    named = []
    for st in rep["steps"]:
        post = st["posterior"]
        truth = (ref or {}).get(post["param"])
        named.append(
            {
                "effect": st["effect"],
                "param": post["param"],
                "mean": post["mean"],
                "sd": post["sd"],
                "q05": post["q05"],
                "q95": post["q95"],
                "reference": truth,
                "holds": None if truth is None else post["q05"] <= truth <= post["q95"],
                "changes": changes_text(st["changes"]),
            }
        )
    return {
        "named_effects": d.named_effects,
        "decision": d.decision,
        "gaps": rep["gaps"],
        "named": named,
        "final_model": rep["final_model"],
        "seconds": time.perf_counter() - t0,
    }


def figure(results: dict, ref: dict, path: Path) -> None:
    """Intervals relative to the reference, and the restoring force."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(11, 4.2))
    keep = [r["parameter"] for r in results["all"]["table"] if r["reference"]]  # not n1 = 0
    names = keep
    for j, (label, res) in enumerate(results.items()):
        for i, row in enumerate(r for r in res["table"] if r["parameter"] in keep):
            y = i + 0.25 * (j - 1)
            rel = [100 * (row[k] - row["reference"]) / row["reference"] for k in ("q05", "q95")]
            ax1.plot(rel, [y, y], lw=3, color=f"C{j}", label=label if i == 0 else None)
            ax1.plot(100 * (row["estimate"] - row["reference"]) / row["reference"], y, "k|")
    ax1.axvline(0, color="k", lw=0.8)
    ax1.set_yticks(range(len(names)), names)
    ax1.set_xlabel("90 % interval and mean, % of the input-output reference")
    ax1.legend(fontsize=8)
    x = np.linspace(-3.0, 3.0, 201) * results["all"]["sigma_x"]
    k1 = ref["a2_centred"]  # the reference's linear stiffness in x = y - mean(y)
    quad = ref["k2"] + 3 * ref["k3"] * ref["output_mean"]
    ax2.plot(x, quad * x**2 + ref["k3"] * x**3, "k", lw=1.5, label="reference (k2 kept)")
    draws = results["all"]["draws"]
    a2, n2 = np.asarray(draws["a2"])[:, None], np.asarray(draws["n2"])[:, None]
    lo, hi = np.quantile((a2 - k1) * x + n2 * x**3, [0.05, 0.95], axis=0)
    ax2.fill_between(x, lo, hi, color="C0", alpha=0.4, label="hosid 90 % (all periods)")
    ax2.set_xlabel("x = y - mean(y) (V)")
    ax2.set_ylabel("restoring force - reference k1 x (per unit mass)")
    ax2.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def write_table(results: dict, ref: dict, ref_d: dict, path: Path) -> None:
    """``table.md``."""
    lines = ["# Silverbox: output-only fit against the input-output reference", ""]
    lines += [
        f"Reference (least squares over the periods, residual rms {ref['residual_rms']:.4g} "
        f"of an acceleration rms {ref['acceleration_rms']:.4g}): c = {ref['c']:.5g}, "
        f"k1 = {ref['k1']:.6g}, k2 = {ref['k2']:.5g}, k3 = {ref['k3']:.6g}, "
        f"g = {ref['g']:.6g}, b = {ref['b']:.5g}; S0 = g^2 x (level of u in its band) = "
        f"{ref['S0']:.5g} (its lowest lines: {ref['S0_low']:.5g}); band edge "
        f"{ref['edge_rad_s']:.5g} rad/s.  With quadratic damping: c = {ref_d['c']:.5g}, "
        f"d = {ref_d['d']:.4g}, a1eq = {ref_d['a1eq']:.5g}.",
        "",
    ]
    for label, res in results.items():
        lines += [
            f"## {label} ({res['periods']} periods): `hosid fit` defaults, "
            f"{res['fit_seconds']:.1f} s",
            "",
            "| parameter | reference | estimate | q05 | q95 | holds | error % |",
            "|---|---|---|---|---|---|---|",
        ]
        for r in res["table"]:
            lines.append(
                f"| {r['parameter']} | {r['reference']:.5g} | {r['estimate']:.5g} | "
                f"{r['q05']:.5g} | {r['q95']:.5g} | {'yes' if r['holds'] else 'no'} | "
                f"{r['error_percent']:+.2f} |"
            )
        lines += ["", *(f"- {n}" for n in res["notes"] or []), ""]
        if "diagnose" in res:
            lines += _diagnose_lines(res["diagnose"])
    path.write_text("\n".join(lines) + "\n")


def _diagnose_lines(diag: dict) -> list[str]:
    """The diagnose paragraph of ``table.md``."""
    if "error" in diag:
        return [f"`hosid diagnose` failed ({diag['seconds']:.0f} s): {diag['error']}", ""]
    gaps = " -> ".join(f"{g:.3g}" for g in diag["gaps"])
    lines = [
        f"`hosid diagnose` ({diag['seconds']:.0f} s): named "
        f"{', then '.join(diag['named_effects']) or 'nothing'}; gap {gaps}; final model "
        f"{' + '.join(diag['final_model'])}.",
        "",
        f"> {diag['decision']}",
        "",
    ]
    if diag["named"]:
        lines += [
            "| named | parameter | reference | mean +- sd | q05 | q95 | holds |",
            "|---|---|---|---|---|---|---|",
        ]
        for n in diag["named"]:
            ref = "-" if n["reference"] is None else f"{n['reference']:.4g}"
            holds = "-" if n["holds"] is None else ("yes" if n["holds"] else "no")
            lines.append(
                f"| {n['effect']} | {n['param']} | {ref} | {n['mean']:.4g} +- {n['sd']:.3g} | "
                f"{n['q05']:.4g} | {n['q95']:.4g} | {holds} |"
            )
        lines += [""] + [f"- {n['effect']} changes: {n['changes']}" for n in diag["named"]]
        lines += [""]
    return lines


def main(argv=None) -> dict:
    """Run the analysis (module docstring)."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--file", type=Path, default=None)
    ap.add_argument("--out", type=Path, default=RESULTS)
    ap.add_argument("--parts", nargs="+", default=list(PARTS), choices=list(PARTS))
    ap.add_argument("--no-diagnose", action="store_true")
    ap.add_argument("--seed", type=int, default=16)
    args = ap.parse_args(argv)
    path = args.file or data_file()
    if not path.is_file():  # the data are not part of the project
        print(f"silverbox: {path} is absent (set HOSID_SILVERBOX); nothing done", file=sys.stderr)
        return {}
    sb = load_silverbox(path)
    ref = reference(sb)
    ref_d = reference(sb, quadratic_damping=True)
    args.out.mkdir(parents=True, exist_ok=True)
    results = {}
    with tempfile.TemporaryDirectory() as tmp:
        for label in args.parts:
            sl = PARTS[label]
            sub = part(sb, sl)
            csv = owners_csv(sb, sl, Path(tmp) / f"silverbox-{label.replace(' ', '-')}.csv")
            record = read_record(csv)  # exactly what `hosid fit REC` reads
            sub_ref = reference(sub)
            params, info = fit_part(record, seed=args.seed)
            results[label] = {
                "periods": sub.record.n_segments,
                "reference": sub_ref,
                "table": table(ref, params, ref_d),
                "sigma_x": float(np.std(record.x)),
                **info,
            }
            if label == "all" and not args.no_diagnose:
                results[label]["diagnose"] = run_diagnose(csv, Path(tmp), seed=args.seed, ref=ref)
    write_table(results, ref, ref_d, args.out / "table.md")
    slim = {k: {kk: vv for kk, vv in v.items() if kk != "draws"} for k, v in results.items()}
    out = {"reference": ref, "reference_quadratic_damping": ref_d, "results": slim}
    (args.out / "summary.json").write_text(json.dumps(out, indent=1, default=str) + "\n")
    if "all" in results:
        figure(results, ref, args.out / "silverbox.png")
    print((args.out / "table.md").read_text())
    return out


if __name__ == "__main__":
    main()
