r"""The excitation settled against the record: a shaping filter asked for is kept only
when the record rejects the white force it nests.

``narrowband_excitation`` holds white noise at the boundary of its parameter space,
:math:`u = 1/\omega_f^2 = 0` (:data:`hosid.model.coordinates.COORDINATES`), where its
damping ratio :math:`\zeta_f` is not identified.  On a white record its fit wanders near
that boundary (the filter's peak at or above the Nyquist frequency), where the augmented
state's identities see the record's top band through the jerk and the filter's spread
enters the drift's: on 10 white records of each system the posterior means of the drift
coefficients had 0.26-0.65 of the white fit's efficiency (``analyses/excitation_study.py``).
:func:`white_limit` tests that boundary with the term's own quasi-likelihood and weight
(the distance-metric statistic of :func:`hosid.inference.gmm.j_difference`),

.. math:: D = \min_{u = 0} J(\theta) - \min J(\theta),

against :math:`\chi^2_2` (the damping ratio is a nuisance the null does not hold, as in
:mod:`hosid.check.evidence`).  When :math:`p \ge` :data:`WHITE_P` the white model is
estimated instead (:func:`hosid.inference.estimate.estimate`), with its own, more
efficient, equations; the estimate's notes say which, with :math:`D` and :math:`p`.

:data:`WHITE_P` is small because the two errors cost differently, and because
:math:`D` has a heavier tail than :math:`\chi^2_2` (its weight is estimated from the
record's blocks, as :mod:`hosid.check.evidence` measured): a filter kept on a white
record costs efficiency, a filter dropped where it shows costs bias, and where the
study's filters show they show by far.  Measured (independent simulator): on 44 white
records (24 of the paper oscillator, 20 of the ship-roll-like one) the largest :math:`D`
was 17.8 (:math:`p = 1.4\cdot 10^{-4}`; at :math:`10^{-3}` that record kept a filter at
110 rad/s and its :math:`a_1` posterior mean moved from 0.67 to 1.19); under the
filters of the excitation study (peaks below, at and above the resonance, 3 records a
case, 21 in all) the smallest was 185.
"""

from __future__ import annotations

import numpy as np

from ..model.coordinates import COORDINATES
from ..model.model import Model
from .gmm import QuasiLikelihood, Transformed, j_difference, solve

__all__ = ["SETTLED", "WHITE_P", "settled_term", "white_limit"]

#: The level below which the record rejects the white force (module docstring).
WHITE_P = 1e-6
#: The excitation terms settled against the record (module docstring).
SETTLED = ("narrowband_excitation",)


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
    ``theta`` (module docstring): ``effect``, ``D``, ``p_value``, ``reference`` and
    ``df``.

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
    return {"effect": effect, **test}
