r"""How a test sees a term's parameter: its regular coordinate :math:`u`, null
:math:`u = 0` (the effect absent, or the force white and Gaussian), and the Wald
threshold of a test at a level.  The evidence of a candidate effect
(:mod:`hosid.check.evidence`) and the white limit of an excitation term asked for
(:mod:`hosid.inference.settle`) both test there.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import stats

__all__ = ["COORDINATES", "WHITE_CORNER", "Coordinate", "critical_z", "param_sd"]

#: A corner (or an impulse rate) this high is a white (Gaussian) force on any sampled
#: band (``u = 1/wc^2 = 0``, ``u = 1/rate = 0``).
WHITE_CORNER = 1e7


@dataclass(frozen=True)
class Coordinate:
    """How the test sees a candidate's parameter: ``u`` regular at the null ``u = 0``."""

    param: str
    label: str
    boundary: bool  #: the null lies on the boundary of the parameter space (u >= 0)
    #: "identity", "inverse_square" (wc, wf), "inverse" (an impulse rate) or "square"
    kind: str = "identity"
    rounds: int = 2  #: fewest rounds of :func:`weigh` (module docstring)
    #: degrees of freedom of the quasi-likelihood ratio's reference: 2 for a shaping
    #: filter (its damping ratio, a nuisance the null does not hold, is fitted too:
    #: chi2(2), where the boundary's mixture of chi2(1) named the filter at p < 0.01 on
    #: one clean record of six)
    df: int = 1

    def to_param(self, u):
        """The model's parameter at coordinate ``u``."""
        u = np.asarray(u, dtype=float)
        if self.kind == "inverse_square":
            return 1.0 / np.sqrt(np.maximum(u, WHITE_CORNER**-2.0))
        if self.kind == "inverse":
            return 1.0 / np.maximum(u, 1.0 / WHITE_CORNER)
        if self.kind == "square":
            return np.sqrt(np.maximum(u, 0.0))
        return u

    def to_u(self, value: float) -> float:
        """The coordinate of a parameter value."""
        if self.kind == "inverse_square":
            return 0.0 if not value < WHITE_CORNER else float(value) ** -2.0
        if self.kind == "inverse":
            return 0.0 if not value < WHITE_CORNER else 1.0 / float(value)
        if self.kind == "square":
            return float(value) ** 2
        return float(value)

    def bounds(self, lower: float, upper: float) -> tuple[float, float]:
        """The coordinate's range from the parameter's prior support (the null included)."""
        if self.kind == "inverse_square":
            return 0.0, lower**-2.0
        if self.kind == "inverse":
            return 0.0, 1.0 / lower
        if self.kind == "square":
            return 0.0, upper**2
        return (0.0 if self.boundary else lower), upper


#: The regular coordinate of every candidate effect (module docstring).
COORDINATES: dict[str, Coordinate] = {
    "quadratic_damping": Coordinate("n1", "n1", False),
    "cubic_stiffness": Coordinate("n2", "n2", False),
    "quadratic_stiffness": Coordinate("b2", "b2", False),
    "coulomb_friction": Coordinate("mu", "mu", True),
    "excitation_mean": Coordinate("m", "m", False),
    "coloured_excitation": Coordinate("wc", "1/wc^2", True, "inverse_square", rounds=3),
    # the filter's damping ratio is a nuisance the null does not hold (the calibration of a
    # round gives the test its null distribution)
    "narrowband_excitation": Coordinate("wf", "1/wf^2", True, "inverse_square", df=2),
    # the excess kurtosis of the force is proportional to 1/rate (white: 1/rate = 0)
    "impulsive_excitation": Coordinate("rate", "1/rate", True, "inverse"),
    "measurement_noise": Coordinate("noise_sd", "noise_sd^2", True, "square", rounds=1),
}


def critical_z(level: float, boundary: bool) -> float:
    """The Wald threshold of a test at ``level``: one-sided at a boundary null."""
    return float(stats.norm.isf(level if boundary else level / 2.0))


def param_sd(coord: Coordinate, u: float, sd_u: float) -> float:
    """The parameter's sd by the delta method (infinite at a boundary estimate)."""
    if coord.kind == "identity":
        return sd_u
    if u <= 0.0:
        return math.inf
    if coord.kind == "square":  # d sqrt(u) / du
        return sd_u / (2.0 * math.sqrt(u))
    return sd_u / (2.0 * u**1.5)  # d u^(-1/2) / du
