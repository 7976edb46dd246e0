r"""Priors as objects: log-density, sampling, support; and the eq-65 constraint.

Each :class:`Prior` knows ``ln_prob`` (vectorized, ``-inf`` outside its support),
``rescale`` (inverse CDF from the unit interval) and ``sample`` (through an explicit
:class:`numpy.random.Generator`).  A :class:`PriorSet` holds one prior per parameter, in
the model's parameter order, and evaluates ``theta`` of shape ``(..., p)``; its
constraints are functions of ``theta`` that must be positive on every draw.

The one constraint every model with damping carries is eq (65): the equivalent linear
damping is positive,

.. math:: a_{1eq} = a_1 + n_1\sqrt{8/\pi}\,\sigma_{\dot x}
    + \mu\sqrt{2/\pi}/\sigma_{\dot x} > 0

(statistical linearization of each damping law for a Gaussian velocity of standard
deviation :math:`\sigma_{\dot x}`; the extracted text misprints :math:`\sqrt{8/\pi}` as
:math:`8/\pi`).  It removes the twin minimum of J2 and J4 at negative damping.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass

import numpy as np
from scipy import special

__all__ = ["LogNormal", "LogUniform", "Normal", "Prior", "PriorSet", "Uniform"]


class Prior:
    """A one-dimensional prior density (base class)."""

    lower: float = -math.inf
    upper: float = math.inf
    #: Whether the parameter is handled in its logarithm (a log-uniform or log-normal
    #: prior): the solvers' and the sampler's coordinates.
    log_scaled = False

    def ln_prob(self, x) -> np.ndarray:  # pragma: no cover - abstract
        """Log density (``-inf`` outside the support)."""
        raise NotImplementedError

    def rescale(self, u) -> np.ndarray:  # pragma: no cover - abstract
        """Map ``u`` in [0, 1] to the parameter (inverse CDF)."""
        raise NotImplementedError

    def sample(self, rng: np.random.Generator, size=None) -> np.ndarray:
        """Draws from the prior with ``rng``."""
        return self.rescale(rng.uniform(size=size))


@dataclass(frozen=True)
class Uniform(Prior):
    """Uniform on ``[lower, upper]``."""

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

    def __str__(self) -> str:
        return f"U({self.lower:.4g}, {self.upper:.4g})"


@dataclass(frozen=True)
class LogUniform(Prior):
    """Density proportional to ``1/x`` on ``[lower, upper]``, ``0 < lower``."""

    lower: float
    upper: float
    log_scaled = True

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

    def __str__(self) -> str:
        return f"logU({self.lower:.4g}, {self.upper:.4g})"


@dataclass(frozen=True)
class Normal(Prior):
    """Normal ``N(mu, sigma^2)``."""

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
        u = np.asarray(u, dtype=float)
        return self.mu + self.sigma * math.sqrt(2) * special.erfinv(2 * u - 1)

    def __str__(self) -> str:
        return f"N({self.mu:.4g}, {self.sigma:.4g}^2)"


@dataclass(frozen=True)
class LogNormal(Prior):
    r""":math:`\ln x \sim N(\ln m, s^2)` truncated to ``[lower, upper]`` (``0 < lower``):
    median ``m`` (untruncated), log-sd ``s``.
    """

    median: float
    sigma: float
    lower: float
    upper: float
    log_scaled = True

    def __post_init__(self):
        if not (self.sigma > 0 and 0 < self.lower < self.median < self.upper):
            raise ValueError(
                "LogNormal prior needs sigma > 0 and 0 < lower < median < upper, got "
                f"{self.median}, {self.sigma}, {self.lower}, {self.upper}"
            )

    def _z(self, x):
        return (np.log(x) - math.log(self.median)) / self.sigma

    @property
    def _mass(self) -> float:  # the normal's probability within the truncation
        lo, hi = self._z(self.lower), self._z(self.upper)
        return float(special.ndtr(hi) - special.ndtr(lo))

    def ln_prob(self, x) -> np.ndarray:
        """Log density."""
        x = np.asarray(x, dtype=float)
        inside = (x >= self.lower) & (x <= self.upper)
        with np.errstate(divide="ignore", invalid="ignore"):
            z = self._z(x)
            lp = -np.log(x * self.sigma * math.sqrt(2 * math.pi) * self._mass) - 0.5 * z**2
        return np.where(inside, lp, -np.inf)

    def rescale(self, u) -> np.ndarray:
        """Inverse CDF."""
        lo = special.ndtr(self._z(self.lower))
        z = special.ndtri(lo + np.asarray(u, dtype=float) * self._mass)
        return np.clip(self.median * np.exp(self.sigma * z), self.lower, self.upper)

    def __str__(self) -> str:
        return f"logN({self.median:.4g}, {self.sigma:.3g}; {self.lower:.4g}-{self.upper:.4g})"


#: A constraint: ``theta (..., p) -> (...)``, admissible where positive.
Constraint = Callable[[np.ndarray], np.ndarray]


class PriorSet(Mapping):
    """One prior per parameter (in order) and named constraints.

    Parameters
    ----------
    priors : mapping name -> Prior
    constraints : mapping name -> callable, optional
        ``theta (..., p) -> (...)``; a draw is admissible where every one is positive.
    """

    def __init__(
        self,
        priors: Mapping[str, Prior],
        constraints: Mapping[str, Constraint] | None = None,
    ):
        self._priors = dict(priors)
        self.constraints = dict(constraints or {})
        # uniform and log-uniform priors (every default) evaluated in one pass per call
        ps = list(self._priors.values())
        self._box = None
        if ps and all(type(p) in (Uniform, LogUniform) for p in ps):
            lo = np.array([p.lower for p in ps], dtype=float)
            hi = np.array([p.upper for p in ps], dtype=float)
            log = np.array([type(p) is LogUniform for p in ps])
            const = -sum(
                math.log(math.log(p.upper / p.lower)) if type(p) is LogUniform
                else math.log(p.upper - p.lower)
                for p in ps
            )  # fmt: skip
            self._box = (lo, hi, log, const)

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

    def admissible(self, theta) -> np.ndarray:
        """Whether every constraint holds (boolean of shape ``theta.shape[:-1]``)."""
        th = np.asarray(theta, dtype=float)
        ok = np.ones(th.shape[:-1], dtype=bool)
        for con in self.constraints.values():
            ok &= np.asarray(con(th)) > 0
        return ok

    def ln_prob(self, theta) -> np.ndarray:
        """Joint log prior, ``-inf`` outside the supports or the constraints."""
        th = np.asarray(theta, dtype=float)
        if th.shape[-1] != len(self):
            raise ValueError(f"theta has {th.shape[-1]} parameters, expected {len(self)}")
        if self._box is not None:
            lo, hi, log, const = self._box
            inside = np.all((th >= lo) & (th <= hi), axis=-1)
            with np.errstate(divide="ignore", invalid="ignore"):
                lp = const - np.sum(np.log(th[..., log]), axis=-1)
            return np.where(inside & self.admissible(th), lp, -np.inf)
        lp = np.zeros(th.shape[:-1])
        for i, p in enumerate(self._priors.values()):
            lp = lp + p.ln_prob(th[..., i])
        return np.where(self.admissible(th), lp, -np.inf)

    def sample(self, rng: np.random.Generator, size: int) -> np.ndarray:
        """``size`` joint draws ``(size, p)``, constraints by rejection.

        Raises
        ------
        ValueError
            If fewer than one draw in a thousand is admissible.
        """
        out = np.empty((0, len(self)))
        tried = 0
        while out.shape[0] < size:
            draw = np.stack([p.sample(rng, size) for p in self._priors.values()], axis=-1)
            out = np.concatenate([out, draw[self.admissible(draw)]])
            tried += size
            if tried > 1000 * size and out.shape[0] < size:
                raise ValueError("the constraints exclude almost all of the prior")
        return out[:size]

    def describe(self) -> dict[str, str]:
        """Each prior and constraint as short text (for reports)."""
        out = {k: str(v) for k, v in self._priors.items()}
        out.update({f"constraint {k}": "> 0" for k in self.constraints})
        return out
