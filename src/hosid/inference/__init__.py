"""Inference: estimating equations -> calibrated quasi-likelihood -> emcee posterior."""

from .estimate import COSTS, Estimate, components_for, estimate
from .fit import fit
from .options import FitOptions

__all__ = ["COSTS", "Estimate", "FitOptions", "components_for", "estimate", "fit"]
