"""The content of a diagnosis: its ``report.json`` dictionary and its one-paragraph verdict.

:func:`diagnosis_report` is :meth:`hosid.check.diagnosis_result.Diagnosis.report`;
:func:`decision_text` the sentence :func:`hosid.check.diagnose.diagnose` stores as
``decision``.  The files are written by :mod:`hosid.output.diagnosis`.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

import numpy as np

from ..verdicts import Check, overall
from .evidence import COORDINATES

if TYPE_CHECKING:  # pragma: no cover
    from .diagnosis_result import Diagnosis, Step
    from .selection import Round

__all__ = ["decision_text", "diagnosis_report"]


def _evidence(rnd: Round, effect: str) -> str:
    ev = rnd.evidence[effect]
    return (
        f"z = {ev.z:.1f}, D = {ev.D:.1f} (p = {ev.p_value:.2g}, calibrated "
        f"{rnd.adjusted(effect):.3f})"
    )


def _step_text(step: Step) -> str:
    post = step.posterior()
    return (
        f"{step.effect} ({post['param']} = {post['mean']:.4g} +- {post['sd']:.2g}; "
        f"{_evidence(step.round, step.effect)}; gap {step.gap_before:.2f} -> "
        f"{step.gap_after:.2f})"
    )


def decision_text(diag: Diagnosis) -> str:
    """The verdict: what was named in which order, and why the search stopped."""
    s = diag.settings
    parts = []
    if diag.steps:
        parts.append("named " + ", then ".join(_step_text(st) for st in diag.steps))
    last = diag.rounds[-1] if len(diag.rounds) > len(diag.steps) else None
    if last is not None:
        best = last.best()
        what = "a further" if diag.steps else "any"
        text = f"no candidate supports {what} effect at a false-alarm rate of {s['alpha']:g}"
        if best is not None:
            text += f" (best: {best}, {_evidence(last, best)})"
        if last.vetoed:
            text += "; vetoed by the gap: " + "; ".join(
                f"{c}: {why}" for c, why in last.vetoed.items()
            )
        parts.append(text)
    elif len(diag.steps) == len(s["candidates"]):
        parts.append("every candidate was named")
    elif diag.steps:
        parts.append(f"stopped after {len(diag.steps)} effect(s) (max_effects)")
    base = diag.base
    if not diag.steps and base.diverged:
        parts.append("the base model's posterior-predictive simulations diverge")
    elif not diag.steps and base.z >= s["threshold"]:
        parts.append(
            f"but the base gap {base.total:.2f} is {base.z:.1f} robust sd above its null: "
            "the record holds something the candidates do not describe"
        )
    return "; ".join(parts)


def _changes(before, after) -> dict[str, dict[str, float]]:
    """What a named step changes: every parameter both models share, its estimate before
    and after, and the shift in the earlier posterior's sd.
    """
    out = {}
    for i, p in enumerate(before.model.param_names):
        if p not in after.theta_hat:
            continue
        v0, v1 = float(before.theta_hat[p]), float(after.theta_hat[p])
        sd = float(np.std(before.sample[:, i], ddof=1)) if before.sample.shape[0] > 1 else 0.0
        out[p] = {"before": v0, "after": v1, "shift_sd": (v1 - v0) / sd if sd > 0 else math.nan}
    return out


def changes_text(changes: dict[str, dict[str, float]], limit: float = 1.0) -> str:
    """The parameters a step moves by more than ``limit`` earlier sd, in one line."""
    moved = [
        f"{p} {c['before']:.4g} -> {c['after']:.4g} ({c['shift_sd']:+.1f} sd)"
        for p, c in changes.items()
        if abs(c["shift_sd"]) > limit
    ]
    return ", ".join(moved) if moved else f"no parameter moves by more than {limit:g} sd"


def _step_row(step: Step, before) -> dict[str, Any]:
    ev = step.round.evidence[step.effect]
    g0, g1 = step.gap_before, step.gap_after
    return {
        "effect": step.effect,
        "param": COORDINATES[step.effect].param,
        "model": list(step.check.model.names),
        "evidence": {**ev.as_dict(), "p_adjusted": step.round.adjusted(step.effect)},
        "posterior": step.posterior(),
        "method": step.check.method,
        "gap_before": g0,
        "gap_after": g1,
        "shrink": g1 / g0 if math.isfinite(g0) and g0 > 0 else math.nan,
        "z_after": step.check.z,
        "hansen": step.check.hansen,
        "vetoed": dict(step.vetoed),
        "changes": _changes(before, step.check),
    }


def _candidate_rows(diag: Diagnosis) -> list[dict[str, Any]]:
    """The first round's candidates: the three numbers, the estimate, the screened gap."""
    rows = []
    first = diag.rounds[0] if diag.rounds else None
    g0 = diag.base.total
    for row in first.as_dict()["candidates"] if first else []:
        chk = diag.candidates.get(row["effect"])
        if chk is not None:
            row["gap"] = chk.total
            row["gap_z"] = chk.z
            row["shrink"] = chk.total / g0 if math.isfinite(g0) and g0 > 0 else math.nan
            row["gap_measures"] = chk.gap["measures"]
        rows.append(row)
    listed = {r["effect"] for r in rows}
    rows += [{"effect": c, "error": why} for c, why in diag.failed.items() if c not in listed]
    return rows


def predictive_check(diag: Diagnosis) -> Check:
    """Whether the final model describes the record: its posterior-predictive gap's robust
    z against the null (``fail`` when its simulations diverge, ``warn`` at or above the
    threshold).
    """
    final, limit = diag.final, diag.settings["threshold"]
    model = " + ".join(final.model.names)
    if final.diverged:
        return Check(
            "predictive", "fail", None,
            f"the posterior-predictive simulations of {model} diverge",
        )  # fmt: skip
    if final.z >= limit:
        return Check(
            "predictive", "warn", final.z,
            f"the gap {final.total:.2f} of {model} is {final.z:.1f} robust sd above its null "
            f"(>= {limit:g}): the record holds something the candidates do not describe",
        )  # fmt: skip
    return Check(
        "predictive", "pass", final.z,
        f"{model} describes the record: gap {final.total:.2f}, {final.z:.1f} robust sd "
        f"from its null (< {limit:g})",
    )  # fmt: skip


def diagnosis_report(diag: Diagnosis) -> dict[str, Any]:
    """The ``report.json`` content (infinite gaps stay ``inf``; see ``jsonable``)."""
    checks = diag.checks()
    return {
        "checks": [c.as_dict() for c in checks],
        "verdict": overall(checks),
        "named_effect": diag.named_effect,
        "named_effects": diag.named_effects,
        "decision": diag.decision,
        "base": list(diag.base.model.names),
        "final_model": list(diag.final.model.names),
        "base_diverged": diag.base.diverged,
        "gap_before": diag.gap_before,
        "gap_after": diag.gap_after,
        "z_before": diag.base.z,
        "z_after": diag.final.z,
        "p_before": diag.base.p_value,
        "p_after": diag.final.p_value,
        "hansen_before": diag.base.hansen,
        "hansen_after": diag.final.hansen,
        "gaps": diag.gaps,
        "steps": [
            _step_row(st, diag.steps[i - 1].check if i else diag.base)
            for i, st in enumerate(diag.steps)
        ],
        "rounds": [r.as_dict() for r in diag.rounds],
        "candidates": _candidate_rows(diag),
        "base_fit": diag.base.summary(),
        "final_fit": diag.final.summary(),
        "settings": diag.settings,
    }
