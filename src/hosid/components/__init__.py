"""Likelihood components: estimating equations from the record's state."""

from .base import Component, Moments
from .bispectral import J3
from .identities import Identities
from .polyspectral import J4
from .spectral import J2
from .tail import Tail

__all__ = ["J2", "J3", "J4", "Component", "Identities", "Moments", "Tail"]
