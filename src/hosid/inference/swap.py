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
components (Laplace estimates of ``hosid.estimate`` with J4B, or J4A, added to the
default equations; independent simulator, 4000 s, seeds of our own).  Under the broad
filter at the ship's resonance the raw estimator lands on the swapped side in 3 of 16
records (hosid's simulator: 1 of 16), the filter's damping ratio 0.09-0.11 against 0.25,
and there the default equations prefer the swap (their J 7.7 at the swapped estimate,
28.5 at the truth, on one record).  With J4B among the equations two of three swapped
records came back (``zf`` 0.072 to 0.185, 0.12 to 0.28; J4A: 0.16, 0.27), the third
partly (0.127 to 0.141), and two right ones stayed (within 0.04).  Under the narrow filter
there (``zf`` 0.1, a half-power half-width of one frequency bin of the record's 102 s
blocks) the same addition moved ``zf`` up by 0.03-0.05 and ``a2`` down by 0.016-0.053,
up to 3 sd (J4A alike), on three records of three: the trispectral costs' Gaussian
reference is built from bin values, and a peak one bin wide is where that is suspected
to fail.  J4B's equations corrected by their mean on 8 records simulated at the current
point do neither: one swapped record of three came part of the way (0.12 to 0.15), and a
narrow filter's record still moved (``a2`` by -0.054).  A Gaussian reference exact for
the window's leakage would let the trispectrum join the equations; until then it bounds
them.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from ..components.polyspectral import J4
from ..model.model import Model
from .gmm import quasi_likelihood

__all__ = ["FLOOR", "swap_guard"]

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
