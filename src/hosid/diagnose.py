r"""The model-discrepancy workflow: find the gap, name the missing effect, close it.

:func:`diagnose` fits a base model (:func:`hosid.modelfit.fit_model`), draws
posterior-predictive replicate records from it, and measures the record's gap
:math:`G_0` from them (:func:`hosid.discrepancy.gaps`: a root mean square of
replicate-standardized distances, about 1 for a record the model explains).  It then
adds each candidate effect of :data:`hosid.terms.CANDIDATES` not yet in the model,
refits, and measures the new gap :math:`G_c` the same way.

Decision rule (both thresholds are arguments):

1. The base gap must be significant.  The leave-one-out gaps of the replicates
   (each scored against the other :math:`R - 1`) sample the null distribution of
   :math:`G`; its robust standardization

   .. math:: z_G = \frac{G_0 - \operatorname{med} G^{null}}
                        {1.4826\,\operatorname{MAD} G^{null}}

   must reach ``threshold`` (default 3).  Otherwise no effect is named: the model
   already explains the record.  (The rank p-value
   :math:`(1 + \#\{G^{null} \ge G_0\})/(R + 1)` is reported too, but with 10-20
   replicates a single heavy-tailed leave-one-out gap, scored against few
   replicates, can hide a gap of 4 or 5: measured on the test records.)
2. The best candidate :math:`c^* = \arg\min_c G_c` is named if its addition shrinks
   the gap by the factor ``shrink``: :math:`G_{c^*} \le \text{shrink}\cdot G_0`.
   Otherwise no candidate explains the gap.

Every model's replicates use the same random streams (common random numbers), so
that candidate gaps differ by their models and not by the noise of the replicates.
The replicates are simulated at posterior draws, not at the point estimate, so the
gap carries the parameters' uncertainty.  A model whose posterior draws make more
than ``R/2`` simulations diverge (the response escapes, e.g. a fitted damping law
that turns negative at high speed) cannot produce a stationary record like the
observed one: its gap is infinite (``null`` in ``report.json``).

:func:`write_report` writes ``report.json`` (``named_effect``, ``gap_before``,
``gap_after``, ``candidates``, ``base``, ``final_model`` and more) and
``report.html`` with the before/after plots of the measures that moved.
"""

from __future__ import annotations

import base64
import html
import io
import json
import math
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from .discrepancy import MeasureSpec, gaps, measures
from .errors import HosidInputError
from .modelfit import ModelFit, fit_model
from .records import Record
from .report import _write
from .results import _jsonable
from .terms import CANDIDATES, ColouredExcitation, Model, get_term

__all__ = [
    "Diagnosis",
    "ModelCheck",
    "check_model",
    "diagnose",
    "spectral_costs",
    "write_report",
]


@dataclass
class ModelCheck:
    """One model fitted to the record and its posterior-predictive gap."""

    fit: ModelFit
    gap: dict
    record_measures: dict[str, np.ndarray]
    replicate_measures: list[dict[str, np.ndarray]]
    seconds: float
    failed_replicates: int = 0
    spectral_costs: dict[str, float] = field(default_factory=dict)

    @property
    def total(self) -> float:
        """The total gap :math:`G` (infinite when the model's simulations diverge)."""
        return float(self.gap["total"])

    @property
    def diverged(self) -> bool:
        """Whether more posterior draws escaped (diverging simulations) than half the
        number of replicates: the model cannot reproduce a stationary record.
        """
        return not math.isfinite(self.total)

    @property
    def p_value(self) -> float:
        """The posterior-predictive rank p-value of :math:`G`."""
        return float(self.gap["p_value"])

    @property
    def z(self) -> float:
        r"""Robust standardization of :math:`G` by the leave-one-out null gaps,
        :math:`(G - \operatorname{med} G^{null})/(1.4826\,\operatorname{MAD})`.
        """
        if not math.isfinite(self.total):
            return math.inf
        null = np.asarray(self.gap["null"], dtype=float)
        med = float(np.median(null))
        mad = 1.4826 * float(np.median(np.abs(null - med)))
        return (self.total - med) / max(mad, 1e-12)


