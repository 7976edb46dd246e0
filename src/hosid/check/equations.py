"""The estimating equations that weigh a candidate effect against a model (the null
fit's, prepared on a record's state at the model's estimate; :mod:`hosid.check.evidence`).
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from ..components.base import Component
from ..components.cumulant import ForceKurtosis
from ..components.tail import TAIL_PARAMS, Tail
from ..inference.estimate import components_for, prepare_state
from ..model.coordinates import COORDINATES, Coordinate
from ..model.excitation import Spectrum
from ..model.model import Model
from ..record import Record
from ..state import RecordState

__all__ = ["components_for_test", "null_moments", "null_theta", "record_state"]


def components_for_test(model: Model, effect: str) -> list[Component]:
    """The components that weigh ``effect`` against ``model``: those of the default fit
    (:func:`hosid.inference.estimate.components_for`), with the spectral tail
    (:class:`hosid.components.tail.Tail`) when the extended model has a corner or
    measurement noise, as the default fit of that model has.
    """
    comps = components_for()
    ext = model.extended(effect)
    if any(ext.has(p) for p in TAIL_PARAMS):
        comps.append(Tail())
    has_kurtosis = any(isinstance(c, ForceKurtosis) for c in comps)
    if (Spectrum(ext).whitening or ext.has("rate")) and not has_kurtosis:  # as the fit has
        comps.append(ForceKurtosis())
    return comps


def record_state(record, model, states) -> RecordState:
    """The record's state for ``model``, shared through the cache ``states``."""
    key = (
        not (model.has("b2") or model.has("m")),
        model.has("noise_sd"),
        Spectrum(model).whitening,
    )
    if states is None:
        return prepare_state(record, model)
    if key not in states:
        states[key] = prepare_state(record, model)
    return states[key]


def null_moments(
    record: Record, model: Model, effect: str, start: Mapping[str, float], states=None
) -> list:
    """The equations that weigh ``effect`` against ``model`` (:func:`components_for_test`),
    prepared on ``record`` at ``start`` with the effect at its null: the first
    preparation of :func:`weigh`.
    """
    ext = model.extended(effect)
    theta = null_theta(ext, COORDINATES[effect], start)
    state = record_state(record, ext, states)
    return [c.prepare(state, ext, theta) for c in components_for_test(model, effect)]


def null_theta(ext: Model, coord: Coordinate, start: Mapping[str, float]) -> np.ndarray:
    """``start`` in the extended model's parameters, the effect at its null."""
    null_value = float(coord.to_param(0.0))
    return np.array([start.get(n, null_value) if n != coord.param else null_value
                     for n in ext.param_names])  # fmt: skip
