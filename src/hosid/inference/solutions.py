r"""The solutions of the estimating equations: the search, and the choice among starts.

:func:`solve_rounds` solves from one start within the search's :func:`bounds`, in
rounds of (prepare the equations at the current vector, solve), at each parameter's
:func:`typical_scale`; :func:`capped` bounds the Laplace covariance of the result.

A model whose force goes through a shaping filter is solved from several pilots
(:func:`hosid.inference.pilot.whitened_pilots`: the filter and the oscillator may swap).
Each start ends with its own solution and its own quasi-likelihood, prepared and weighted
there (:mod:`hosid.inference.gmm`); :func:`select_solution` keeps one, and
:func:`alternatives` names the others the kept one's weight cannot rule out (the sampler
seeds walkers at them).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from scipy import stats

from ..errors import HosidInputError
from ..model.system import System
from .gmm import HANSEN_P, QuasiLikelihood, quasi_likelihood, solve

__all__ = [
    "acceptable",
    "alternatives",
    "bounds",
    "capped",
    "select_solution",
    "solve_rounds",
    "solved",
    "typical_scale",
]


def solved(starts, solve_one) -> tuple[list, HosidInputError | None]:
    """``(theta, ql, start)`` of every start that ``solve_one(start) -> (theta, ql)``
    solves, and the first input error of those that fail.
    """
    failure, found = None, []
    for theta0 in starts:
        try:
            theta, ql = solve_one(theta0)
        except HosidInputError as exc:
            failure = failure or exc
            continue
        found.append((theta, ql, theta0))
    return found, failure


def acceptable(found, df: int) -> bool:
    """Whether any solution ``(theta, ql, start)`` passes its own Hansen test on ``df``
    degrees of freedom (p at least :data:`hosid.inference.gmm.HANSEN_P`).
    """
    return any(passes(float(-2.0 * ql(th)), df) for th, ql, _ in found)


def passes(J: float, df: int) -> bool:
    """Whether Hansen's :math:`J` on ``df`` degrees of freedom has p of at least
    :data:`hosid.inference.gmm.HANSEN_P`.
    """
    return bool(stats.chi2.sf(J, df) >= HANSEN_P)


def select_solution(found: Sequence[tuple[np.ndarray, QuasiLikelihood]], df: int) -> int:
    r"""The index of the solution kept among the starts': the smallest own :math:`J`
    among the solutions that no acceptable solution's weight rejects.

    :math:`J_i(\theta) = -2\ell_i(\theta)` is the quasi-likelihood prepared and weighted
    at solution :math:`i`; the acceptable solutions are those whose own test passes
    (:math:`J_i(\hat\theta_i)` on ``df`` degrees of freedom, p at least
    :data:`hosid.inference.gmm.HANSEN_P`), and an acceptable weight rejects solution
    :math:`j` when :math:`J_i(\hat\theta_j)` fails the same test.  When every solution
    is rejected by another, or none is acceptable, the smallest own :math:`J` of all.

    A solution's own :math:`J` alone does not compare across starts: the weight is the
    inverse covariance of the equations at that solution, and where they are noisy (a
    shaping filter whose whitening amplifies the record's top band) it is small, so a
    solution the equations barely see gets a small :math:`J` of its own.  Measured on a
    white record of the ship-roll-like oscillator fitted with ``narrowband_excitation``
    (4000 s): the start with the filter below the resonance ended at :math:`\omega_f =
    9.1` rad/s (15 resonance frequencies, above the J2 band) with :math:`J = 0.9` on 7 df
    and a Laplace sd of :math:`a_1` of 0.75 (the white bound: 0.015); the three others
    ended above 18 rad/s with :math:`J` 12-14 and sd 0.015-0.017, and their weights gave
    the first :math:`J` of 451 to 960 000.  Nor does the largest :math:`J` over the
    weights: with the filter below the ship's resonance the true solution (:math:`J`
    4.5) and the swapped one (7.2) rejected each other (21 and 68), and the swapped one's
    weight was the harsher.  A solution its own test rejects judges nothing: on a white
    record of the paper oscillator two starts ended with a filter of damping ratio 0.01
    above the Nyquist frequency, :math:`J` 469 and 786 of their own, and weights that
    gave the acceptable solutions :math:`J` above :math:`10^7`.
    """
    own = np.array([float(-2.0 * ql(theta)) for theta, ql in found])
    if len(found) == 1 or df <= 0:
        return int(np.argmin(own))

    judges = [i for i in range(len(found)) if passes(own[i], df)]
    kept = [
        j
        for j, (theta, _) in enumerate(found)
        if all(passes(float(-2.0 * found[i][1](theta)), df) for i in judges if i != j)
    ]
    pool = kept or range(len(found))
    return min(pool, key=lambda j: own[j])


def alternatives(ql, theta, solutions, cov, J_best, gap: float = 9.21) -> list[np.ndarray]:
    r"""The solutions more than 3 sd (:math:`\chi^2` of the Laplace covariance) from
    ``theta`` whose quasi-likelihood under the best solution's weight is within ``gap``
    (the 99 % point of :math:`\chi^2_2`) of its minimum, distinct among themselves.
    """
    out: list[np.ndarray] = []
    prec = np.linalg.pinv(cov)
    for th in solutions:
        d = th - theta
        far = float(d @ prec @ d) > 9.0 * th.size
        if far and float(-2.0 * ql(th)) - J_best < gap:
            if all(float((th - o) @ prec @ (th - o)) > 9.0 * th.size for o in out):
                out.append(th)
    return out


def typical_scale(model, state, theta: np.ndarray) -> np.ndarray:
    """A typical size of each parameter (finite differences, solver scaling)."""
    if isinstance(model, System):
        from ..components.chain_features import system_scales

        priors = model.default_priors(system_scales(state, model), constrained=False)
    else:
        priors = model.default_priors(state.scales, constrained=False)
    width = np.array([priors[n].upper - priors[n].lower for n in model.param_names])
    return np.maximum(np.abs(theta), 1e-3 * np.where(np.isfinite(width), width, 1.0))


def bounds(model, support, default) -> tuple[np.ndarray, np.ndarray]:
    """The lower and upper ends of the search: ``support``'s when it names ``model``'s
    parameters, else those of ``default()`` (the default priors).
    """
    if support is None or list(support.names) != list(model.param_names):
        support = default()
    lower = np.array([support[n].lower for n in model.param_names], dtype=float)
    upper = np.array([support[n].upper for n in model.param_names], dtype=float)
    return lower, upper


def solve_rounds(state, model, components, theta, rounds, logs, lower, upper):
    """``rounds`` of (prepare the equations at ``theta``, solve): the estimate and its
    quasi-likelihood.
    """
    for _ in range(rounds):
        try:
            moments = [c.prepare(state, model, theta) for c in components]
            ql = quasi_likelihood(moments, n_params=len(theta))
        except ValueError as exc:
            raise HosidInputError(str(exc)) from None
        scale = typical_scale(model, state, theta)
        new = solve(ql, theta, log_params=logs, scale=0.1 * scale, lower=lower, upper=upper)
        if not np.all(np.isfinite(new)):
            raise HosidInputError("the estimating equations have no finite solution")
        theta = new
    return theta, ql


def capped(cov: np.ndarray, width: np.ndarray) -> np.ndarray:
    """``cov`` with no parameter's sd above a quarter of its support's ``width``: one the
    equations barely see (e.g. at a bound of its support) gets no more spread than that.
    """
    sd = np.sqrt(np.maximum(np.diag(cov), 1e-300))
    cap = np.where(np.isfinite(width), 0.25 * width, np.inf)
    return cov * np.outer(*(2 * [np.minimum(1.0, cap / sd)]))
