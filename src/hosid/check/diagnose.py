r"""The model-discrepancy workflow: name the missing effects, one at a time.

:func:`diagnose` fits the base model (:func:`hosid.check.model_check.check_model`:
emcee, or the cheaper screened posterior; with the excitation settled for the record,
or as given where that fit fails: a white model's band edge fitted to a narrow-band
force at a ship's resonance landed far outside its priors, and the record stopped with
an error before), measures its posterior-predictive gap
(:mod:`hosid.check.gaps`) and repeats rounds of

1. **weigh** every candidate effect not yet in the model from the fit itself
   (:mod:`hosid.check.evidence`: the Wald :math:`z` of the effect's parameter and the
   quasi-likelihood ratio :math:`D`, both calibrated), and **calibrate** the round on
   the model's own replicate records (:mod:`hosid.check.selection`: a false-alarm rate
   ``alpha`` for the round, whatever the number of candidates);
2. **add** the supported candidate with the smallest p-value, fit the extended model and
   measure its gap: the gap **vetoes** the effect when the extended model's simulations
   diverge while the current model's do not, or its gap does not fall below the current
   one (then the next supported candidate is tried): an effect is named only if the model
   with it predicts the record better.  A shaping filter or impulses whose fit keeps the
   white force (:mod:`hosid.inference.settle`: the record does not reject it at that
   test's level) are vetoed too.  When both models' simulations diverge the gap
   says nothing and the evidence decides;

until no candidate is supported (or ``max_effects`` are named).  The three numbers of
every candidate (:math:`z`, :math:`D`, its calibrated p-value) are kept for each round;
with ``candidate_gaps`` the first round's candidates also get their predictive gap
(screened posterior, for the report only: it does not enter the decision).

Every model's replicates use the same random streams (one
:class:`numpy.random.SeedSequence` spawned once: common random numbers), so that gaps
differ by their models and not by the noise of the replicates.  The base gap's
significance (its robust z against the leave-one-out null, ``threshold``) is reported:
a significant gap with no supported candidate points to an effect outside the list.
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
from ..verdicts import Check
from .evidence import COORDINATES
from .measures import MeasureSpec
from .model_check import ModelCheck, check_model
from .selection import Round, weigh_round

__all__ = ["DEFAULT_REPLICATES", "Diagnosis", "ModelCheck", "Step", "check_model", "diagnose"]

#: Fewest replicates :func:`diagnose` accepts (the null needs a robust spread).
MIN_REPLICATES = 8
#: Replicates per model by default.  A round's calibrated test is a Monte Carlo test:
#: with R = 19 or 20 an effect is named only if its record beats every null replicate, with
#: R = 40 if at most one beats it.  For a test of exact power 0.80 / 0.91 / 0.97 (at
#: 5 %) that is 0.71 / 0.84 / 0.93 with R = 20 and 0.76 / 0.88 / 0.95 with R = 40 (the
#: binomial law of the exceedances); each replicate costs one screening.
DEFAULT_REPLICATES = 40


@dataclass
class Step:
    """One named effect: the round that supported it, the fitted extended model, the gap
    before and after, and the candidates the gap vetoed first.
    """

    effect: str
    round: Round
    check: ModelCheck
    gap_before: float
    vetoed: dict[str, str] = field(default_factory=dict)

    @property
    def gap_after(self) -> float:
        """The extended model's gap."""
        return self.check.total

    def posterior(self) -> dict[str, float]:
        """The named parameter's posterior (draws of the check): mean, sd, quantiles."""
        param = COORDINATES[self.effect].param
        s = self.check.sample[:, self.check.model.index(param)]
        q = np.quantile(s, [0.05, 0.25, 0.5, 0.75, 0.95])
        mean, sd = float(np.mean(s)), float(np.std(s, ddof=1))
        return {
            "param": param,
            "mean": mean,
            "sd": sd,
            "z": mean / sd if sd > 0 else math.inf,
            **dict(zip(("q05", "q25", "q50", "q75", "q95"), q.tolist(), strict=True)),
        }


