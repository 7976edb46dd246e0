"""The settings of a fit, with their defaults stated once.

:class:`FitOptions` is what :func:`hosid.inference.fit.fit` reads besides the record and
what it describes (a :class:`~hosid.model.model.Model` or a
:class:`~hosid.model.system.System`); the command line, the batch engine and the monitor
pass their settings as its fields, by keyword (``fit(record, model="paper", seed=1)``) or
as an object (``fit(record, system, FitOptions(seed=1))``, keywords overriding it).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from .sampler import MAX_STEPS

__all__ = ["FitOptions"]


@dataclass(frozen=True)
class FitOptions:
    """Every setting of a fit and its default.

    Attributes
    ----------
    cost : {None, "J2", "J4A", "J4B"}
        ``None``: the default, most efficient components; otherwise the paper's (a single
        oscillator's only).
    components : sequence of components, optional
        Any combination instead of ``cost``'s (:mod:`hosid.components`).
    constrained : bool
        Keep the equivalent damping of eq (65) positive on every draw (per element).
    priors : PriorSet, optional
        Default: every parameter's default prior.
    block_seconds, omega_max : float, optional
        Block length and upper edge of the J2 band; default derived from the record.
    form : {"scaled", "printed"}
        Weighting of the spectral components.
    domain : {"principal", "reduced", "full"}
        Trispectral domain of J4.
    n_walkers, n_steps, max_steps : int
        Ensemble size (default ``None``: 32, or 2 p + 2 for p > 15 parameters); a fixed
        number of steps, or the stop rule's limit
        (:data:`~hosid.inference.sampler.MAX_STEPS`).
    seed : int or Generator, optional
        The only source of randomness (walkers, moves, prior draws).
    progress : bool or Stages
        One labelled progress bar (a command passes its :class:`hosid.progress.Stages`).
    backend : path, optional
        HDF5 chain to store or resume (:class:`hosid.inference.chains.ChainFile`).
    truths : mapping, optional
        True values (simulated records), kept for plots.
    with_map : bool
        Evaluate the quasi-likelihood on an ``(a1, n1)`` grid (single oscillator).
    start : {"auto", "estimate", "twin"}
        Where the walkers start (:func:`hosid.inference.fit.fit`).
    unit : str
        The unit of the record's displacement (labels of the report).
    force : bool
        Fit a record that fails a check anyway.
    checks : sequence of Check, optional
        The record's checks when the caller already made them.
    settle : bool
        Settle the excitation against the record (a band's edge added, a shaping filter
        the record does not show dropped: :func:`hosid.inference.estimate.estimate`);
        false fits the model as given.
    """

    cost: str | None = None
    components: Sequence[Any] | None = None
    constrained: bool = True
    priors: Any = None
    block_seconds: float | None = None
    omega_max: float | None = None
    form: str = "scaled"
    domain: str = "principal"
    n_walkers: int | None = None
    n_steps: int | None = None
    max_steps: int = MAX_STEPS
    seed: int | np.random.Generator | None = None
    progress: Any = True
    backend: str | Path | None = None
    truths: Mapping[str, float] | None = None
    with_map: bool = True
    start: str = "auto"
    unit: str = "m"
    force: bool = False
    checks: Sequence[Any] | None = None
    settle: bool = True

    @classmethod
    def of(cls, options: FitOptions | None = None, **changes) -> FitOptions:
        """``options`` (default: the defaults) with ``changes``.

        Raises
        ------
        TypeError
            For a name that is not a setting (as for an unknown keyword argument).
        """
        names = {f.name for f in dataclasses.fields(cls)}
        unknown = [k for k in changes if k not in names]
        if unknown:
            raise TypeError(f"fit() got an unexpected keyword argument {unknown[0]!r}")
        return dataclasses.replace(options or cls(), **changes)
