"""The single oscillator's default components computed as the one-element chain's.

A single oscillator under a white force is the system of one element between the ground
and its dof (:meth:`hosid.model.system.System.single`), and its default components
(:func:`hosid.inference.estimate.components_for`: identities, J2's in-band level, the
level above the band, the force's kurtosis) are the one-element case of a system's
(:mod:`hosid.components.chain_identities`, :mod:`hosid.components.chain_spectral`,
:mod:`hosid.components.chain_cumulant`), to the last digit.  :func:`one_element` hands the
single oscillator's default fit to them, so one code computes a single oscillator's
equations and a chain's; :class:`OneElement` sees the single oscillator's state as the
one-channel :class:`~hosid.chain_state.ChainState` it is.  The single oscillator's own
components keep what only it has: shaped and impulsive forces, measurement noise, the
paper's J2 drift equations and J4.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..chain_state import ChainState
from ..model.excitation import Spectrum
from ..model.model import Model
from ..model.system import System
from ..state import RecordState
from .base import Moments

__all__ = ["OneElement", "one_element"]


@dataclass(frozen=True)
class OneElement:
    """A system's component on a single oscillator's state and model."""

    inner: Any

    @property
    def name(self) -> str:
        """The inner component's name."""
        return self.inner.name

    def prepare(self, state: RecordState, model: Model, pilot: np.ndarray) -> Moments:
        """The inner component's equations on the one-element chain."""
        return self.inner.prepare(ChainState.of(state), System.single(model), pilot)


def one_element(state: RecordState, model: Model, components: Sequence) -> list | None:
    """The one-element chain's components in place of the single oscillator's default set,
    or ``None`` where the single oscillator's own are needed (a force that is not white,
    impulses, a denoised or smooth state, other components, or no level above the band,
    where J2 keeps its drift equations).
    """
    from ..inference.estimate import components_for
    from .chain_cumulant import ChainKurtosis
    from .chain_identities import ChainIdentities
    from .chain_spectral import ChainJ2, ChainLevel
    from .level import Level

    others = [t.name for t in model.terms if t.kind != "drift" and t.name != "excitation_level"]
    if others or not Spectrum(model).white or state.noise is not None or state.j is not None:
        return None
    if list(components) != components_for() or Level().skipped(state, model) is not None:
        return None
    chain = [ChainIdentities(), ChainJ2(cross=False), ChainLevel(), ChainKurtosis()]
    return [OneElement(c) for c in chain]
