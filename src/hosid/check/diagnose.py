r"""The model-discrepancy workflow: find the gap, name the missing effect, close it.

:func:`diagnose` fits a base model with :func:`hosid.inference.fit.fit` (emcee), draws
posterior-predictive replicate records from it (:meth:`hosid.model.Model.simulate` at
posterior draws), and measures the record's gap :math:`G_0` from them
(:func:`hosid.check.gaps.gaps`: a root mean square of replicate-standardized
distances, about 1 for a record the model explains).  It then adds each candidate
effect of :data:`hosid.model.CANDIDATES` not yet in the model and measures the new gap
:math:`G_c` the same way.  Candidates are *screened* without a chain: the replicates'
parameters are drawn from the Gaussian :math:`N(\hat\theta, \hat C)` of
:func:`hosid.inference.estimate.estimate`, restricted to the priors and importance
weighted to the calibrated quasi-posterior that :func:`~hosid.inference.fit.fit`
samples (:func:`hosid.check.posterior.screen_sample`).  The named model is then fitted
with emcee and its gap measured again from its posterior: that is the gap after.

Decision rule (both thresholds are arguments):

1. The base gap must be significant.  The leave-one-out gaps of the replicates
   (each scored against the other :math:`R - 1`) sample the null distribution of
   :math:`G`; its robust standardization

   .. math:: z_G = \frac{G_0 - \operatorname{med} G^{null}}
                        {1.4826\,\operatorname{MAD} G^{null}}

   must reach ``threshold`` (default 3).  Otherwise no effect is named.  (The rank
   p-value :math:`(1 + \#\{G^{null} \ge G_0\})/(R + 1)` is reported too; with 10-20
   replicates a single heavy-tailed leave-one-out gap can hide a gap of 4 or 5.)
2. The best candidate :math:`c^* = \arg\min_c G_c` is named if its addition shrinks
   the gap by the factor ``shrink``: :math:`G_{c^*} \le \text{shrink}\cdot G_0`.

Every model's replicates use the same random streams (one
:class:`numpy.random.SeedSequence` spawned once: common random numbers), so that
candidate gaps differ by their models and not by the noise of the replicates.  A draw
whose simulation escapes is replaced by the next one (same stream); a model with more
than ``R/2`` escaping draws cannot produce a stationary record like the observed one
and gets an infinite gap.  Each model's Hansen test (:math:`J`, its degrees of freedom
and p-value, from :func:`~hosid.inference.estimate.estimate`) is reported with it.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import xarray as xr

from ..errors import HosidInputError
from ..model.model import Model, get_term
from ..model.terms import CANDIDATES
from ..record import Record
from .measures import MeasureSpec
from .model_check import ModelCheck, check_model

__all__ = ["Diagnosis", "ModelCheck", "check_model", "diagnose"]

#: Fewest replicates :func:`diagnose` accepts (the null needs a robust spread).
MIN_REPLICATES = 8


@dataclass
class Diagnosis:
    """The result of :func:`diagnose`.

    ``base`` and ``final`` are fitted with emcee (``final`` is ``base`` when no effect
    is named); ``candidates`` holds the screened checks of every candidate that ran,
    ``failed`` the candidates that could not be estimated and why.
    """

    base: ModelCheck
    candidates: dict[str, ModelCheck]
    final: ModelCheck
    named_effect: str | None
    decision: str
    settings: dict[str, Any] = field(default_factory=dict)
    failed: dict[str, str] = field(default_factory=dict)

    @property
    def final_tree(self) -> xr.DataTree:
        """The final model's emcee fit (for ``posterior.nc``).

        Raises
        ------
        ValueError
            If the final check was not fitted with emcee (only a hand-built diagnosis).
        """
        if self.final.tree is None:
            raise ValueError("the final model was not fitted with emcee")
        return self.final.tree

    @property
    def gap_before(self) -> float:
        """The base model's total gap."""
        return self.base.total

    @property
    def gap_after(self) -> float:
        """The final model's total gap (measured on its emcee posterior)."""
        return self.final.total

    def report(self) -> dict[str, Any]:
        """The ``report.json`` content (infinite gaps stay ``inf``; see ``jsonable``)."""
        g0 = self.base.total
        cands = []
        for name, chk in sorted(self.candidates.items(), key=lambda kv: kv[1].total):
            row = {
                "effect": name,
                "gap_after": chk.total,
                "shrink": chk.total / g0 if math.isfinite(g0) else math.nan,
                "p_value": chk.p_value,
                "z": chk.z,
                "explains": bool(chk.z < self.settings["threshold"]),
                "measures": chk.gap["measures"],
                "estimate": chk.theta_hat,
                "interval90": chk.interval(0.9),
                "hansen": chk.hansen,
                "method": chk.method,
                "ess": chk.info.get("ess"),
                "seconds": chk.seconds,
            }
            if chk.diverged:
                row["error"] = "its posterior-predictive simulations diverge"
            cands.append(row)
        for name, why in self.failed.items():
            cands.append({"effect": name, "gap_after": None, "error": why})
        screened = self.candidates.get(self.named_effect) if self.named_effect else None
        return {
            "named_effect": self.named_effect,
            "base_diverged": self.base.diverged,
            "gap_before": g0,
            "gap_after": self.gap_after,
            "gap_after_screen": screened.total if screened else None,
            "p_before": self.base.p_value,
            "p_after": self.final.p_value,
            "z_before": self.base.z,
            "z_after": self.final.z,
            "hansen_before": self.base.hansen,
            "hansen_after": self.final.hansen,
            "decision": self.decision,
            "base": list(self.base.model.names),
            "final_model": list(self.final.model.names),
            "candidates": cands,
            "base_fit": self.base.summary(),
            "final_fit": self.final.summary(),
            "settings": self.settings,
        }


