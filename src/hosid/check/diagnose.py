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

import numpy as np

from ..errors import HosidInputError
from ..model.model import Model, get_term
from ..model.terms import CANDIDATES
from ..record import Record
from .diagnosis_result import Diagnosis, Step
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

    from ..progress import Stages

    stages = Stages("hosid diagnose", enabled=progress)
    bar = stages.stage(f"fit base ({posterior})", unit="fit",
                       total=2 + (len(cands) if candidate_gaps else 0))  # fmt: skip
    failed: dict[str, str] = {}
    try:
        base_chk, base_note = _base_check(check, base_model, path_ss, posterior)
        bar.update()
        for c in cands:  # the fit may have added an excitation term that covers one
            if c not in base_chk.model.candidates:
                failed[c] = f"the fitted model ({' + '.join(base_chk.model.names)}) covers it"
        cands = [c for c in cands if c not in failed]
        limit = min(limit, len(cands))
        steps, rounds, gaps_of = _rounds(
            record, base_chk, cands, limit, alpha, check, (path_ss, posterior), stages,
            cand_ss if candidate_gaps else None, failed,
        )  # fmt: skip
        bar.update(max(0, bar.total - bar.n))
    finally:
        stages.close()
    current = steps[-1].check if steps else base_chk
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


def _rounds(record, current: ModelCheck, cands, limit, alpha, check, how, stages, gap_seed,
            failed):  # fmt: skip
    """The rounds from the base model's check ``current`` (module docstring), at most
    ``limit`` effects named: the steps, every round and, from ``gap_seed`` (``None``: not
    measured), the first round's candidates' gaps; the candidates that fail go to
    ``failed``.
    """
    steps: list[Step] = []
    rounds: list[Round] = []
    gaps_of: dict[str, ModelCheck] = {}
    remaining = list(cands)
    while remaining and len(steps) < limit:
        bar = stages.relabel(f"round {len(rounds) + 1}: weigh {len(remaining)} candidates", grow=1)
        rnd = weigh_round(
            record, current.model, remaining, start=current.theta_hat, alpha=alpha,
            family=len(cands), replicates=current.replicates, starts=current.draws,
        )  # fmt: skip
        rounds.append(rnd)
        bar.update()
        if len(rounds) == 1:
            failed.update(rnd.failed)
            if gap_seed is not None:
                gaps_of = _candidate_gaps(check, current.model, cands, gap_seed, stages, failed)
        step = _step(rnd, current, check, how, stages)
        if step is None:
            break
        steps.append(step)
        remaining.remove(step.effect)
        current = step.check
    return steps, rounds, gaps_of


def _step(rnd: Round, current: ModelCheck, check, how, stages) -> Step | None:
    """The round's step: its first supported candidate whose fit (``check(model, *how)``)
    :func:`_veto` lets pass, or ``None``; the vetoes go to ``rnd.vetoed``.
    """
    rnd.vetoed = {}
    for c in rnd.supported():
        bar = stages.relabel(f"fit + {c} ({how[1]})", grow=1)
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


def _candidate_gaps(check, model, cands, ss, stages, failed) -> dict[str, ModelCheck]:
    """Every candidate's gap (screened quasi-posterior; report only); a failure is noted
    in ``failed`` unless it holds one already.
    """
    gaps = {}
    for c in cands:
        bar = stages.relabel(f"gap + {c} (screen)")
        try:
            gaps[c] = check(model.extended(c), ss, "screen", False)
        except HosidInputError as exc:
            failed.setdefault(c, str(exc))
        bar.update()
    return gaps


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
