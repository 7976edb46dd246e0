"""Likelihood components: estimating equations from the record's state."""

from .base import Component, Moments
from .identities import Identities
from .spectral import J2

__all__ = ["J2", "Component", "Identities", "Moments"]
