"""Inference: estimating equations -> calibrated quasi-likelihood -> emcee posterior."""

from .estimate import COSTS, Estimate, components_for, estimate
from .fit import fit

__all__ = ["COSTS", "Estimate", "components_for", "estimate", "fit"]
