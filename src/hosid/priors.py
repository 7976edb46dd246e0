r"""Priors for the oscillator's parameters and the eq-65 admissibility constraint.

Each prior knows ``ln_prob`` (vectorized, ``-inf`` outside its support),
``sample`` (through an explicit :class:`numpy.random.Generator`) and ``rescale``
(from the unit interval, for nested samplers and tests).  A :class:`PriorSet`
combines one prior per parameter and evaluates ``theta`` of shape ``(..., p)``.

The constraint of eq (65) keeps the equivalent linear damping positive,

.. math:: a_{1eq} = a_1 + n_1\sqrt{8/\pi}\,\sigma_{\dot x} > 0,

with :math:`\sigma_{\dot x}` measured from the record.  It removes the twin
minimum of J2 and J4 at negative damping.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass

import numpy as np
from scipy import special

__all__ = [
    "DEFAULT_PRIORS",
    "LogUniform",
    "Normal",
    "Prior",
    "PriorSet",
    "Uniform",
    "default_priors",
]

SQRT_8_PI = math.sqrt(8.0 / math.pi)


class Prior:
    """Base class: a one-dimensional prior density."""

    lower: float = -math.inf
    upper: float = math.inf

    def ln_prob(self, x) -> np.ndarray:  # pragma: no cover - abstract
        """Log density (``-inf`` outside the support)."""
        raise NotImplementedError

    def rescale(self, u) -> np.ndarray:  # pragma: no cover - abstract
        """Map ``u`` in [0, 1] to the parameter through the inverse CDF."""
        raise NotImplementedError

    def sample(self, rng: np.random.Generator, size=None) -> np.ndarray:
        """Draw from the prior with ``rng``."""
        return self.rescale(rng.uniform(size=size))


@dataclass(frozen=True)
class Uniform(Prior):
    r"""Uniform on :math:`[\text{lower}, \text{upper}]`."""

    lower: float
    upper: float

    def __post_init__(self):
        if not self.upper > self.lower:
            raise ValueError(f"Uniform prior needs lower < upper, got {self.lower}, {self.upper}")

    def ln_prob(self, x) -> np.ndarray:
        """Log density."""
        x = np.asarray(x, dtype=float)
        inside = (x >= self.lower) & (x <= self.upper)
        return np.where(inside, -math.log(self.upper - self.lower), -np.inf)

    def rescale(self, u) -> np.ndarray:
        """Inverse CDF."""
        return self.lower + np.asarray(u, dtype=float) * (self.upper - self.lower)


@dataclass(frozen=True)
class LogUniform(Prior):
    r"""Density :math:`\propto 1/x` on :math:`[\text{lower}, \text{upper}]`, lower > 0."""

    lower: float
    upper: float

    def __post_init__(self):
        if not (self.lower > 0 and self.upper > self.lower):
            raise ValueError(
                f"LogUniform prior needs 0 < lower < upper, got {self.lower}, {self.upper}"
            )

    def ln_prob(self, x) -> np.ndarray:
        """Log density."""
        x = np.asarray(x, dtype=float)
        inside = (x >= self.lower) & (x <= self.upper)
        with np.errstate(divide="ignore", invalid="ignore"):
            lp = -np.log(x) - math.log(math.log(self.upper / self.lower))
        return np.where(inside, lp, -np.inf)

    def rescale(self, u) -> np.ndarray:
        """Inverse CDF."""
        return self.lower * (self.upper / self.lower) ** np.asarray(u, dtype=float)


@dataclass(frozen=True)
class Normal(Prior):
    r"""Normal :math:`\mathcal N(\mu, \sigma^2)`."""

    mu: float
    sigma: float

    def __post_init__(self):
        if not self.sigma > 0:
            raise ValueError(f"Normal prior needs sigma > 0, got {self.sigma}")

    def ln_prob(self, x) -> np.ndarray:
        """Log density."""
        z = (np.asarray(x, dtype=float) - self.mu) / self.sigma
        return -0.5 * z**2 - math.log(self.sigma * math.sqrt(2 * math.pi))

    def rescale(self, u) -> np.ndarray:
        """Inverse CDF."""
        return self.mu + self.sigma * math.sqrt(2) * special.erfinv(
            2 * np.asarray(u, dtype=float) - 1
        )


#: Weakly informative defaults: wide enough to hold the negative-damping twin
#: mode and any stiffness a user would meet; S0 log-uniform over ten decades.
DEFAULT_PRIORS: dict[str, Prior] = {
    "a1": Uniform(-50.0, 50.0),
    "n1": Uniform(-10.0, 10.0),
    "a2": Uniform(-500.0, 2000.0),
    "n2": Uniform(-500.0, 2000.0),
    "S0": LogUniform(1e-4, 1e6),
}


class PriorSet(Mapping):
    r"""One prior per parameter, evaluated jointly on ``theta`` of shape ``(..., p)``.

    Parameters
    ----------
    priors : mapping name -> Prior
        In parameter order.
    sigma_v : float, optional
        The record's velocity RMS; with it (and ``constrained=True``) the eq-65
        constraint :math:`a_1 + n_1\sqrt{8/\pi}\sigma_{\dot x} > 0` is applied.
    constrained : bool
        Apply the eq-65 constraint (default True; needs ``sigma_v``).
    """

    def __init__(
        self,
        priors: Mapping[str, Prior],
        *,
        sigma_v: float | None = None,
        constrained: bool = True,
    ):
        self._priors = dict(priors)
        if constrained and sigma_v is None:
            raise ValueError("the eq-65 constraint needs sigma_v (the record's velocity RMS)")
        if constrained and not ("a1" in self._priors and "n1" in self._priors):
            raise ValueError("the eq-65 constraint needs a1 and n1 among the parameters")
        self.sigma_v = sigma_v
        self.constrained = constrained

    def __getitem__(self, key: str) -> Prior:
        return self._priors[key]

    def __iter__(self):
        return iter(self._priors)

    def __len__(self) -> int:
        return len(self._priors)

    @property
    def names(self) -> tuple[str, ...]:
        """Parameter names in order."""
        return tuple(self._priors)

    def a1eq(self, theta) -> np.ndarray:
        """Equivalent linear damping of eq (65) at ``theta``."""
        th = np.asarray(theta, dtype=float)
        i, j = self.names.index("a1"), self.names.index("n1")
        return th[..., i] + th[..., j] * SQRT_8_PI * (self.sigma_v or 0.0)

    def ln_prob(self, theta) -> np.ndarray:
        """Joint log prior, ``-inf`` outside the supports or the constraint."""
        th = np.asarray(theta, dtype=float)
        if th.shape[-1] != len(self):
            raise ValueError(f"theta has {th.shape[-1]} parameters, expected {len(self)}")
        lp = sum(p.ln_prob(th[..., i]) for i, p in enumerate(self._priors.values()))
        lp = np.asarray(lp, dtype=float)
        if self.constrained:
            lp = np.where(self.a1eq(th) > 0, lp, -np.inf)
        return lp

    def sample(self, rng: np.random.Generator, size: int) -> np.ndarray:
        """``size`` joint draws of shape ``(size, p)`` (rejection for the constraint)."""
        out = np.empty((0, len(self)))
        while out.shape[0] < size:
            draw = np.stack([p.sample(rng, size) for p in self._priors.values()], axis=-1)
            out = np.concatenate([out, draw[np.isfinite(self.ln_prob(draw))]])
        return out[:size]


def default_priors(
    names: Iterable[str] = ("a1", "n1", "a2", "n2", "S0"),
    *,
    sigma_v: float | None = None,
    constrained: bool = True,
    overrides: Mapping[str, Prior] | None = None,
) -> PriorSet:
    """The default :class:`PriorSet` (``DEFAULT_PRIORS``), with optional overrides."""
    overrides = dict(overrides or {})
    missing = [n for n in names if n not in DEFAULT_PRIORS and n not in overrides]
    if missing:
        raise ValueError(f"no default prior for {', '.join(missing)}: pass one in overrides")
    priors = {n: overrides.get(n, DEFAULT_PRIORS.get(n)) for n in names}
    return PriorSet(priors, sigma_v=sigma_v, constrained=constrained)