def check_model(
    record: Record,
    model: Model | str,
    *,
    rng: np.random.Generator,
    replicate_seeds: Sequence[np.random.SeedSequence],
    spec: MeasureSpec | None = None,
    **fit_options: Any,
) -> ModelCheck:
    """Fit ``model`` and measure the record's gap from its posterior-predictive replicates.

    Parameters
    ----------
    record : Record
    model : Model or str
    rng : numpy.random.Generator
        For the fit and the choice of posterior draws.
    replicate_seeds : sequence of SeedSequence
        One per replicate; pass the same seeds for every model (common random
        numbers).
    spec : MeasureSpec, optional
        The measures' layout; default from the record.
    **fit_options
        Passed to :func:`hosid.modelfit.fit_model`.
    """
    t0 = time.perf_counter()
    model = Model.from_spec(model) if isinstance(model, str) else model
    spec = MeasureSpec.from_record(record) if spec is None else spec
    fit = fit_model(record, model, rng=rng, **fit_options)
    drift = model.simulator_params(fit.estimate)
    obs = measures(record, spec=spec, drift=drift)
    order = rng.permutation(fit.draws.shape[0])
    reps: list[dict[str, np.ndarray]] = []
    failed = 0
    k = 0
    R = len(replicate_seeds)
    for seed in replicate_seeds:
        sim = None
        while sim is None and failed <= R // 2 and k < order.size:
            theta = fit.draws[order[k]]
            k += 1
            try:
                sim = model.simulate(
                    theta, duration=record.duration, dt=record.dt, rng=np.random.default_rng(seed)
                )
            except HosidInputError:  # diverged: the draw lets the response escape
                sim = None
            if sim is not None and not np.max(np.abs(sim.x)) < 1e6:
                sim = None
            if sim is None:
                failed += 1
        if sim is None:
            break
        if sim.n != record.n:
            sim = Record(x=sim.x[: record.n], dt=sim.dt, name=sim.name)
        reps.append(measures(sim, spec=spec, drift=drift))
    if len(reps) == R:
        gap = gaps(obs, reps)
    else:  # more than half as many draws diverged as there are replicates
        gap = {
            "total": math.inf,
            "measures": dict.fromkeys(obs, math.inf),
            "z": {m: np.full(np.shape(v), np.inf) for m, v in obs.items()},
            "worst": "divergence",
            "null": np.array([np.nan]),
            "p_value": 0.0,
            "n_replicates": len(reps),
        }
    spectral = spectral_costs(
        record,
        model,
        fit.estimate,
        omega_n=spec.omega_n,
        block_seconds=fit_options.get("block_seconds", 20.48),
    )
    return ModelCheck(
        fit=fit,
        gap=gap,
        record_measures=obs,
        replicate_measures=reps,
        seconds=time.perf_counter() - t0,
        failed_replicates=failed,
        spectral_costs=spectral,
    )


def spectral_costs(
    record: Record,
    model: Model,
    estimate: dict[str, float],
    *,
    omega_n: float,
    block_seconds: float = 20.48,
) -> dict[str, float]:
    r"""The well-scaled, centred costs of the force inferred with ``estimate``.

    :math:`J_2^W`, :math:`J_3^W`, :math:`J_4^W` (:mod:`hosid.polyspectra`) and their
    sum, the eq (15) combination, on bins :math:`2 \le k`,
    :math:`\omega_k \le 1.6\,\omega_n` (bin 1 is left out so that a mean force does not
    enter).  Each is about 0 for a white Gaussian force; a missing asymmetric term
    raises :math:`J_3^W`, a missing symmetric nonlinearity :math:`J_4^W`.
    """
    from . import polyspectra as ps

    F = model.features(record)
    T = block_seconds
    fs = ps.feature_spectra(
        F, record.dt, block_seconds=T, omega_max=1.6 * omega_n, omega_min=1.5 * 2 * np.pi / T
    )
    lam = np.array([1.0] + [estimate[p] for p in model.drift_params])
    wc = estimate.get("wc")
    shape = None if wc is None else (lambda w: ColouredExcitation.shape(w, wc))
    S0 = estimate["S0"]
    out = {
        "J2W": float(ps.j2w(fs, lam, S0, shape)),
        "J3W": float(ps.j3w(fs, lam, S0, shape)),
        "J4W": float(ps.j4w(fs, lam, S0, shape)),
    }
    out["eq15"] = out["J2W"] + out["J3W"] + out["J4W"]
    return out


