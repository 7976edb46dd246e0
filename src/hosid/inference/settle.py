r"""The excitation settled against the record: a shaping filter or impulses asked for
are kept only when the record rejects the white Gaussian force they nest.

``narrowband_excitation`` holds white noise at the boundary of its parameter space,
:math:`u = 1/\omega_f^2 = 0` (:data:`hosid.model.coordinates.COORDINATES`), where its
damping ratio :math:`\zeta_f` is not identified; ``impulsive_excitation`` holds white
Gaussian noise at :math:`u = 1/r = 0`.  On a white record their fits wander near that
boundary, and with their own equations (the augmented state's identities, which see the
record's top band through the jerk; J2 whole instead of its level beside the level
component) the drift is less well determined: on 10 white records of each system the
posterior means of the drift coefficients had 0.26-0.65 of the white fit's efficiency
with a filter (``analyses/excitation_study.py``) and, for the ship-roll-like oscillator,
0.55-0.67 of it for a1 and n1 with impulses (``analyses/impulse_study.py``).
:func:`white_limit` tests that boundary with the term's own quasi-likelihood and weight
(the distance-metric statistic of :func:`hosid.inference.gmm.j_difference`),

.. math:: D = \min_{u = 0} J(\theta) - \min J(\theta),

against :math:`\chi^2_2` for a filter (its damping ratio is a nuisance the null does not
hold, as in :mod:`hosid.check.evidence`) and :math:`\tfrac12\chi^2_0 + \tfrac12\chi^2_1`
for impulses.  When :math:`p` is at least the term's level (:data:`SETTLED`) the white
model is estimated instead (:func:`hosid.inference.estimate.estimate`), with its own,
more efficient, equations; the estimate's notes say which, with :math:`D` and :math:`p`.

The levels are small because the two errors cost differently (a term kept on a white
record costs efficiency, a term dropped where it shows costs bias) and because the
filter's :math:`D` has a heavier tail than :math:`\chi^2_2` (its weight is estimated from
the record's blocks, as :mod:`hosid.check.evidence` measured).  Measured (independent
simulator, estimates): with a filter, on 44 white records (24 of the paper oscillator,
20 of the ship-roll-like one) the largest :math:`D` was 17.8 (:math:`p = 1.4\cdot
10^{-4}`; kept at :math:`10^{-3}`, that record's filter sat at 110 rad/s and moved its
:math:`a_1` posterior mean from 0.67 to 1.19), while under the excitation study's
filters (peaks below, at and above the resonance, 3 records a case, 21 in all) the
smallest was 185: level :math:`10^{-6}`.  With impulses the reference holds better: on
12 white records (6 a system) the largest :math:`D` was 1.5 (:math:`p = 0.11`); under
impulses at 0.5 a second :math:`D` was 398-552 on 3 paper records and 6.6-100 on 6 of the
ship-roll-like oscillator, whose period is 10 s (two of them below 23): level
:math:`10^{-3}`.
"""

from __future__ import annotations

import numpy as np

from ..model.coordinates import COORDINATES
from ..model.model import Model
from .gmm import QuasiLikelihood, Transformed, j_difference, solve

__all__ = ["SETTLED", "settled_note", "settled_term", "white_limit"]

#: The excitation terms settled against the record, each with the level below which the
#: record rejects the white Gaussian force it nests (module docstring).
SETTLED = {"narrowband_excitation": 1e-6, "impulsive_excitation": 1e-3}


def settled_term(model: Model) -> str | None:
    """The term of ``model`` that :func:`white_limit` tests, if any."""
    return next((n for n in model.names if n in SETTLED), None)


def white_limit(
    model: Model,
    ql: QuasiLikelihood,
    theta: np.ndarray,
    *,
    log_params: list[int],
    scale: np.ndarray,
) -> dict:
    r"""The test of the white force nested in ``model``'s settled term at its estimate
    ``theta`` (module docstring): ``effect``, ``D``, ``p_value``, ``reference``, ``df``
    and ``level`` (:data:`SETTLED`: the white force is rejected when ``p_value`` is
    below it).

    ``log_params`` and ``scale`` are the solver's (:func:`hosid.inference.gmm.solve`).
    """
    effect = settled_term(model)
    if effect is None:
        raise ValueError(f"the model has no term {' or '.join(SETTLED)}")
    coord = COORDINATES[effect]
    own = {model.index(p) for p in next(t for t in model.terms if t.name == effect).params}
    free = [k for k in range(theta.size) if k not in own]
    null = np.asarray(theta, dtype=float).copy()
    null[model.index(coord.param)] = coord.to_param(0.0)

    def fixed(v):
        v = np.asarray(v, dtype=float)
        out = np.broadcast_to(null, (*v.shape[:-1], null.size)).copy()
        out[..., free] = v
        return out

    q0 = Transformed.of(ql, fixed)
    v = solve(
        q0, null[free], log_params=[free.index(k) for k in log_params if k in free],
        scale=0.1 * scale[free],
    )  # fmt: skip
    J0, J = float(-2.0 * q0(v)), float(-2.0 * ql(theta))
    test = j_difference(J0, J, df=coord.df, boundary=coord.boundary and coord.df == 1)
    return {"effect": effect, **test, "level": SETTLED[effect]}


def settled_note(test: dict, *, kept: bool) -> str:
    """What :mod:`hosid.inference.settle` found, in a sentence."""
    found = f"D = {test['D']:.3g} on {test['reference']}, p = {test['p_value']:.2g}"
    if kept:
        return f"{test['effect']}: the record rejects a white force ({found})"
    return (
        f"{test['effect']} asked for, but the record does not reject a white force ({found} "
        f">= {test['level']:g}): the white model is fitted (hosid.inference.settle)"
    )