@dataclass
class Diagnosis:
    """The result of :func:`diagnose`.

    ``base`` and ``final`` are the first and last models' checks (``final`` is ``base``
    when nothing is named); ``steps`` the named effects in order; ``rounds`` every round
    of evidence (one more than the steps unless the candidates ran out);
    ``candidates`` the first round's candidates with their screened gaps.
    """

    base: ModelCheck
    candidates: dict[str, ModelCheck]
    final: ModelCheck
    decision: str
    settings: dict[str, Any] = field(default_factory=dict)
    failed: dict[str, str] = field(default_factory=dict)
    steps: list[Step] = field(default_factory=list)
    rounds: list[Round] = field(default_factory=list)
    record_checks: list[Check] = field(default_factory=list)

    @property
    def named_effects(self) -> list[str]:
        """Every named effect, in the order it was added."""
        return [s.effect for s in self.steps]

    @property
    def named_effect(self) -> str | None:
        """The first named effect (``None`` when nothing is named)."""
        return self.steps[0].effect if self.steps else None

    @property
    def final_tree(self) -> xr.DataTree:
        """The final model's emcee fit (for ``posterior.nc``).

        Raises
        ------
        ValueError
            If the final model was not fitted with emcee (``posterior="screen"``).
        """
        if self.final.tree is None:
            raise ValueError("the final model was not fitted with emcee")
        return self.final.tree

    @property
    def gaps(self) -> list[float]:
        """The total gap of the base model and after each named effect, in order."""
        return [self.base.total, *(s.gap_after for s in self.steps)]

    @property
    def gap_before(self) -> float:
        """The base model's total gap."""
        return self.base.total

    @property
    def gap_after(self) -> float:
        """The final model's total gap."""
        return self.final.total

    def checks(self) -> list[Check]:
        """The verdicts that travel with the result: the record checks the command ran,
        the final fit's own (calibration, convergence) and the predictive check.
        """
        from ..output.results import attr
        from .report import predictive_check

        own = [] if self.final.tree is None else attr(self.final.tree, "checks") or []
        own = [Check.from_dict(c) for c in own]  # a fit checks the record itself
        seen = {c.name for c in own}
        extra = [c for c in self.record_checks if c.name not in seen]
        return [*extra, *own, predictive_check(self)]

    def report(self) -> dict[str, Any]:
        """The ``report.json`` content (infinite gaps stay ``inf``; see ``jsonable``)."""
        from .report import diagnosis_report

        return diagnosis_report(self)


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


def _veto(current: ModelCheck, new: ModelCheck, effect: str) -> str | None:
    """Why the extended model's fit or gap vetoes its effect (module docstring), or
    ``None``.
    """
    if effect not in new.model.names:  # a shaping filter or impulses settled to white
        return (
            "its fit keeps the white force: the record does not reject it (hosid.inference.settle)"
        )
    if current.diverged:  # no finite gap to compare with
        return None
    if new.diverged:
        return "its posterior-predictive simulations diverge"
    if new.total >= current.total:
        return f"it does not narrow the gap ({current.total:.2f} -> {new.total:.2f})"
    return None


def _validate(replicates, alpha, threshold, max_effects, posterior) -> None:
    if int(replicates) != replicates or replicates < MIN_REPLICATES:
        raise HosidInputError(f"need at least {MIN_REPLICATES} replicates, got {replicates}")
    if not (math.isfinite(alpha) and 0 < alpha < 1):
        raise HosidInputError(f"alpha must be in (0, 1), got {alpha}")
    need = math.ceil(1.0 / alpha - 1.0 - 1e-9)
    if replicates < need:  # the smallest calibrated p-value is 1 / (R + 1)
        raise HosidInputError(
            f"a false-alarm rate of {alpha:g} needs at least {need} replicates, got {replicates}"
        )
    if not (math.isfinite(threshold) and threshold > 0):
        raise HosidInputError(f"threshold must be positive, got {threshold}")
    if max_effects is not None and (int(max_effects) != max_effects or max_effects < 0):
        raise HosidInputError(f"max_effects must be a non-negative integer, got {max_effects}")
    if posterior not in ("emcee", "screen"):
        raise HosidInputError(f"unknown posterior {posterior!r}: emcee or screen")


