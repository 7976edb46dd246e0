"""The model: terms, parameter layout, priors, simulator and information limit; systems
of several degrees of freedom (:mod:`.system`) and their simulator (:mod:`.chain`).
"""

from .chain import simulate_chain
from .model import ALIASES, Model, get_term
from .priors import LogNormal, LogUniform, Normal, Prior, PriorSet, Uniform
from .simulate import PAPER_PARAMS, simulate, simulate_ensemble
from .system import System
from .system_file import read_system
from .terms import CANDIDATES, TERMS, DriftTerm, Scales, Term

__all__ = [
    "ALIASES",
    "CANDIDATES",
    "PAPER_PARAMS",
    "TERMS",
    "DriftTerm",
    "LogNormal",
    "LogUniform",
    "Model",
    "Normal",
    "Prior",
    "PriorSet",
    "Scales",
    "System",
    "Term",
    "Uniform",
    "get_term",
    "read_system",
    "simulate",
    "simulate_chain",
    "simulate_ensemble",
]