@dataclass
class Diagnosis:
    """The result of :func:`diagnose`."""

    base: ModelCheck
    candidates: dict[str, ModelCheck]
    named_effect: str | None
    decision: str
    settings: dict[str, Any] = field(default_factory=dict)
    failed: dict[str, str] = field(default_factory=dict)

    @property
    def final(self) -> ModelCheck:
        """The check of the final model (the base if nothing was named)."""
        return self.candidates[self.named_effect] if self.named_effect else self.base

    @property
    def gap_before(self) -> float:
        """The base model's total gap."""
        return self.base.total

    @property
    def gap_after(self) -> float:
        """The final model's total gap."""
        return self.final.total

    def report(self) -> dict[str, Any]:
        """The ``report.json`` content."""
        cands = []
        for name, chk in sorted(self.candidates.items(), key=lambda kv: kv[1].total):
            cands.append(
                {
                    "effect": name,
                    "gap_after": chk.total,
                    "shrink": chk.total / self.base.total,
                    "p_value": chk.p_value,
                    "z": chk.z,
                    "explains": bool(chk.z < self.settings["threshold"]),
                    "measures": chk.gap["measures"],
                    "estimate": chk.fit.estimate,
                    "interval90": chk.fit.interval(0.9),
                    "spectral_costs": chk.spectral_costs,
                    "seconds": chk.seconds,
                    **(
                        {"error": "its posterior-predictive simulations diverge"}
                        if chk.diverged
                        else {}
                    ),
                }
            )
        for name, why in self.failed.items():
            cands.append({"effect": name, "gap_after": None, "error": why})
        return {
            "named_effect": self.named_effect,
            "base_diverged": self.base.diverged,
            "gap_before": self.base.total,
            "gap_after": self.gap_after,
            "p_before": self.base.p_value,
            "p_after": self.final.p_value,
            "z_before": self.base.z,
            "z_after": self.final.z,
            "decision": self.decision,
            "base": list(self.base.fit.model.names),
            "final_model": list(self.final.fit.model.names),
            "candidates": cands,
            "base_fit": {
                "estimate": self.base.fit.estimate,
                "interval90": self.base.fit.interval(0.9),
                "measures": self.base.gap["measures"],
                "null_gaps": self.base.gap["null"].tolist(),
                "spectral_costs": self.base.spectral_costs,
            },
            "final_fit": {
                "estimate": self.final.fit.estimate,
                "interval90": self.final.fit.interval(0.9),
                "measures": self.final.gap["measures"],
                "null_gaps": self.final.gap["null"].tolist(),
            },
            "settings": self.settings,
        }


