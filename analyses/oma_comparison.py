r"""Operational modal analysis beside hosid's modal view, on the same records (issue 33).

Frequency domain decomposition with enhanced-FDD damping (:func:`fdd_modes`, by hand)
and covariance-driven stochastic subspace identification (SSI-cov: koma-python's
``koma.oma.covssi``, its ``oma`` module needs only numpy and scipy; install it with
``pip install --no-deps koma-python``, since its plotting extras pull VTK; pyOMA2 is not
on the package index) and hosid's default fit of the system file are run on the same
records of the independent chain simulator (``independent_chain_sim.py``, 2000 s at
dt = 0.02, displacement channels):

- a **linear** 2-dof chain, where both must agree with the truth's modes (the SSI's
  spread over the records against hosid's posterior sd);
- the **nonlinear** 2-dof chain of ``chain_bound.py`` (cubic springs at the ground and
  between the masses, quadratic damping at the ground) at three force levels (S0 times
  0.25, 1 and 4): an output-only linear analysis sees the modes of the system linearised
  at each level, which move with it; hosid gives the same modes (``modes``, the system
  linearised at the record's response level) and beside them the element laws, which do
  not move.

The truth's response-level modes are those of the true parameters linearised with each
record's own state (:func:`hosid.model.modal.response_slopes` on the simulated
displacements and velocities).  The SSI uses model order 2n (the two modes; no noise on
the channels) and ``BLOCK_ROWS`` block rows.

    pip install --no-deps koma-python
    python analyses/oma_comparison.py              # 4 records a case
    python analyses/oma_comparison.py --summary    # the tables from the fits made
    python analyses/oma_comparison.py --truth      # the truth recomputed, the tables
"""

from __future__ import annotations

import argparse
import csv
import math
import sys
from collections.abc import Sequence
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

import independent_chain_sim  # noqa: E402

import hosid  # noqa: E402
from hosid.model.modal import modal_draws, response_slopes, small_slopes  # noqa: E402
from hosid.model.system import System  # noqa: E402
from hosid.output.results import summarize  # noqa: E402

RESULTS = HERE / "results"
SEED = 20261126
BLOCK_ROWS = 60
#: Samples a Welch segment of FDD's spectra (164 s at dt = 0.02: 0.006 Hz a bin).
FDD_SEGMENT = 8192
ELEMENTS = [
    (("ground", "x1"), ("linear_damping", "linear_stiffness")),
    (("x1", "x2"), ("linear_damping", "linear_stiffness")),
]
NONLINEAR = [
    (("ground", "x1"), ("linear_damping", "quadratic_damping", "linear_stiffness",
                        "cubic_stiffness")),
    (("x1", "x2"), ("linear_damping", "linear_stiffness", "cubic_stiffness")),
]  # fmt: skip
LINEAR_VALUES = {"a1[ground-x1]": 0.3, "a2[ground-x1]": 25.0, "a1[x1-x2]": 0.2,
                 "a2[x1-x2]": 15.0, "mass[x2]": 0.8, "S0[x1]": 2.0, "S0[x2]": 2.0}  # fmt: skip
NONLINEAR_VALUES = {"a1[ground-x1]": 0.3, "n1[ground-x1]": 0.1, "a2[ground-x1]": 25.0,
                    "n2[ground-x1]": 5.0, "a1[x1-x2]": 0.2, "a2[x1-x2]": 15.0,
                    "n2[x1-x2]": 10.0, "mass[x2]": 0.8, "S0[x1]": 2.0, "S0[x2]": 2.0}  # fmt: skip
#: name: (elements, values, force level factor)
CASES = {
    "linear": (ELEMENTS, LINEAR_VALUES, 1.0),
    "nonlinear_S0x0.25": (NONLINEAR, NONLINEAR_VALUES, 0.25),
    "nonlinear_S0x1": (NONLINEAR, NONLINEAR_VALUES, 1.0),
    "nonlinear_S0x4": (NONLINEAR, NONLINEAR_VALUES, 4.0),
}
LAWS = ("a2[ground-x1]", "n2[ground-x1]", "a2[x1-x2]", "n2[x1-x2]")


def system(case: str) -> System:
    """The case's system with its true values (the force levels scaled)."""
    elements, values, level = CASES[case]
    values = {k: v * level if k.startswith("S0") else v for k, v in values.items()}
    return System(("x1", "x2"), elements, values=values)


