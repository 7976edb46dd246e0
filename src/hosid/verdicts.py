"""Verdicts that travel with results: one :class:`Check` per thing hosid looked at.

A check has a ``name`` (``offset``, ``clipping``, ``oscillator``, ``convergence`` ...),
a ``status`` (``"pass"``, ``"warn"`` or ``"fail"``), the measured ``value`` and a
one-line ``message``.  ``summary.json`` holds them as ``"checks"``, the ``DataTree``
attributes as ``checks_json`` and the report's banner shows them.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from dataclasses import asdict, dataclass
from typing import Any

__all__ = ["ESS_MIN", "RHAT_MAX", "STATUSES", "Check", "convergence", "overall"]

#: The statuses, from best to worst.
STATUSES = ("pass", "warn", "fail")
#: A chain has converged when every rank-normalized R-hat is below this ...
RHAT_MAX = 1.01
#: ... and every bulk and tail effective sample size at least this.
ESS_MIN = 400.0


@dataclass(frozen=True)
class Check:
    """One verdict (module docstring)."""

    name: str
    status: str
    value: float | None
    message: str

    def __post_init__(self) -> None:
        if self.status not in STATUSES:
            raise ValueError(f"status must be one of {STATUSES}, got {self.status!r}")
        if self.value is not None:
            v = float(self.value)
            object.__setattr__(self, "value", v if math.isfinite(v) else None)

    def as_dict(self) -> dict[str, Any]:
        """Plain JSON types."""
        return asdict(self)

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> Check:
        """The inverse of :meth:`as_dict`."""
        return cls(str(data["name"]), str(data["status"]), data.get("value"), str(data["message"]))


def overall(checks: Iterable[Check]) -> str:
    """The worst status of ``checks`` (``"pass"`` when there are none)."""
    worst = 0
    for c in checks:
        worst = max(worst, STATUSES.index(c.status))
    return STATUSES[worst]


def convergence(diagnostics: Mapping[str, float]) -> Check:
    """The sampler's verdict from the worst R-hat and ESS (``r_hat_max``,
    ``ess_bulk_min``, ``ess_tail_min``): ``warn`` outside :data:`RHAT_MAX` /
    :data:`ESS_MIN`.
    """
    r = float(diagnostics["r_hat_max"])
    e = min(float(diagnostics["ess_bulk_min"]), float(diagnostics["ess_tail_min"]))
    ok = r < RHAT_MAX and e >= ESS_MIN
    return Check(
        "convergence",
        "pass" if ok else "warn",
        r,
        f"worst R-hat {r:.4f} (< {RHAT_MAX} wanted), smallest ESS {e:.0f} (>= {ESS_MIN:.0f})"
        + ("" if ok else ": run longer (--steps) before trusting the intervals"),
    )