def diagnose(
    record: Record,
    base: Model | str | Sequence[str] = "paper",
    *,
    rng: np.random.Generator,
    candidates: Sequence[str] | None = None,
    replicates: int = 20,
    threshold: float = 3.0,
    shrink: float = 0.75,
    progress: bool = False,
    **fit_options: Any,
) -> Diagnosis:
    r"""Fit ``base``, measure its gap, try every candidate effect, name the one that
    closes it (see the module docstring for the rule).

    Parameters
    ----------
    record : Record
    base : Model, str or sequence of str
        ``"linear"`` (a1, a2), ``"paper"`` (a1, n1, a2, n2) or term names.
    rng : numpy.random.Generator
        The only source of randomness.
    candidates : sequence of str, optional
        Effects to try; default every one of :data:`hosid.terms.CANDIDATES` not in
        ``base``.
    replicates : int
        Posterior-predictive replicates per model (at least 8; the null of the gap
        is estimated from their leave-one-out gaps).
    threshold : float
        The base gap is significant when its robust z (module docstring) reaches it.
    shrink : float
        The named effect must cut the gap to at most ``shrink`` times the base gap.
    progress : bool
        Show a progress bar over the models.
    **fit_options
        Passed to :func:`hosid.modelfit.fit_model`.

    Returns
    -------
    Diagnosis

    Raises
    ------
    HosidInputError
        On unknown effect names, bad thresholds, or too few replicates.
    """
    if not isinstance(rng, np.random.Generator):
        raise TypeError("rng must be a numpy.random.Generator")
    if isinstance(base, Model):
        base_model = base
    else:
        base_model = Model.from_spec(base)
    if candidates is None:
        cands = list(base_model.candidates)
    else:
        cands = [get_term(c).name for c in candidates]
        bad = [c for c in cands if c not in CANDIDATES]
        if bad:
            raise HosidInputError(
                f"not candidate effects: {', '.join(bad)}; candidates: {', '.join(CANDIDATES)}"
            )
        already = [c for c in cands if c in base_model.names]
        if already:
            raise HosidInputError(f"already in the base model: {', '.join(already)}")
    if int(replicates) < 8:
        raise HosidInputError(f"need at least 8 replicates, got {replicates}")
    if not (math.isfinite(threshold) and threshold > 0):
        raise HosidInputError(f"threshold must be positive, got {threshold}")
    if not 0 < shrink <= 1:
        raise HosidInputError(f"shrink must be in (0, 1], got {shrink}")
    spec = MeasureSpec.from_record(record)
    seeds = np.random.SeedSequence(int(rng.integers(2**63 - 1))).spawn(int(replicates))

    from tqdm.auto import tqdm

    models = [("base", base_model)] + [(c, base_model.with_term(c)) for c in cands]
    checks: dict[str, ModelCheck] = {}
    bar = tqdm(models, desc="diagnose", disable=not progress, leave=False)
    failed: dict[str, str] = {}
    for label, model in bar:
        bar.set_postfix_str(label)
        try:
            checks[label] = check_model(
                record, model, rng=rng, replicate_seeds=seeds, spec=spec, **fit_options
            )
        except HosidInputError as exc:
            if label == "base":
                raise
            failed[label] = str(exc)  # e.g. its simulations escape the potential well
    base_chk = checks.pop("base")
    named = None
    if base_chk.diverged:
        decision_base = "the base model's posterior-predictive simulations diverge; "
    else:
        decision_base = ""
    if base_chk.z < threshold:
        decision = (
            f"the base model explains the record: gap {base_chk.total:.2f} is "
            f"{base_chk.z:.1f} < {threshold:g} robust sd above its null median; no effect named"
        )
    elif not checks:
        decision = "the base gap is significant but there are no candidates to try"
    else:
        best = min(checks, key=lambda c: checks[c].total)
        g = checks[best].total
        if g <= shrink * base_chk.total:
            named = best
            decision = decision_base + (
                f"adding {best} shrinks the gap from {base_chk.total:.2f} to {g:.2f} "
                f"(x{g / base_chk.total:.2f} <= {shrink})"
            )
        else:
            decision = decision_base + (
                f"the base gap {base_chk.total:.2f} is significant (z = "
                f"{base_chk.z:.1f}) but no candidate explains it: the best, {best}, "
                f"leaves {g:.2f} (x{g / base_chk.total:.2f} > {shrink})"
            )
    settings = {
        "replicates": int(replicates),
        "threshold": float(threshold),
        "shrink": float(shrink),
        "candidates": cands,
        "duration": record.duration,
        "dt": record.dt,
        "fit_options": {k: v for k, v in fit_options.items()},
    }
    return Diagnosis(
        base=base_chk,
        candidates=checks,
        named_effect=named,
        decision=decision,
        settings=settings,
        failed=failed,
    )


# --------------------------------------------------------------------- report
def _png(fig) -> bytes:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=100, bbox_inches="tight")
    import matplotlib.pyplot as plt

    plt.close(fig)
    return buf.getvalue()


def gap_plot(diag: Diagnosis):
    """Bar chart of the total gap of the base model and of every candidate."""
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    labels = ["base", *diag.candidates]
    values = np.array([diag.base.total] + [c.total for c in diag.candidates.values()])
    finite = values[np.isfinite(values)]
    cap = 1.2 * float(finite.max()) if finite.size else 1.0
    diverged = ~np.isfinite(values)
    values = np.where(diverged, cap, values)
    colors = ["0.4"] + [
        "tab:green" if c == diag.named_effect else "tab:blue" for c in diag.candidates
    ]
    fig, ax = plt.subplots(figsize=(7, 3.2))
    bars = ax.barh(labels[::-1], values[::-1], color=colors[::-1])
    for bar, div in zip(bars, diverged[::-1], strict=True):
        if div:
            bar.set_hatch("//")
            ax.text(cap, bar.get_y() + bar.get_height() / 2, " diverges", va="center", fontsize=8)
    null = np.asarray(diag.base.gap["null"], dtype=float)
    null = null[np.isfinite(null)]
    if null.size:
        ax.axvspan(
            float(np.min(null)),
            float(np.max(null)),
            color="0.85",
            zorder=0,
            label="base null range (leave-one-out)",
        )
    if math.isfinite(diag.base.total):
        ax.axvline(
            diag.settings["shrink"] * diag.base.total,
            color="tab:red",
            ls="--",
            label=f"shrink threshold x{diag.settings['shrink']}",
        )
    ax.set_xlabel("total gap G (replicate standard deviations)")
    if ax.get_legend_handles_labels()[0]:
        ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8)
    fig.tight_layout()
    return fig