def _candidates(base: Model, candidates: Sequence[str] | None) -> list[str]:
    if candidates is None:
        return list(base.candidates)
    cands = [get_term(c).name for c in candidates]
    bad = [c for c in cands if c not in CANDIDATES]
    if bad:
        raise HosidInputError(
            f"not candidate effects: {', '.join(bad)}; candidates: {', '.join(CANDIDATES)}"
        )
    already = [c for c in cands if c in base.names]
    if already:
        raise HosidInputError(f"already in the base model: {', '.join(already)}")
    return list(dict.fromkeys(cands))


def _decide(base, checks, threshold, shrink) -> tuple[str | None, str]:
    """The decision rule of the module docstring: ``(named effect, reason)``."""
    prefix = "the base model's posterior-predictive simulations diverge; " if base.diverged else ""
    if base.z < threshold:
        return None, (
            f"the base model explains the record: gap {base.total:.2f} is "
            f"{base.z:.1f} < {threshold:g} robust sd above its null median; no effect named"
        )
    if not checks:
        return None, prefix + "the base gap is significant but there are no candidates to try"
    best = min(checks, key=lambda c: checks[c].total)
    g, g0 = checks[best].total, base.total
    if g <= shrink * g0:
        return best, prefix + (
            f"adding {best} shrinks the gap from {g0:.2f} to {g:.2f} (x{g / g0:.2f} <= {shrink:g})"
        )
    return None, prefix + (
        f"the base gap {g0:.2f} is significant (z = {base.z:.1f}) but no candidate "
        f"explains it: the best, {best}, leaves {g:.2f} (x{g / g0:.2f} > {shrink:g})"
    )


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
) -> Diagnosis:
    r"""Fit ``base``, measure its gap, try every candidate effect, name the one that
    closes it and fit the named model (module docstring).

    Parameters
    ----------
    record : Record
        The observed record.
    base : Model, str or sequence of str
        ``"linear"`` (a1, a2), ``"paper"`` (a1, n1, a2, n2) or term names.
    rng : numpy.random.Generator
        The only source of randomness.
    candidates : sequence of str, optional
        Effects to try; default every one of :data:`hosid.model.CANDIDATES` not in
        ``base``.
    replicates : int
        Posterior-predictive replicates per model (at least 8).
    threshold : float
        The base gap is significant when its robust z reaches it.
    shrink : float
        The named effect must cut the gap to at most ``shrink`` times the base gap.
    progress : bool
        One progress bar over the workflow's steps.

    Returns
    -------
    Diagnosis

    Raises
    ------
    HosidInputError
        On unknown effect names, bad thresholds, too few replicates, or a base model
        that cannot be fitted to the record.
    """
    if not isinstance(rng, np.random.Generator):
        raise TypeError("rng must be a numpy.random.Generator")
    base_model = Model.from_spec(base)
    cands = _candidates(base_model, candidates)
    if int(replicates) != replicates or replicates < MIN_REPLICATES:
        raise HosidInputError(f"need at least {MIN_REPLICATES} replicates, got {replicates}")
    if not (math.isfinite(threshold) and threshold > 0):
        raise HosidInputError(f"threshold must be positive, got {threshold}")
    if not 0 < shrink <= 1:
        raise HosidInputError(f"shrink must be in (0, 1], got {shrink}")
    spec = MeasureSpec.from_record(record)
    root = np.random.SeedSequence(int(rng.integers(2**63 - 1)))
    rep_ss, *streams = root.spawn(3 + len(cands))
    seeds = rep_ss.spawn(int(replicates))
    gens = [np.random.default_rng(s) for s in streams]

    from tqdm.auto import tqdm

    bar = tqdm(total=2 + len(cands), desc="diagnose", disable=not progress, leave=False)
    try:
        bar.set_postfix_str("fit base")
        base_chk = check_model(record, base_model, rng=gens[0], replicate_seeds=seeds, spec=spec)
        bar.update()
        checks: dict[str, ModelCheck] = {}
        failed: dict[str, str] = {}
        for i, c in enumerate(cands):
            bar.set_postfix_str(f"screen + {c}")
            try:
                checks[c] = check_model(
                    record,
                    base_model.with_term(c),
                    rng=gens[2 + i],
                    replicate_seeds=seeds,
                    spec=spec,
                    method="screen",
                )
            except HosidInputError as exc:
                failed[c] = str(exc)
            bar.update()
        named, decision = _decide(base_chk, checks, threshold, shrink)
        final = base_chk
        if named is not None:
            bar.set_postfix_str(f"fit + {named}")
            try:
                final = check_model(
                    record,
                    base_model.with_term(named),
                    rng=gens[1],
                    replicate_seeds=seeds,
                    spec=spec,
                )
                decision += f"; the fitted model's gap is {final.total:.2f}"
            except HosidInputError as exc:
                decision += f"; but fitting it failed ({exc}): no effect named"
                failed[named] = f"fit: {exc}"
                named = None
        bar.update()
    finally:
        bar.close()
    settings = {
        "replicates": int(replicates),
        "threshold": float(threshold),
        "shrink": float(shrink),
        "candidates": cands,
        "duration": record.duration,
        "dt": record.dt,
        "block_seconds": spec.block * spec.dt,
        "omega_n": spec.omega_n,
        "screening": "estimate + importance-weighted Gaussian draws",
    }
    return Diagnosis(
        base=base_chk,
        candidates=checks,
        final=final,
        named_effect=named,
        decision=decision,
        settings=settings,
        failed=failed,
    )
