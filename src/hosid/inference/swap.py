r"""The swap guard: under a second-order shaping filter, the sampler stays on the
estimate's side of the exchange of filter and oscillator.

With the filter at the oscillator's resonance, the filter's pair
:math:`(2\zeta_f\omega_f, \omega_f^2)` and the oscillator's equivalent linear pair
:math:`(c, k)` can trade places: for a linear oscillator the two systems give the same
response spectrum and the same likelihood of the displacement path exactly, and the
equations of the default fit (the generator identities, J2, the force's kurtosis) are of
second order in the force but for one number, the kurtosis: they cannot tell the two
apart, and only the nonlinear terms can.  On a ship-roll-like record under a broad filter
at its resonance (``ship_at_broad-2`` of ``analyses/excitation_study.py``: a1 0.03, n1
0.15, a2 0.35, wf 0.6, zf 0.25) the quasi-likelihood was -4.8 at the swapped solution
(a1 0.21, zf 0.08) and -6.9 at the truth; on records whose estimate was right (a1 0.01 to
0.03) the posterior still spread over the swapped mode, its 95 % points of ``a1`` at
0.21 to 0.26.  The exact path likelihood of the augmented state (Girsanov, evaluated on
the record's jet at the same :math:`S_0\omega_f^4`) was 30 lower at the swap, with no
mode there; evaluated on sampled records it is biased (``n1`` by -2 bound-sd on the
ship-roll-like records and by -57 on the paper oscillator, whose jerk relaxes within a
few samples), so it is not what hosid uses.

The inferred force's trispectrum against the Gaussian one of its own spectrum (J4B,
:mod:`hosid.components.polyspectral`, eqs 62-63) sees the swap from the right side: with
its weights frozen at the truth, its term (its quasi-log-likelihood alone) was -912 at
the swapped solution of ``ship_at_broad-2``, and frozen at the estimates on the truth's
side of three other records it was -0.3 to -1.6 at the truth; frozen at the swapped
solution it does not see the truth (-0.0).  As equations of the fit it is
biased where the filter is as narrow as the resonance (the ship-roll-like oscillator
under a filter at its resonance with :math:`\zeta_f = 0.1`: with J4B among the
equations ``a2`` moved 4-6 bound-sd low in 6 of 10 records), and its term at the truth
there was -0.9 to -17 (4 records).  So it weighs nothing in the posterior and only
bounds it: a draw whose J4B term, with the weights frozen at the estimate, is below
:data:`FLOOR` is outside the support (:func:`swap_guard`), far beyond anything the
truth showed and far above what the swapped mode shows.  Where the estimate itself is on
the swapped side the guard does not see the truth's side, and the posterior keeps both.

Measured on the excitation study's 100 records (independent simulator, the same records
and seeds as before the guard): with the broad filter at the ship's resonance the upper
95 % points of ``a1`` of records 3 and 4 fell from 0.21 and 0.25 to 0.11, and ``a1``'s
bias from +4.32 to +3.32 bound-sd (tolerance 3.63); record 2, whose estimate is the
swapped one, keeps both modes (its point 0.25).  Every other case changed by the
sampler's noise only (the drift's 90 % intervals pooled over the 80 filtered records
0.897, was 0.900).

Why the trispectrum stays out of the equations, measured again with the current
components (Laplace estimates of ``hosid.estimate`` with J4B added to the default
equations; independent simulator, 4000 s, seeds of our own).  Under the broad filter at
the ship's resonance the raw estimator lands on the swapped side in 3 of 16 records
(hosid's simulator: 1 of 16), the filter's damping ratio 0.09-0.11 against 0.25, and
there the default equations prefer the swap (their J 7.7 at the swapped estimate, 28.5
at the truth, on one record).  With J4B's Gaussian part built from bin values (eq 63)
two of three swapped records came back, and under the narrow filter there (``zf`` 0.1,
a half-power half-width of one frequency bin of the record's 102 s blocks) ``zf`` moved
up by 0.03-0.05 and ``a2`` down by 0.016-0.053, up to 3 sd, on three records of three.
With the exact Gaussian part (:mod:`hosid.components.gaussian_reference`, unbiased at
the truth) one swapped record of three came back, and on 10 narrow-filter records ``a2``
still moved by -0.027, -0.059 and -0.014 on three (by less than 0.011 on the others):
the bias is not the reference's.  So it bounds the posterior and chooses the side.

**The side.**  The equations' search may miss the true side altogether, its pilots all
leading to the swapped solution.  The search therefore solves once more from the
:func:`mirror` of the solution it keeps, and :func:`trispectral_side` decides: a solution
is kept in place of another when J4B frozen at it rejects the other while J4B frozen at
the other does not reject it.  Frozen at the truth's side J4B rejects the swap (by -22 to
-15 700 on 10 records where both were found), frozen at the swapped side it sees nothing
(-0.0 to -0.3).  Measured with ``simulations=0`` on 20 broad-filter records of our own
(independent simulator, 4000 s, the estimate with and without the mirror): 5 estimates
were on the swapped side, and 2 of them came to the true side (``zf`` 0.092 to 0.274 and
0.094 to 0.297, ``a1`` 0.170 to 0.028 and 0.177 to 0.021); from the other 3 the mirror
start went back to the swapped solution.  No other estimate of these 20, nor of 16
narrow-filter records, changed.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from ..components.polyspectral import J4
from ..model.model import Model
from .gmm import quasi_likelihood
from .solutions import passes

__all__ = ["FLOOR", "mirror", "swap_guard", "trispectral_side"]

#: The J4B term below which a draw is outside the guard (module docstring): -2 FLOOR is
#: 100 for chi2(2) at the truth, a tail probability of 2e-22.
FLOOR = -50.0


def swap_guard(est) -> Callable[[np.ndarray], np.ndarray] | None:
    """``admissible(theta) -> bool array`` for the estimate ``est``
    (:class:`hosid.inference.estimate.Estimate`) of a model with a second-order shaping
    filter (module docstring); ``None`` for any other model, or where J4B has no
    equations on the record (too few bins or blocks).
    """
    model = est.model
    if not isinstance(model, Model) or not model.has("wf"):
        return None
    try:
        moments = J4(kind="B").prepare(est.state, model, est.theta)
        term = quasi_likelihood([moments], n_params=len(est.theta))
    except ValueError:
        return None

    def admissible(theta: np.ndarray) -> np.ndarray:
        return np.asarray(term(np.asarray(theta, dtype=float))) > FLOOR

    return admissible


def _term(state, model: Model, theta: np.ndarray):
    """J4B's quasi-log-likelihood with its weights frozen at ``theta``, or ``None``."""
    try:
        moments = J4(kind="B").prepare(state, model, theta)
        return quasi_likelihood([moments], n_params=len(theta))
    except ValueError:
        return None