def moved_measures(diag: Diagnosis, most: int = 4) -> list[str]:
    """The measures whose gap changed most from the base to the final model."""
    before = diag.base.gap["measures"]
    after = diag.final.gap["measures"]
    if diag.base.diverged:  # no finite "before": show where the final model is worst
        return sorted(after, key=lambda k: -after[k])[:most]
    return sorted(before, key=lambda k: -abs(before[k] - after[k]))[:most]


def measures_plot(diag: Diagnosis, names: Sequence[str]):
    r"""For each measure, the record's standardized distance :math:`z_j` from the
    replicates of the base model and of the final model, component by component.
    """
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    n = max(1, len(names))
    ncol = 2 if n > 1 else 1
    nrow = math.ceil(n / ncol)
    fig, axes = plt.subplots(nrow, ncol, figsize=(4.6 * ncol, 2.6 * nrow), squeeze=False)
    after_label = f"after: + {diag.named_effect}" if diag.named_effect else "after: base"
    for ax, name in zip(axes.ravel(), names, strict=False):
        zb = np.asarray(diag.base.gap["z"][name], dtype=float)
        zb = np.where(np.isfinite(zb), zb, np.nan)  # a diverged base has no z
        za = np.asarray(diag.final.gap["z"][name], dtype=float)
        za = np.where(np.isfinite(za), za, np.nan)
        idx = np.arange(zb.size)
        ax.bar(idx - 0.2, zb, width=0.4, color="0.5", label="before: base")
        ax.bar(idx + 0.2, za, width=0.4, color="tab:green", label=after_label)
        ax.axhspan(-2, 2, color="tab:blue", alpha=0.08, zorder=0)
        ax.axhline(0, color="k", lw=0.6)
        gb, ga = diag.base.gap["measures"][name], diag.final.gap["measures"][name]
        ax.set_title(f"{name}: G {gb:.2f} -> {ga:.2f}", fontsize=9)
        ax.set_xticks(idx)
        ax.set_xlabel("component", fontsize=8)
        ax.set_ylabel("z (replicate sd)", fontsize=8)
    for ax in axes.ravel()[n:]:
        ax.set_visible(False)
    axes[0, 0].legend(fontsize=7)
    fig.tight_layout()
    return fig


_CSS = (
    "body{font-family:sans-serif;max-width:980px;margin:2em auto;color:#222}"
    "table{border-collapse:collapse;margin:1em 0}td,th{border:1px solid #ccc;padding:3px 8px;"
    "text-align:right}th{background:#f0f0f0}.named{background:#e3f6e3}"
    ".banner{padding:.6em 1em;border-radius:4px;background:#eef;margin:1em 0}"
)


