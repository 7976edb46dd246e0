r"""The choice among the solutions of the estimating equations from several starts.

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

from .gmm import HANSEN_P, QuasiLikelihood

__all__ = ["alternatives", "select_solution"]


def select_solution(
    found: Sequence[tuple[np.ndarray, QuasiLikelihood]], p_values: Sequence[float]
) -> int:
    r"""The index of the solution that the weights of the acceptable solutions accept
    best: the smallest :math:`\max_{i \in A}J_i(\hat\theta_j)`, with :math:`J_i =
    -2\ell_i` the quasi-likelihood prepared and weighted at solution :math:`i` and
    :math:`A` the solutions whose own Hansen test passes (``p_values`` at least
    :data:`hosid.inference.gmm.HANSEN_P`; none: the smallest own :math:`J` alone,
    which then picks itself).

    A solution's own :math:`J_j(\hat\theta_j)` does not compare across starts: the
    weight is the inverse covariance of the equations at that solution, and where they
    are noisy (a shaping filter whose whitening amplifies the record's top band) it is
    small, so a solution the equations barely see gets a small :math:`J` of its own.
    Measured on a white record of the ship-roll-like oscillator fitted with
    ``narrowband_excitation`` (4000 s): the start with the filter below the resonance
    ended at :math:`\omega_f = 9.1` rad/s (15 resonance frequencies, above the J2 band)
    with :math:`J = 0.9` on 7 df and a Laplace sd of :math:`a_1` of 0.75 (the white
    bound: 0.015); the three others ended above 18 rad/s with :math:`J` 12-14 and sd
    0.015-0.017, and their weights gave the first one :math:`J` of 451 to 960 000.  A
    solution its own test rejects judges nothing: on a white record of the paper
    oscillator two starts ended with a filter of damping ratio 0.01 above the Nyquist
    frequency, :math:`J` 469 and 786 of their own, and weights that gave the two
    acceptable solutions (:math:`J` 12-14) :math:`J` above :math:`10^7`.
    """
    if len(found) == 1:
        return 0
    own = [float(-2.0 * ql(theta)) for theta, ql in found]
    judges = [i for i, p in enumerate(p_values) if p >= HANSEN_P] or [int(np.argmin(own))]
    worst = [max(float(-2.0 * found[i][1](theta)) for i in judges) for theta, _ in found]
    return int(np.argmin(worst))


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
