r"""Where a system's missing effect sits: (effect, element) candidates, each weighed by
the Wald test of its coefficient in the extended system's fit.

For a system :math:`S` (:class:`hosid.model.system.System`) and a candidate pair
:math:`(t, e)`, a drift term :math:`t` of :data:`CHAIN_CANDIDATES` that element :math:`e`
lacks, :func:`locate` fits the extended system :math:`S + (t, e)` with a system's default
estimating equations (:func:`hosid.inference.system_estimate.estimate_system`: the rounds
of efficient GMM, started at :math:`S`'s estimate with the new coefficient :math:`c` at
its null 0) and weighs :math:`c` by

.. math:: z = \hat c / \mathrm{sd}(\hat c),

the sd from the calibrated curvature of the quasi-likelihood (efficient GMM: the
sandwich covariance, what the posterior of :func:`hosid.fit` says about :math:`c`),
widened by Hansen's dispersion when the extended fit's over-identification test rejects
(:data:`hosid.inference.calibrate.HANSEN_P`), as the posterior is.  Under :math:`S` each
:math:`z` is standard normal; a round names the pair with the largest :math:`|z|` when
its two-sided p-value is below :math:`\alpha/K` for the :math:`K` pairs weighed
(Bonferroni: a false-alarm rate of at most :math:`\alpha` a round, whatever the pairs'
correlation).  The named pair joins the system and the next round weighs the others,
until none is supported or ``max_effects`` are named.

The single oscillator's :func:`hosid.check.diagnose.diagnose` calibrates each round on
posterior-predictive replicates and vetoes an effect whose model does not narrow the
predictive gap; for a system each replicate would cost a simulation and one fit per
pair, so the rounds here rest on the Wald statistics' normal law, and their false-alarm
rate is measured on clean records instead (``analyses/locate_power.py``).  Candidates
are the symmetric drift terms whose null (0) is inside their prior: quadratic damping,
cubic and quadratic stiffness.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from ..errors import HosidInputError
from ..inference.calibrate import calibrate
from ..inference.estimate import Estimate
from ..inference.system_estimate import centred, estimate_system, system_state
from ..model.model import get_term
from ..model.system import Element, System
from ..record import Record
from ..screen import check_record, reject_failures
from ..verdicts import Check

__all__ = ["CHAIN_CANDIDATES", "Localisation", "Weighed", "locate"]

#: The effects a pair may add (two-sided nulls at 0); the default list.
CHAIN_CANDIDATES = ("quadratic_damping", "cubic_stiffness", "quadratic_stiffness")
#: Used when ``candidates`` is not given: the odd terms (the state stays centred).
DEFAULT_CANDIDATES = ("quadratic_damping", "cubic_stiffness")


@dataclass
class Weighed:
    """One (effect, element) pair's evidence: the coefficient's estimate, its calibrated
    sd, ``z`` and the two-sided p-value; Hansen's test of the extended fit.
    """

    effect: str
    element: str
    param: str
    value: float
    sd: float
    z: float
    p_value: float
    hansen_p: float
    dispersion: float
    seconds: float

    @property
    def label(self) -> str:
        """``"cubic_stiffness in x1-x2"``."""
        return f"{self.effect} in {self.element}"

    def as_dict(self) -> dict[str, Any]:
        """Plain numbers for reports."""
        return {**self.__dict__, "label": self.label}


@dataclass
class Round:
    """The pairs weighed against one system, the per-pair level and the named pair."""

    system: System
    weighed: list[Weighed]
    failed: dict[str, str]
    level: float
    named: Weighed | None

    def as_dict(self) -> dict[str, Any]:
        """Plain data for reports."""
        return {
            "system": self.system.describe(),
            "level": self.level,
            "candidates": [w.as_dict() for w in self.weighed],
            "failed": dict(self.failed),
            "named": None if self.named is None else self.named.label,
        }


@dataclass
class Localisation:
    """The result of :func:`locate`: the rounds, the named pairs in order, the final
    system's estimate and sd.
    """

    base: System
    final: System
    rounds: list[Round]
    alpha: float
    estimate: dict[str, float]
    sd: dict[str, float]
    settings: dict[str, Any] = field(default_factory=dict)
    record_checks: list[Check] = field(default_factory=list)

    @property
    def named(self) -> list[Weighed]:
        """The named pairs, in the order they were added."""
        return [r.named for r in self.rounds if r.named is not None]

    @property
    def named_effects(self) -> list[str]:
        """``["cubic_stiffness in x1-x2", ...]``."""
        return [w.label for w in self.named]

    @property
    def decision(self) -> str:
        """One sentence: what was named and why the rounds stopped."""
        last = self.rounds[-1]
        if not self.named:
            return (f"no pair is supported: the largest |z| has p = {_best_p(last):.3g} "
                    f">= alpha/K = {last.level:.3g}")  # fmt: skip
        said = ", then ".join(f"{w.label} (z = {w.z:+.2f})" for w in self.named)
        if last.named is not None:
            cap = self.settings.get("max_effects")
            why = f"max_effects = {cap} reached" if cap == len(self.named) else "no pair left"
            return f"named {said}; {why}"
        return f"named {said}; no other pair is supported (p >= {last.level:.3g})"

    def report(self) -> dict[str, Any]:
        """The ``report.json`` content."""
        return {
            "kind": "locate",
            "base": self.base.describe(),
            "final": self.final.describe(),
            "named_effects": self.named_effects,
            "named": [
                {
                    k: getattr(w, k)
                    for k in ("effect", "element", "param", "value", "sd", "z", "p_value")
                }
                for w in self.named
            ],
            "decision": self.decision,
            "alpha": self.alpha,
            "rounds": [r.as_dict() for r in self.rounds],
            "estimate": self.estimate,
            "sd": self.sd,
            "checks": [c.as_dict() for c in self.record_checks],
            "settings": self.settings,
        }


def _best_p(r: Round) -> float:
    return min((w.p_value for w in r.weighed), default=1.0)


def pairs(system: System, candidates: Sequence[str]) -> list[tuple[str, int]]:
    """The (effect, element index) pairs: each candidate in each element that lacks it."""
    out = []
    for k, e in enumerate(system.elements):
        have = {t.name for t in e.terms}
        out += [(c, k) for c in candidates if c not in have]
    return out


def extended(system: System, effect: str, k: int) -> System:
    """``system`` with ``effect`` added to its element ``k`` (no parameter values)."""
    elements = list(system.elements)
    e = elements[k]
    elements[k] = Element(e.between, (*e.terms, get_term(effect)))
    return replace(system, elements=tuple(elements), values=())


def _weigh(state, system, effect, k, start: dict[str, float]) -> tuple[Weighed, Estimate]:
    """The pair's evidence and the extended system's estimate (module docstring)."""
    t0 = time.perf_counter()
    ext = extended(system, effect, k)
    param = f"{get_term(effect).params[0]}[{ext.elements[k].label}]"
    est = estimate_system(state, ext, start=[start.get(n, 0.0) for n in ext.param_names])
    i = ext.index(param)
    disp = calibrate(est).dispersion  # Hansen's widening, as the posterior's
    sd = math.sqrt(max(float(est.cov[i, i]) * disp, 0.0))
    value = float(est.theta[i])
    z = value / sd if sd > 0 else 0.0
    p = math.erfc(abs(z) / math.sqrt(2.0))
    weighed = Weighed(effect, ext.elements[k].label, param, value, sd, z, p,
                      float(est.test["p_value"]), disp, time.perf_counter() - t0)  # fmt: skip
    return weighed, est


def locate(
    record: Record,
    system: System,
    *,
    candidates: Sequence[str] | None = None,
    alpha: float = 0.05,
    max_effects: int | None = None,
    block_seconds: float | None = None,
    unit: str = "m",
    force: bool = False,
    checks: Sequence[Check] | None = None,
    progress: Callable[[str], None] | None = None,
) -> Localisation:
    """Name the missing (effect, element) pairs of ``system`` (module docstring).

    Parameters
    ----------
    record : Record
        The record, one channel per degree of freedom of ``system``.
    system : System
        The base system (an all-linear chain, say).
    candidates : sequence of str, optional
        Effects of :data:`CHAIN_CANDIDATES`; default :data:`DEFAULT_CANDIDATES`.
    alpha : float
        The false-alarm rate of a round (Bonferroni over its pairs).
    max_effects : int or None
        Name at most this many pairs (``None``: until none is supported).
    checks : sequence of Check, optional
        The record checks already run (default: run them here).
    progress : callable, optional
        Called with a short text before each pair is weighed.

    Raises
    ------
    HosidInputError
        For an effect that is not a candidate, a system without a pair to weigh, or a
        base system that cannot be estimated.
    """
    t0 = time.perf_counter()
    chosen = tuple(DEFAULT_CANDIDATES if candidates is None else candidates)
    bad = [c for c in chosen if c not in CHAIN_CANDIDATES]
    if bad:
        raise HosidInputError(f"not candidate effects of a system: {', '.join(bad)}; "
                              f"candidates: {', '.join(CHAIN_CANDIDATES)}")  # fmt: skip
    if not 0.0 < alpha < 1.0:
        raise HosidInputError(f"alpha must lie in (0, 1), got {alpha}")
    if not pairs(system, chosen):
        raise HosidInputError("every element already has every candidate effect")
    picked = record.select(system.dofs, measured=system.declared)
    checks = list(checks) if checks is not None else check_record(picked, unit=unit)
    reject_failures(checks, force=force)
    states: dict[bool, Any] = {}  # one state each for centred and uncentred systems

    def state_of(s: System):
        if centred(s) not in states:
            states[centred(s)] = system_state(record, s, block_seconds=block_seconds)
        return states[centred(s)]

    # the candidates are nonlinear, whose fits keep the identities: so does the base
    current = system if system.sensor_noise is not None else replace(system, sensor_noise=False)
    est = estimate_system(state_of(current), current)
    rounds: list[Round] = []
    while True:
        start = current.params(est.theta)
        todo = pairs(current, chosen)
        weighed, failed, fits = [], {}, {}
        for effect, k in todo:
            label = f"{effect} in {current.elements[k].label}"
            if progress is not None:
                progress(label)
            try:
                w, fits[label] = _weigh(state_of(extended(current, effect, k)), current,
                                        effect, k, start)  # fmt: skip
                weighed.append(w)
            except HosidInputError as exc:
                failed[label] = str(exc)
        level = alpha / max(len(weighed), 1)
        best = min(weighed, key=lambda w: w.p_value, default=None)
        named = best if best is not None and best.p_value < level else None
        rounds.append(Round(current, weighed, failed, level, named))
        if named is None:
            break
        est = fits[named.label]  # the named pair's fit is the next round's system's
        current = est.model
        if (max_effects is not None and len(rounds) >= max_effects) or not pairs(current, chosen):
            break
    sd = np.sqrt(np.maximum(np.diag(est.cov), 0.0))
    return Localisation(
        base=system,
        final=current,
        rounds=rounds,
        alpha=alpha,
        estimate=current.params(est.theta),
        sd=dict(zip(current.param_names, sd.tolist(), strict=True)),
        settings={
            "candidates": list(chosen),
            "alpha": alpha,
            "max_effects": max_effects,
            "block_seconds": block_seconds,
            "seconds": time.perf_counter() - t0,
        },
        record_checks=list(checks),
    )
