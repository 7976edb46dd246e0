"""The model: terms, parameter layout, priors, simulator and information limit."""

from .model import ALIASES, Model, get_term
from .priors import LogUniform, Normal, Prior, PriorSet, Uniform
from .simulate import PAPER_PARAMS, simulate, simulate_ensemble
from .terms import CANDIDATES, TERMS, DriftTerm, Scales, Term

__all__ = [
    "ALIASES",
    "CANDIDATES",
    "PAPER_PARAMS",
    "TERMS",
    "DriftTerm",
    "LogUniform",
    "Model",
    "Normal",
    "Prior",
    "PriorSet",
    "Scales",
    "Term",
    "Uniform",
    "get_term",
    "simulate",
    "simulate_ensemble",
]
