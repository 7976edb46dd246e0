r"""What :func:`hosid.check.diagnose.diagnose` finds: the named effects (:class:`Step`)
and the whole run (:class:`Diagnosis`), with its report (:mod:`hosid.check.report`) and
verdicts.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import xarray as xr

from ..verdicts import Check
from .evidence import COORDINATES
from .model_check import ModelCheck
from .selection import Round

__all__ = ["Diagnosis", "Step"]


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
    """The result of :func:`~hosid.check.diagnose.diagnose`.

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