def mirror(state, model: Model, theta: np.ndarray) -> np.ndarray | None:
    r"""``theta`` with the oscillator's equivalent linear pair and the shaping filter's
    traded (module docstring), a start on the other side of the exchange: the oscillator's
    :math:`c = a_1 + n_1\sqrt{8/\pi}\sigma_{\dot x}` (eq 65) and
    :math:`k = a_2 + 3n_2\sigma_x^2` become :math:`2\zeta_f\omega_f` and
    :math:`\omega_f^2` (through :math:`a_1` and :math:`a_2`, the nonlinear coefficients
    kept), the filter gets :math:`\omega_f = \sqrt k`, :math:`\zeta_f = c/2\sqrt k`, and
    :math:`S_0\omega_f^4` is kept.  ``None`` for a model without a second-order filter,
    ``a1`` and ``a2``, or an oscillator with :math:`k \le 0`.
    """
    if not all(model.has(p) for p in ("wf", "zf", "a1", "a2", "S0")):
        return None
    i = {n: model.index(n) for n in ("wf", "zf", "a1", "a2", "S0")}
    sc = state.scales
    c = float(model.equivalent_damping(theta, sc.sigma_v))
    k = theta[i["a2"]]
    if model.has("n2"):
        k += 3.0 * theta[model.index("n2")] * sc.sigma_x**2
    if k <= 0.0 or c <= 0.0:
        return None
    wf, zf = theta[i["wf"]], theta[i["zf"]]
    out = np.array(theta, dtype=float)
    out[i["a1"]] += 2.0 * zf * wf - c
    out[i["a2"]] += wf**2 - k
    out[i["wf"]], out[i["zf"]] = math.sqrt(k), c / (2.0 * math.sqrt(k))
    out[i["S0"]] *= wf**4 / k**2
    return out


def trispectral_side(state, model: Model, found, index: int, df: int) -> int:
    """The solution to keep among ``found`` (``(theta, ql, start)``) in place of
    ``found[index]``: another acceptable one (its own Hansen test passes on ``df``
    degrees of freedom) whose J4B term, frozen there, puts ``found[index]`` below
    :data:`FLOOR` while the kept one's term does not put it there (the smallest own
    :math:`J` of those); else ``index``.  The trispectrum sees the exchange from the
    oscillator's true side only (module docstring), so the side it sees from is kept.
    """
    if not model.has("wf"):
        return index
    theta = found[index][0]
    others = []
    for j, (th, ql, _) in enumerate(found):
        J = float(-2.0 * ql(th))
        if j != index and not np.allclose(th, theta, rtol=0.02) and passes(J, df):
            others.append((J, j))
    own = _term(state, model, theta) if others else None
    if own is None:
        return index
    better = []
    for J, j in others:
        th = found[j][0]
        term = _term(state, model, th)
        if term is not None and float(term(theta)) < FLOOR and float(own(th)) > FLOOR:
            better.append((J, j))
    return min(better)[1] if better else index