def ssi_modes(q: np.ndarray, dt: float, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Frequencies (Hz) and damping ratios of the ``n`` modes found by SSI-cov at model
    order ``2n`` in the channels ``q`` ``(dofs, N)``, by increasing frequency."""
    from koma.oma import covssi

    lam, _, _ = covssi(q.T, 1.0 / dt, BLOCK_ROWS, [2 * n], showinfo=False)
    lam = lam[np.argsort(np.abs(lam))]
    return np.abs(lam) / (2 * math.pi), -lam.real / np.abs(lam)


def fdd_modes(q: np.ndarray, dt: float, n: int, nperseg: int = FDD_SEGMENT):
    """Frequencies (Hz) and damping ratios of the ``n`` most prominent modes by frequency
    domain decomposition, the damping by its enhanced form (EFDD; Brincker, Zhang &
    Andersen 2001), of the channels ``q`` ``(dofs, N)``, by increasing frequency.

    Written here (about 30 lines) because pyOMA2 is not on this machine's package index
    and koma-python has no FDD.  The cross-spectral matrix (Welch, Hann, ``nperseg``)
    is decomposed at every frequency; a mode is a peak of the first singular value; its
    bell is the band around the peak where the first singular vector's MAC with the
    peak's exceeds 0.8; the bell's inverse FFT is the mode's free decay, whose extrema
    between 90 % and 10 % of the first give the logarithmic decrement and the damped
    period.
    """
    from scipy import signal

    k = q.shape[0]
    G = np.stack([np.stack([signal.csd(q[a], q[b], fs=1.0 / dt, nperseg=nperseg)[1]
                            for b in range(k)], axis=-1) for a in range(k)], axis=-2)  # fmt: skip
    U, S, _ = np.linalg.svd(G)
    s1, u1 = S[:, 0], U[:, :, 0]
    peaks, props = signal.find_peaks(np.log(s1), prominence=1.0)
    top = np.sort(peaks[np.argsort(props["prominences"])[::-1][:n]])
    norms = np.sum(np.abs(u1) ** 2, axis=1)
    freqs, zetas = [], []
    for p in top:
        mac = np.abs(u1.conj() @ u1[p]) ** 2 / (norms * norms[p])
        lo, hi = p, p
        while lo > 0 and mac[lo - 1] > 0.8:
            lo -= 1
        while hi < s1.size - 1 and mac[hi + 1] > 0.8:
            hi += 1
        bell = np.where((np.arange(s1.size) >= lo) & (np.arange(s1.size) <= hi), s1, 0.0)
        r = np.fft.irfft(bell)[: nperseg // 2]
        r = r / r[0]
        ext = np.flatnonzero(np.diff(np.sign(np.diff(r))) != 0) + 1  # extrema
        amp = np.abs(r[ext])
        use = ext[(amp < 0.9) & (amp > 0.1)]
        if use.size < 3:
            freqs.append(np.nan)
            zetas.append(np.nan)
            continue
        half = np.arange(use.size)
        slope = np.polyfit(half, np.log(np.abs(r[use])), 1)[0]
        delta = -2.0 * slope  # per cycle
        zeta = delta / math.sqrt(4 * math.pi**2 + delta**2)
        fd = 1.0 / (2.0 * dt * np.mean(np.diff(use)))
        freqs.append(fd / math.sqrt(1.0 - zeta**2))
        zetas.append(zeta)
    return np.array(freqs), np.array(zetas)


def simulate_case(case: str, i: int):
    """Record ``i`` of ``case`` (its seed) with the true state: ``(system, record, q, v)``."""
    s = system(case)
    key = list(CASES).index(case)
    seed = np.random.SeedSequence(SEED).spawn(key + 1)[key].spawn(i + 1)[i]
    rec, q, v = independent_chain_sim.simulate(
        s, duration=2000.0, dt=0.02, rng=np.random.default_rng(seed), name=f"{case}-{i}",
        return_state=True,
    )  # fmt: skip
    return s, rec, q, v


def fdd_row(q: np.ndarray) -> dict:
    """FDD's columns of a record's row."""
    f, z = fdd_modes(q.T, 0.02, 2)
    return {f"{x}{j}_fdd": float(v[j]) for j in range(2) for x, v in (("f", f), ("z", z))}


def truth_modes(s: System, q: np.ndarray, v: np.ndarray) -> dict:
    r"""``{"small": (f, zeta), "response": (f, zeta)}`` of the true parameters, the latter
    linearised with the record's own relative displacements and velocities (until
    2026-11-28 given the velocities' sd, which took a quadratic damping's slope
    :math:`E|\dot r|^3/E\dot r^2` as :math:`\sigma` instead of :math:`1.60\sigma`)."""
    B, th, out = s.incidence, s.vector(), {}
    for kind, slopes in (("small", small_slopes(s)),
                         ("response", response_slopes(s, B @ q.T, B @ v.T))):  # fmt: skip
        om, ze, _ = modal_draws(s, th, slopes)
        out[kind] = (om[0] / (2 * math.pi), ze[0])
    return out


def run_one(case: str, i: int) -> dict:
    """Simulate record ``i`` of ``case``, fit it with hosid and analyse it with SSI and FDD."""
    s, rec, q, v = simulate_case(case, i)
    truth = truth_modes(s, q, v)
    f_ssi, z_ssi = ssi_modes(q.T, 0.02, s.n)
    fit_system = System(("x1", "x2"), CASES[case][0])
    tree = hosid.fit(rec, fit_system, seed=i, progress=False)
    summ = summarize(tree, warn=False)
    row = {"case": case, "record": i, "converged": int(summ["converged"]), **fdd_row(q)}
    for j in range(s.n):
        row.update({
            f"f{j}_truth_small": truth["small"][0][j], f"z{j}_truth_small": truth["small"][1][j],
            f"f{j}_truth": truth["response"][0][j], f"z{j}_truth": truth["response"][1][j],
            f"f{j}_ssi": f_ssi[j], f"z{j}_ssi": z_ssi[j],
        })  # fmt: skip
        for kind, key_ in (("hosid", "modes"), ("hosid_small", "modes_small_amplitude")):
            m = summ[key_][j]
            for x, name in (("f", "frequency_hz"), ("z", "damping_ratio")):
                row[f"{x}{j}_{kind}"] = m[name]["mean"]
                row[f"{x}{j}_{kind}_sd"] = m[name]["sd"]
                row[f"{x}{j}_{kind}_q05"] = m[name]["q05"]
                row[f"{x}{j}_{kind}_q95"] = m[name]["q95"]
    for p in LAWS:
        if p in summ["parameters"]:
            row[p] = summ["parameters"][p]["mean"]
            row[f"{p}_sd"] = summ["parameters"][p]["sd"]
    return row


def _write(rows: list[dict], path: Path) -> None:
    fields = list(dict.fromkeys(k for r in rows for k in r))
    with path.open("w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=fields, lineterminator="\n", restval="")
        w.writeheader()
        w.writerows(rows)


def _read(path: Path) -> list[dict]:
    if not path.is_file():
        return []
    with path.open() as fh:
        return list(csv.DictReader(fh))


def summarize_rows(rows: list[dict], out: Path) -> Path:
    """``oma_comparison.md``: per case and mode, the truth's modes, SSI's and hosid's."""

    def col(rs, k):
        return np.array([float(r[k]) for r in rs if r.get(k) not in (None, "")])

    def ms(x, digits=4):
        return f"{x.mean():.{digits}g} ± {x.std(ddof=1):.2g}" if x.size > 1 else f"{x.mean():.4g}"

    lines = [
        "# Operational modal analysis beside hosid (issue 33)", "",
        "`python analyses/oma_comparison.py`: independent simulator, 2000 s at dt = 0.02, "
        "displacement channels. SSI: koma-python's SSI-cov (model order 4, "
        f"{BLOCK_ROWS} block rows), mean ± sd over the records; FDD: frequency domain "
        f"decomposition, the damping by EFDD (Welch segments of {FDD_SEGMENT} samples, "
        "`fdd_modes`). hosid: the default fit of "
        "the system file; `modes` (linearised at the record's response level), mean of the "
        "posterior means ± the mean posterior sd. Truth: the true parameters linearised with "
        "each record's own state (response) or their linear terms (small amplitude).", "",
        "| case | records | mode | truth, small amplitude: f (Hz), zeta | truth at the "
        "response level | SSI f | FDD f | hosid f | SSI zeta | EFDD zeta | hosid zeta |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]  # fmt: skip
    for case in CASES:
        rs = [r for r in rows if r["case"] == case]
        if not rs:
            continue
        for j in range(2):
            sd_f, sd_z = col(rs, f"f{j}_hosid_sd").mean(), col(rs, f"z{j}_hosid_sd").mean()
            lines.append(
                f"| {case} | {len(rs)} | {j + 1} | {col(rs, f'f{j}_truth_small').mean():.4g}, "
                f"{col(rs, f'z{j}_truth_small').mean():.3g} | "
                f"{col(rs, f'f{j}_truth').mean():.4g}, {col(rs, f'z{j}_truth').mean():.3g} | "
                f"{ms(col(rs, f'f{j}_ssi'))} | {ms(col(rs, f'f{j}_fdd'))} | "
                f"{col(rs, f'f{j}_hosid').mean():.4g} ± {sd_f:.2g} | "
                f"{ms(col(rs, f'z{j}_ssi'), 3)} | {ms(col(rs, f'z{j}_fdd'), 3)} | "
                f"{col(rs, f'z{j}_hosid').mean():.3g} ± {sd_z:.2g} |"
            )
    lines += ["", "The element laws hosid estimates at the three levels (mean of the posterior "
              "means ± the mean posterior sd; truth in the header):", "",
              "| case | " + " | ".join(f"{p} ({NONLINEAR_VALUES[p]:g})" for p in LAWS) + " |",
              "|---|" + "---|" * len(LAWS)]  # fmt: skip
    for case in CASES:
        rs = [r for r in rows if r["case"] == case]
        if not rs or not rs[0].get("n2[x1-x2]"):
            continue
        cells = [f"{col(rs, p).mean():.4g} ± {col(rs, p + '_sd').mean():.2g}" for p in LAWS]
        lines.append(f"| {case} | " + " | ".join(cells) + " |")
    lines += _coverage(rows)
    conv = sum(int(r["converged"]) for r in rows)
    lines += ["", f"hosid's fits converged (R-hat < 1.01, ESS >= 400): {conv}/{len(rows)}."]
    path = out / "oma_comparison.md"
    path.write_text("\n".join(lines) + "\n")
    return path


def _coverage(rows: list[dict]) -> list[str]:
    """Lines: in how many records hosid's 90 % interval of each mode's frequency and
    damping ratio holds the truth at the response level (rows that carry the intervals).
    """
    out = []
    for case in CASES:
        rs = [r for r in rows if r["case"] == case and r.get("f0_hosid_q05") not in (None, "")]
        if not rs:
            continue
        cells = []
        for j in range(2):
            for x, what in (("f", "frequency"), ("z", "damping ratio")):
                held = sum(float(r[f"{x}{j}_hosid_q05"]) <= float(r[f"{x}{j}_truth"])
                           <= float(r[f"{x}{j}_hosid_q95"]) for r in rs)  # fmt: skip
                cells.append(f"mode {j + 1} {what} {held}/{len(rs)}")
        out.append(f"- {case}: hosid's 90 % intervals hold the truth: " + ", ".join(cells) + ".")
    return ["", "Coverage of the modes (truth at the response level):", "", *out] if out else []


def main(argv: Sequence[str] | None = None) -> Path:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--records", type=int, default=4)
    ap.add_argument("--cases", nargs="+", default=list(CASES), choices=list(CASES))
    ap.add_argument("--summary", action="store_true", help="the tables from the fits made")
    ap.add_argument("--truth", action="store_true",
                    help="recompute the truth's columns of the rows made (records simulated "
                    "again), then the tables")  # fmt: skip
    ap.add_argument("--out", type=Path, default=RESULTS)
    a = ap.parse_args(argv)
    a.out.mkdir(parents=True, exist_ok=True)
    path = a.out / "oma_comparison.csv"
    rows = _read(path)
    if a.truth:
        for r in rows:
            s, _, q, v = simulate_case(r["case"], int(r["record"]))
            t = truth_modes(s, q, v)
            for j in range(s.n):
                r.update({f"f{j}_truth_small": str(t["small"][0][j]), f"f{j}_truth": str(
                    t["response"][0][j]), f"z{j}_truth_small": str(t["small"][1][j]),
                    f"z{j}_truth": str(t["response"][1][j])})  # fmt: skip
        _write(rows, path)
    elif not a.summary:
        old = [r for r in rows if r.get("f0_fdd") in (None, "")]
        for r in old:  # rows made before FDD was added: their records simulated again
            q = simulate_case(r["case"], int(r["record"]))[2]
            r.update({k: str(v) for k, v in fdd_row(q).items()})
        if old:
            _write(rows, path)
        done = {(r["case"], int(r["record"])) for r in rows}
        for case in a.cases:
            for i in range(a.records):
                if (case, i) in done:
                    continue
                row = run_one(case, i)
                rows.append({k: str(v) for k, v in row.items()})
                _write(rows, path)
                print(f"{case}-{i}: SSI f {row['f0_ssi']:.4g} {row['f1_ssi']:.4g}, hosid "
                      f"{row['f0_hosid']:.4g} {row['f1_hosid']:.4g}", flush=True)  # fmt: skip
    md = summarize_rows(rows, a.out)
    print(md.read_text())
    return md


if __name__ == "__main__":
    main()