def diagnose(
    record: Record,
    base: Model | str | Sequence[str] = "paper",
    *,
    rng: np.random.Generator,
    candidates: Sequence[str] | None = None,
    replicates: int = DEFAULT_REPLICATES,
    alpha: float = 0.05,
    threshold: float = 3.0,
    max_effects: int | None = None,
    posterior: str = "emcee",
    candidate_gaps: bool = True,
    progress: bool = False,
) -> Diagnosis:
    r"""Name the effects the record supports beyond ``base``, one round at a time
    (module docstring).

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
        Posterior-predictive replicates per model: the gap and the calibration of each
        round (at least :math:`1/\alpha - 1`, 19 for 5 %: the smallest calibrated
        p-value is :math:`1/(R + 1)`).
    alpha : float
        False-alarm rate of a round: the probability of naming an effect when none of
        the candidates is present.
    threshold : float
        Robust z beyond which the base gap is significant (reported when nothing is named:
        an effect outside the candidates).
    max_effects : int, optional
        Stop after naming this many effects (default: as many as are supported).
    posterior : {"emcee", "screen"}
        How the base and every named model are fitted for their gap: emcee
        (:func:`hosid.inference.fit.fit`) or the screened quasi-posterior.
    candidate_gaps : bool
        Also measure the gap of every first-round candidate (report only).
    progress : bool
        One progress bar over the whole run, labelled with its stage.

    Returns
    -------
    Diagnosis

    Raises
    ------
    HosidInputError
        On unknown effect names, bad settings, or a base model that cannot be fitted.
    """
    if not isinstance(rng, np.random.Generator):
        raise TypeError("rng must be a numpy.random.Generator")
    base_model = Model.from_spec(base)
    cands = _candidates(base_model, candidates)
    _validate(replicates, alpha, threshold, max_effects, posterior)
    limit = len(cands) if max_effects is None else min(int(max_effects), len(cands))
    spec = MeasureSpec.from_record(record)
    rep_ss, path_ss, cand_ss = np.random.SeedSequence(int(rng.integers(2**63 - 1))).spawn(3)
    seeds = rep_ss.spawn(int(replicates))

    def check(model, ss, method, keep=True, settle=True):
        gen = np.random.default_rng(ss.spawn(1)[0])
        return check_model(
            record, model, rng=gen, replicate_seeds=seeds, spec=spec, method=method,
            keep_replicates=keep, settle=settle,
        )  # fmt: skip

    from ..progress import bar as progress_bar

    total = 2 + (len(cands) if candidate_gaps else 0)
    bar = progress_bar("hosid diagnose", total=total, enabled=progress, unit="fit")

    def stage(text, grow=0):  # the bar's label names the stage; the total grows by round
        bar.total += grow
        bar.set_description(f"hosid diagnose: {text}", refresh=True)

    steps: list[Step] = []
    rounds: list[Round] = []
    gaps_of: dict[str, ModelCheck] = {}
    failed: dict[str, str] = {}
    try:
        stage(f"fit base ({posterior})")
        current, base_note = _base_check(check, base_model, path_ss, posterior)
        base_chk = current
        bar.update()
        for c in cands:  # the fit may have added an excitation term that covers one
            if c not in current.model.candidates:
                failed[c] = f"the fitted model ({' + '.join(current.model.names)}) covers it"
        cands = [c for c in cands if c not in failed]
        limit = min(limit, len(cands))
        remaining = list(cands)
        while remaining and len(steps) < limit:
            stage(f"round {len(rounds) + 1}: weigh {len(remaining)} candidates", grow=1)
            rnd = weigh_round(
                record, current.model, remaining, start=current.theta_hat, alpha=alpha,
                family=len(cands), replicates=current.replicates, starts=current.draws,
            )  # fmt: skip
            rounds.append(rnd)
            bar.update()
            if len(rounds) == 1:
                failed.update(rnd.failed)
                for c in cands if candidate_gaps else ():
                    stage(f"gap + {c} (screen)")
                    try:
                        gaps_of[c] = check(current.model.extended(c), cand_ss, "screen", False)
                    except HosidInputError as exc:
                        failed.setdefault(c, str(exc))
                    bar.update()
            step = _step(rnd, current, check, (path_ss, posterior), stage, bar)
            if step is None:
                break
            steps.append(step)
            remaining.remove(step.effect)
            current = step.check
        bar.update(max(0, bar.total - bar.n))
    finally:
        bar.close()
    settings = {
        "base": base_note, "replicates": int(replicates), "alpha": float(alpha),
        "threshold": float(threshold), "max_effects": limit, "posterior": posterior,
        "candidates": cands, "duration": record.duration, "dt": record.dt,
        "block_seconds": spec.block * spec.dt, "omega_n": spec.omega_n,
    }  # fmt: skip
    from .report import decision_text

    diag = Diagnosis(base_chk, gaps_of, current, "", settings, failed, steps, rounds)
    diag.decision = decision_text(diag)
    return diag


def _step(rnd: Round, current: ModelCheck, check, how, stage, bar) -> Step | None:
    """The round's step: its first supported candidate whose fit (``check(model, *how)``)
    :func:`_veto` lets pass, or ``None``; the vetoes go to ``rnd.vetoed``.
    """
    rnd.vetoed = {}
    for c in rnd.supported():
        stage(f"fit + {c} ({how[1]})", grow=1)
        try:
            new = check(current.model.extended(c), *how)
            why = _veto(current, new, c)
        except HosidInputError as exc:
            why = f"fitting it failed ({exc})"
        bar.update()
        if why is None:
            return Step(c, rnd, new, current.total, dict(rnd.vetoed))
        rnd.vetoed[c] = why
    return None


def _base_check(check, model, ss, posterior):
    """The base model's check and how it was fitted: with the excitation settled for the
    record (a band's edge added, :func:`hosid.inference.estimate.estimate`), or, where
    that fit fails (a white model's edge fitted to a narrow-band force can land far
    outside its priors), the model as given; the first error stands if both fail.
    """
    try:
        return check(model, ss, posterior), "excitation settled for the record"
    except HosidInputError as exc:
        try:
            chk = check(model, ss, posterior, settle=False)
        except HosidInputError:
            raise exc from None
        return chk, f"as given: with the excitation settled its fit failed ({exc})"
