r"""The estimate's search: its starts, their solutions, and the one kept.

Every start (:func:`starts`) is solved by rounds of efficient GMM
(:func:`hosid.inference.solutions.solve_rounds`).  Under a shaping filter the starts
are the pilots of each way the filter and the oscillator may share the resonances
(:func:`hosid.inference.pilot.whitened_pilots`), the refined pilots when none of their
solutions passes its Hansen test.  The solution kept is the one
:func:`hosid.inference.solutions.select_solution` keeps unless the trispectrum puts it
on the wrong side of the exchange of filter and oscillator
(:func:`hosid.inference.swap.trispectral_side`); the search then solves once more from
the kept solution's mirror across that exchange (:func:`hosid.inference.swap.mirror`)
and takes that solution only where the trispectrum sees the kept one from it, never by
its Hansen :math:`J` alone: with the filter below a ship-roll-like oscillator's
resonance (``ship_below`` of ``analyses/excitation_study.py``, 10 records) the mirror's
swapped solution had the smaller own :math:`J` on 3 records, and kept that way it took
one record whole and split the posterior of two.
"""

from __future__ import annotations

import numpy as np

from ..chain_state import ChainState
from ..model.excitation import Spectrum
from ..model.model import Model
from ..model.system import System
from .chain_pilot import chain_pilot
from .gmm import hansen
from .pilot import initial_theta, whitened_pilots
from .pilot import pilot as pilot_estimate
from .solutions import acceptable, select_solution, solve_rounds, solved
from .swap import mirror, trispectral_side

__all__ = ["kept", "search", "starts"]


def search(state, model: Model, components, start, rounds: int, bounds, chain: bool):
    """The solutions ``(theta, ql, start)`` from every start (:func:`starts`; another
    start may do where one fails: a white filter is degenerate) and the equations' degrees
    of freedom; under a shaping filter with no acceptable solution, from the refined
    pilots too.  ``bounds``: the log-scaled parameters and the search's bounds.

    Raises
    ------
    HosidInputError
        The first start's failure, when no start gives a solution.
    """
    logs, lower, upper = bounds
    whitening = Spectrum(model).whitening

    def one(theta0):
        return solve_rounds(state, model, components, theta0, rounds, logs, lower, upper)

    found, failure = solved(starts(state, model, start, whitening, chain), one)
    df = hansen(found[0][1], found[0][0])["df"] if found else 0
    if whitening and start is None and found and not acceptable(found, df):
        more = whitened_pilots(state, model, initial_theta(state, model), refine=True)
        found += solved(more, one)[0]
    if not found:
        raise failure
    return found, df


def kept(state, model: Model, components, found, df: int, rounds: int, bounds):
    """The solution ``(theta, ql, start)`` the estimate keeps among ``found``
    (:func:`hosid.inference.solutions.select_solution`, then
    :func:`hosid.inference.swap.trispectral_side`), or, under a second-order shaping
    filter, the solution from its :func:`hosid.inference.swap.mirror` when the
    trispectrum sees the kept one from there (module docstring).  ``bounds``: the
    log-scaled parameters and the search's bounds.
    """
    index = select_solution([(t, q) for t, q, _ in found], df)
    best = found[trispectral_side(state, model, found, index, df)]
    other = mirror(state, model, best[0])
    if other is None:
        return best
    logs, lower, upper = bounds
    start = np.clip(other, lower, upper)
    mirrored, _ = solved(
        [start], lambda th: solve_rounds(state, model, components, th, rounds, logs, lower, upper)
    )
    pair = [best, *mirrored]
    return pair[trispectral_side(state, model, pair, 0, df)]


def starts(state, model: Model, start, whitening: bool, chain: bool) -> list[np.ndarray]:
    """Where the search starts: ``start`` if given; under a shaping filter a pilot for
    each way the filter and the oscillator may share the resonances; the one-element
    chain's pilot; else the closed-form pilot.
    """
    if start is not None:
        return [np.array(start, dtype=float)]
    if whitening:
        return whitened_pilots(state, model, initial_theta(state, model))
    if chain:
        return [chain_pilot(ChainState.of(state), System.single(model))]
    return [pilot_estimate(state, model)]
