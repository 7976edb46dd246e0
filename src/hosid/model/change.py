r"""A change of the oscillator's parameters during a simulated record (a step or a ramp).

For condition monitoring: the record of :func:`hosid.model.simulate.simulate` starts
stationary under its parameters :math:`\theta_b` and, from the time :math:`t_c` (seconds
from the record's first sample, after the burn-in), moves to :math:`\theta_a`,

.. math::

    \theta(t) = \bigl(1 - \phi(t)\bigr)\theta_b + \phi(t)\theta_a, \qquad
    \phi(t) = \min\bigl(\max((t - t_c)/R, 0), 1\bigr)

over a ramp of :math:`R` seconds, or :math:`\phi(t) = \mathbf 1\{t \ge t_c\}` for a step
(:math:`R = 0`).  Any of :math:`a_1, n_1, a_2, n_2, S_0` and the optional drift
coefficients :math:`b_2, \mu, m` may change.  The drift coefficients change inside the
compiled Heun kernels, sub-step by sub-step (:math:`\phi` at the sub-step's midpoint; a
step falls on the sub-step boundary nearest :math:`t_c`), so nothing of the length of
the record is added.  A change of the level scales the force from then on:

.. math::

    g(t) \to \sqrt{S_0(t)/S_0}\;g(t),

that is the white force's increments :math:`\Delta W` and :math:`\Delta Z`, the input of
the low-pass, the shaped or band-limited force's values and the impulses' areas, so the
force's spectrum after the change is :math:`S_0(t)L(\omega)` (a slowly varying level:
exact for the white force and the impulses, whose increments are independent; a
shaped force keeps its correlation across the change).

The same change as flat keys (``hosid simulate``'s sidecar of true values, a design
table): ``change_at``, ``ramp`` and ``<p>_after`` (:data:`FLAT_KEYS`).

Notes
-----
:func:`blend` is compiled into :func:`hosid.model.simulate._heun` and
:func:`hosid.model.simulate._heun_forced`; numba's on-disk cache of those kernels does
not notice an edit of this file, so after changing :func:`blend` touch ``simulate.py``
(or clear its ``__pycache__``).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from types import MappingProxyType

import numpy as np

from .._jit import njit
from ..errors import HosidInputError

__all__ = ["CHANGE_PARAMS", "FLAT_KEYS", "NO_SWITCH", "Change", "blend", "switch"]

#: The parameters that may change.
CHANGE_PARAMS = ("a1", "n1", "a2", "n2", "S0", "b2", "mu", "m")
#: The change as flat keys (a sidecar of true values, a design table's columns).
FLAT_KEYS = ("change_at", "ramp", *(f"{p}_after" for p in CHANGE_PARAMS))


def _spell(key: str, options: bool) -> str:
    return "--" + key.replace("_", "-") if options else key


@dataclass(frozen=True)
class Change:
    r"""A step (``ramp = 0``) or linear ramp of parameters at ``at`` seconds (module
    docstring).

    Parameters
    ----------
    at : float
        Seconds from the record's first sample at which the change starts,
        :math:`0 < t_c < T`.
    after : mapping
        Parameter name (:data:`CHANGE_PARAMS`) -> value after the change; at least one.
    ramp : float
        Seconds over which the parameters move linearly to ``after`` (0: a step);
        :math:`t_c + R \le T`.

    Raises
    ------
    HosidInputError
        If ``after`` is empty, names another parameter or holds a non-finite value, or
        ``at`` or ``ramp`` are not finite and positive (non-negative).
    """

    at: float
    after: Mapping[str, float] = field(hash=False)
    ramp: float = 0.0

    def __post_init__(self) -> None:
        try:
            after = {str(k): float(v) for k, v in dict(self.after).items()}
            at, ramp = float(self.at), float(self.ramp)
        except (TypeError, ValueError):
            raise HosidInputError("change: at, ramp and the values after it are numbers") from None
        unknown = sorted(set(after) - set(CHANGE_PARAMS))
        if unknown:
            raise HosidInputError(
                f"change: cannot change {', '.join(unknown)}; "
                f"parameters that can change: {', '.join(CHANGE_PARAMS)}"
            )
        if not after:
            raise HosidInputError("change: give at least one parameter's value after it")
        if not all(math.isfinite(v) for v in after.values()):
            raise HosidInputError("change: the values after it must be finite")
        if not (math.isfinite(at) and at > 0):
            raise HosidInputError(f"change: at = {at:g} s must be finite and positive")
        if not (math.isfinite(ramp) and ramp >= 0):
            raise HosidInputError(f"change: ramp = {ramp:g} s must be finite and >= 0")
        object.__setattr__(self, "after", MappingProxyType(after))
        object.__setattr__(self, "at", at)
        object.__setattr__(self, "ramp", ramp)

    def __reduce__(self):  # the read-only view of ``after`` does not pickle
        return (type(self), (self.at, dict(self.after), self.ramp))

    @classmethod
    def split(
        cls, values: Mapping[str, float | None], *, options: bool = False
    ) -> tuple[dict[str, float], Change | None]:
        """Split flat keys (:data:`FLAT_KEYS`; ``None`` = absent) off ``values``: the
        other entries and the change (``None`` when no key is given).

        ``options``: name the keys as ``hosid simulate``'s options in messages.

        Raises
        ------
        HosidInputError
            If ``ramp`` or a value after the change is given without ``change_at``, or
            ``change_at`` without any value after it (or as :class:`Change`).
        """
        given = {k: v for k, v in values.items() if v is not None}
        rest = {k: v for k, v in given.items() if k not in FLAT_KEYS}
        after = {k[: -len("_after")]: v for k, v in given.items() if k in FLAT_KEYS[2:]}
        if "change_at" not in given:
            stray = [_spell(k, options) for k in FLAT_KEYS if k in given]
            if stray:
                raise HosidInputError(
                    f"{', '.join(stray)} without {_spell('change_at', options)}: "
                    "give the time of the change"
                )
            return rest, None
        if not after:
            names = [_spell(k, options) for k in FLAT_KEYS[2:] if k in values] or [
                _spell(k, options) for k in FLAT_KEYS[2:]
            ]
            raise HosidInputError(
                f"{_spell('change_at', options)} needs at least one of {', '.join(names)}"
            )
        return rest, cls(at=given["change_at"], after=after, ramp=given.get("ramp", 0.0))

    def flat(self) -> dict[str, float]:
        """The change as flat keys: ``change_at``, ``ramp`` and ``<p>_after``."""
        return {
            "change_at": self.at,
            "ramp": self.ramp,
            **{f"{p}_after": self.after[p] for p in CHANGE_PARAMS if p in self.after},
        }

    def params_after(self, params: Mapping[str, float]) -> dict[str, float]:
        """``params`` with the values after the change."""
        return {**params, **self.after}

    def describe(self, params: Mapping[str, float]) -> str:
        """One line: what changes, from what to what, and when."""
        moves = ", ".join(
            f"{p} {float(params.get(p, 0.0) or 0.0):g} -> {v:g}" for p, v in self.after.items()
        )
        if self.ramp > 0:
            return f"change {moves} ramped over {self.at:g}-{self.at + self.ramp:g} s"
        return f"change {moves} at {self.at:g} s"

    def validate(
        self, params: Mapping[str, float], duration: float, dt: float, substeps=None
    ) -> None:
        """Check the change against the record and the oscillator after it.

        Raises
        ------
        HosidInputError
            If the change does not start inside the record, :math:`0 < t_c < T`, its
            ramp ends after the record, :math:`t_c + R > T`, or the oscillator after it
            has no stationary state (:func:`hosid.model.simulate._check`).
        """
        from .simulate import _check

        if not self.at < duration:
            raise HosidInputError(
                f"change: at = {self.at:g} s is not inside the record (0, {duration:g} s)"
            )
        if self.at + self.ramp > duration:
            raise HosidInputError(
                f"change: the ramp ends at {self.at + self.ramp:g} s, after the record "
                f"({duration:g} s)"
            )
        try:
            _check(self.params_after(params), duration, dt, substeps)
        except HosidInputError as exc:
            raise HosidInputError(f"after the change: {exc}") from None


#: The kernels' switch without a change (:func:`switch`).
NO_SWITCH = (np.zeros(7), 1.0, -1.0, -1.0)


def switch(
    change: Change | None,
    params: Mapping[str, float],
    *,
    duration: float,
    dt: float,
    substeps,
    burn: int,
) -> tuple[np.ndarray, float, float, float]:
    r"""The kernels' switch ``(c_after, S0_after / S0, start, end)``: the drift
    coefficients after the change (in the kernels' order), the ratio of the levels, and
    the change's start and end in samples from the start of the burn-in
    (:math:`\mathrm{burn} + 1 + t_c/\Delta t`: the record's first sample is the state
    after ``burn + 1`` samples); :data:`NO_SWITCH`'s negative times never switch.

    Raises
    ------
    HosidInputError
        As :meth:`Change.validate`.
    """
    if change is None:
        return NO_SWITCH
    from .simulate import _DRIFT_KEYS

    change.validate(params, duration, dt, substeps)
    after = change.params_after(params)
    c2 = np.array([float(after.get(k, 0.0) or 0.0) for k in _DRIFT_KEYS])
    start = burn + 1 + change.at / dt
    ratio = float(after["S0"]) / float(params["S0"])
    return c2, ratio, start, start + change.ramp / dt


@njit(cache=True, inline="always")
def blend(k, k0, k1, c, sw, out):  # pragma: no cover - compiled
    r"""Drift coefficients of sub-step ``k`` (``k0 <= k <= k1``, the change's sub-steps)
    into ``out``, :math:`(1 - \phi)c + \phi c_a` with :math:`\phi` at the sub-step's
    midpoint (1 from ``k1`` on); returns the force's scale
    :math:`\sqrt{1 + \phi(S_{0a}/S_0 - 1)}`.
    """
    f = 1.0 if k >= k1 else (k + 0.5 - k0) / (k1 - k0)
    c2 = sw[0]
    for j in range(out.size):
        out[j] = (1.0 - f) * c[j] + f * c2[j]
    return math.sqrt(1.0 + f * (sw[1] - 1.0))
