"""Likelihood components: estimating equations from the record's state."""

from .base import Component, Moments
from .bispectral import J3
from .cumulant import ForceKurtosis
from .identities import Identities
from .level import Level
from .polyspectral import J4
from .spectral import J2
from .tail import Tail

__all__ = [
    "J2",
    "J3",
    "J4",
    "Component",
    "ForceKurtosis",
    "Identities",
    "Level",
    "Moments",
    "Tail",
]