def _html(rep: dict[str, Any], images: dict[str, bytes]) -> str:
    e = html.escape
    rows = [
        "<tr><th>effect</th><th>gap after</th><th>x base</th><th>z</th><th>p</th>"
        "<th>worst measure</th><th>J2W</th><th>J3W</th><th>J4W</th></tr>"
    ]
    for c in rep["candidates"]:
        if c.get("gap_after") is None or "error" in c:
            rows.append(
                f"<tr><td>{e(c['effect'])}</td><td colspan=8>failed: {e(c['error'])}</td></tr>"
            )
            continue
        worst = max(c["measures"], key=c["measures"].get)
        cls = ' class="named"' if c["effect"] == rep["named_effect"] else ""
        rows.append(
            f"<tr{cls}><td>{e(c['effect'])}</td><td>{_f(c['gap_after'], 2)}</td>"
            f"<td>{_f(c['shrink'], 2)}</td><td>{_f(c['z'], 1)}</td><td>{_f(c['p_value'], 3)}</td>"
            f"<td>{e(worst)}</td>"
            + "".join(f"<td>{c['spectral_costs'][k]:.0f}</td>" for k in ("J2W", "J3W", "J4W"))
            + "</tr>"
        )
    est_rows = ["<tr><th>parameter</th><th>estimate</th><th>90 % interval</th></tr>"]
    for k, v in rep["final_fit"]["estimate"].items():
        lo, hi = rep["final_fit"]["interval90"][k]
        est_rows.append(f"<tr><td>{e(k)}</td><td>{v:.4g}</td><td>{lo:.4g} .. {hi:.4g}</td></tr>")
    meas = ["<tr><th>measure</th><th>before</th><th>after</th></tr>"]
    for k, v in rep["base_fit"]["measures"].items():
        meas.append(
            f"<tr><td>{e(k)}</td><td>{_f(v, 2)}</td>"
            f"<td>{_f(rep['final_fit']['measures'][k], 2)}</td></tr>"
        )
    named = rep["named_effect"] or "none"
    parts = [
        "<!DOCTYPE html>",
        '<html lang="en"><head><meta charset="utf-8">',
        f"<title>hosid diagnose: {e(named)}</title><style>{_CSS}</style></head><body>",
        "<h1>hosid diagnose</h1>",
        f'<div class="banner"><b>Named effect: {e(named)}</b>. {e(rep["decision"])}.</div>',
        f"<p>Base model: {e(' + '.join(rep['base']))}. Final model: "
        f"{e(' + '.join(rep['final_model']))}. Gap before {_f(rep['gap_before'], 2)} "
        f"(z = {_f(rep['z_before'], 1)}, p = {_f(rep['p_before'], 3)}), after "
        f"{_f(rep['gap_after'], 2)} (z = {_f(rep['z_after'], 1)}, "
        f"p = {_f(rep['p_after'], 3)}).</p>",
        "<h2>Candidates</h2><table>" + "".join(rows) + "</table>",
        "<p>J2W, J3W, J4W: the well-scaled centred second-, third- and fourth-order costs "
        "of the force inferred at each model's estimate (about 0 for a white Gaussian "
        f"force; base model: {_costs_text(rep['base_fit']['spectral_costs'])}).</p>",
        f'<figure><img src="data:image/png;base64,{_b64(images["gaps"])}" alt="gaps">'
        "<figcaption>Total gap of every model; the grey band is the range of the base "
        "model's leave-one-out null gaps.</figcaption></figure>",
        "<h2>Measures that moved</h2>",
        f'<figure><img src="data:image/png;base64,{_b64(images["measures"])}" alt="measures">'
        "<figcaption>Standardized distance z of the record from the posterior-predictive "
        "replicates, per component of the measures whose gap moved most, for the base model "
        "(grey) and the final model (green); the band is |z| &lt; 2.</figcaption></figure>",
        "<h2>Gap per measure</h2><table>" + "".join(meas) + "</table>",
        "<h2>Final model</h2><table>" + "".join(est_rows) + "</table>",
        "<h2>Settings</h2><pre>" + e(json.dumps(_jsonable(rep["settings"]), indent=1)) + "</pre>",
        "</body></html>",
        "",
    ]
    return "\n".join(parts)


def _f(value: float | None, digits: int) -> str:
    """A number for the report; ``None`` (an infinite gap in JSON) reads "diverged"."""
    if value is None:
        return "diverged"
    if isinstance(value, float) and not math.isfinite(value):
        return "diverged" if value > 0 else "-"
    return f"{value:.{digits}f}"


def _costs_text(costs: dict[str, float]) -> str:
    return ", ".join(f"{k} {v:.0f}" for k, v in costs.items())


def _b64(data: bytes) -> str:
    return base64.b64encode(data).decode("ascii")


def write_report(diag: Diagnosis, out_dir: str | Path) -> tuple[Path, Path]:
    """Write ``report.json`` and ``report.html`` into ``out_dir`` (created)."""
    out = Path(out_dir)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise HosidInputError(f"cannot create {out}: {exc.strerror or exc}") from None
    rep = _jsonable(diag.report())
    images = {
        "gaps": _png(gap_plot(diag)),
        "measures": _png(measures_plot(diag, moved_measures(diag))),
    }
    paths = (out / "report.json", out / "report.html")
    _write(paths[0], json.dumps(rep, indent=1))
    _write(paths[1], _html(rep, images))
    return paths
