r"""Pseudo-likelihoods built from the identification costs.

A deterministic cost :math:`J(\theta)` becomes a pseudo-log-likelihood

.. math:: \ell(\theta) = -\frac12 J_M(\theta)
    - \frac{1}{2\tau}\sum_{c\ne M} w_c\,J_c(\theta),

a sum over *components* :math:`c` with weights :math:`w_c`: the moment criterion
:math:`J_M` (a proper :math:`\chi^2_2`, never tempered) and the spectral costs,
which share one temperature :math:`\tau`.  Each named cost is the paper's
protocol (section 7, eq 15) in likelihood form:

=======  =====================================================
cost     components (``form="scaled"``)
=======  =====================================================
``J2``   ``moments`` + ``J2W``  (stiffness; equivalent damping and :math:`S_0`)
``J4A``  ``moments`` + ``J2W`` + ``J4AW``  (adds the a1-n1 split)
``J4B``  ``moments`` + ``J2W`` + ``J4BW``
=======  =====================================================

``form="literal"`` uses the costs as printed (``J2``, ``J4A``, ``J4B``); their scales
are arbitrary, so each is weighted by the inverse of its value at the mode
(:func:`hosid.calibrate.calibrate` sets the weights).

The ``moments`` component is the generalized-method-of-moments form of the
stationary moment identities (see :mod:`hosid.estimators`):

.. math::

    g_1 = \dot x^2 - a_2x^2 - n_2x^4 - x\,h(\dot x),\qquad
    g_2 = 3x^2\dot x^2 - a_2x^4 - n_2x^6 - x^3h(\dot x),\qquad
    J_M = N_b\,\bar g^{\mathsf T}\hat S^{-1}\bar g,

with :math:`h = a_1\dot x + n_1\dot x|\dot x|`, :math:`\bar g` the record means,
and :math:`\hat S` the covariance of the means of :math:`g` over :math:`N_b`
non-overlapping batches (the spectral blocks), evaluated at the moment estimate.
:math:`J_M` is asymptotically :math:`\chi^2_2` at the truth.

The well-scaled spectral components are centred U-statistics (see
:mod:`hosid.costs`): their expectation at the truth is 0.  Because the spectral
ordinates are strongly dependent, :math:`\tau = 1` over-counts the information;
:func:`hosid.calibrate.calibrate` chooses :math:`\tau` by parametric bootstrap.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from . import costs as C
from .errors import HosidInputError
from .records import Record
from .spectra import derivatives

__all__ = [
    "COST_CHOICES",
    "FORMS",
    "MomentData",
    "PseudoLikelihood",
    "components_for",
    "moment_data",
]

COST_CHOICES = ("J2", "J4A", "J4B")
FORMS = ("scaled", "literal")

_SCALED = {"J2": "J2W", "J4A": "J4AW", "J4B": "J4BW"}


def components_for(cost: str, form: str = "scaled") -> tuple[str, ...]:
    """Component names of a cost's pseudo-likelihood (module table)."""
    if cost not in COST_CHOICES:
        raise HosidInputError(f"unknown cost {cost!r}: choose from {', '.join(COST_CHOICES)}")
    if form not in FORMS:
        raise HosidInputError(f"unknown cost form {form!r}: use 'scaled' or 'literal'")
    name = (lambda c: _SCALED[c]) if form == "scaled" else (lambda c: c)
    spectral = (name("J2"),) if cost == "J2" else (name("J2"), name(cost))
    return ("moments", *spectral)


@dataclass(frozen=True)
class MomentData:
    r"""Batch means of the products entering the moment identities.

    ``P`` has shape ``(n_batches, 2, 5)``: for identity ``i``, the means of the
    products multiplying ``(1, a1, n1, a2, n2)`` with the signs folded in, so
    that :math:`\bar g_{b,i} = P_{b,i,0} + \sum_j \theta_j P_{b,i,j}`.
    ``W`` is the inverse covariance of the record mean of ``g``.
    """

    P: np.ndarray
    W: np.ndarray = field(repr=False)

    @property
    def n_batches(self) -> int:
        """Number of batches."""
        return self.P.shape[0]

    def g(self, theta) -> np.ndarray:
        """Record mean of the two moment conditions, shape ``(..., 2)``."""
        th = np.asarray(theta, dtype=float)
        Pm = self.P.mean(axis=0)  # (2, 5)
        lam = np.concatenate([np.ones((*th.shape[:-1], 1)), th[..., :4]], axis=-1)
        return lam @ Pm.T

    def cost(self, theta) -> np.ndarray:
        r""":math:`J_M = \bar g^{\mathsf T} S^{-1} \bar g` (S: covariance of the mean)."""
        g = self.g(theta)
        return np.einsum("...i,ij,...j->...", g, self.W, g)


def moment_data(
    record: Record,
    *,
    batch_samples: int,
    velocity: np.ndarray | None = None,
    tail: float = 0.0,
    reference: Sequence[float] | None = None,
) -> MomentData:
    r"""Batch means for the ``moments`` component.

    Parameters
    ----------
    batch_samples : int
        Samples per batch (the spectral block length is a good choice).
    velocity : ndarray, optional
        The record's velocity (spectral derivative by default).
    tail : float
        Velocity variance lost above Nyquist, added to :math:`\dot x^2`.
    reference : (a1, n1, a2, n2), optional
        Where the covariance of the conditions is evaluated (two-step GMM);
        by default the moment estimate with the damping terms dropped.
    """
    x = record.x - np.mean(record.x)
    v = derivatives(x, record.dt)[0] if velocity is None else velocity
    nb = x.size // batch_samples
    if nb < 4:
        raise HosidInputError(
            f"record too short for the moment batches: {x.size} samples give {nb} batches "
            f"of {batch_samples} (need at least 4)"
        )
    n = nb * batch_samples
    x, v = x[:n].reshape(nb, -1), v[:n].reshape(nb, -1)
    v2 = v**2 + tail
    vv = v * np.abs(v)
    x2 = x**2
    rows = [
        [v2, -x * v, -x * vv, -x2, -(x2**2)],
        [3 * x2 * v2, -x2 * x * v, -x2 * x * vv, -(x2**2), -(x2**3)],
    ]
    P = np.stack([np.stack([r.mean(axis=1) for r in row], axis=-1) for row in rows], axis=1)
    if reference is None:
        Pm = P.mean(axis=0)
        # a2, n2 with the damping terms dropped (the plain moment method)
        a2n2 = np.linalg.solve(-Pm[:, 3:5], Pm[:, 0])
        reference = (0.0, 0.0, *a2n2)
    lam = np.concatenate([[1.0], np.asarray(reference, float)[:4]])
    gb = P @ lam  # (nb, 2)
    S = np.cov(gb, rowvar=False) / nb
    return MomentData(P=P, W=np.linalg.inv(S))


class PseudoLikelihood:
    r"""Tempered pseudo-log-likelihood of one cost (module doc).

    Parameters
    ----------
    data : CostData
        Prepared block spectra of the record (:func:`hosid.costs.prepare`).
    moments : MomentData
        Batch moments of the same record (:func:`moment_data`).
    cost : {"J2", "J4A", "J4B"}
    form : {"scaled", "literal"}
    temperature : float or mapping
        :math:`\tau` (> 0) shared by the spectral components, or one per
        spectral component (``{"J2W": tau_2, "J4AW": tau_4}``).
    weights : mapping, optional
        :math:`w_c` per component (default 1).
    stiffness : (a2, n2), optional
        *Cut* the stiffness out of the spectral components: they are evaluated
        with :math:`(a_2, n_2)` held at these values (the moment estimate), so
        that the stiffness is informed by the ``moments`` component alone, as in
        the paper's protocol.  The ``moments`` component is a proper
        :math:`\chi^2_2` criterion and is never tempered.  With the cut, the
        spectral statistics are exact polynomials in the damping, evaluated through
        :class:`hosid.costs.DampingExpansion` (40x faster).
    damping_scale : (s_a1, s_n1)
        Typical magnitudes of a1 and n1 (conditioning of that expansion only).

    Calling the object with ``theta`` of shape ``(..., 5)`` (a1, n1, a2, n2, S0)
    returns :math:`\ell(\theta)` of shape ``theta.shape[:-1]``; non-finite cost
    values give ``-inf``.
    """

    def __init__(
        self,
        data: C.CostData,
        moments: MomentData,
        *,
        cost: str = "J4A",
        form: str = "scaled",
        temperature: float | Mapping[str, float] = 1.0,
        weights: Mapping[str, float] | None = None,
        stiffness: Sequence[float] | None = None,
        damping_scale: Sequence[float] = (10.0, 1.0),
    ):
        self.components = components_for(cost, form)
        spectral = [c for c in self.components if c != "moments"]
        if isinstance(temperature, Mapping):
            taus = {c: float(temperature.get(c, np.nan)) for c in spectral}
        else:
            taus = dict.fromkeys(spectral, float(temperature))
        taus["moments"] = 1.0
        for c, t in taus.items():
            if not (np.isfinite(t) and t > 0):
                raise HosidInputError(f"temperature of {c} must be positive, got {t}")
        self.temperatures = taus
        self.data = data
        self.moments = moments
        self.cost = cost
        self.form = form
        self.temperature = temperature
        self.weights = {c: 1.0 for c in self.components}
        self.weights.update(weights or {})
        self.stiffness = None if stiffness is None else tuple(map(float, stiffness))
        self.damping_scale = tuple(map(float, damping_scale))
        self._expansion = None

    @property
    def expansion(self) -> C.DampingExpansion | None:
        """With the stiffness cut, the exact damping polynomials of the block
        statistics (:class:`hosid.costs.DampingExpansion`), built on first use.
        """
        if self.stiffness is None:
            return None
        if self._expansion is None:
            self._expansion = C.DampingExpansion(self.data, *self.stiffness, self.damping_scale)
        return self._expansion

    def with_(self, **changes) -> PseudoLikelihood:
        """A copy with ``temperature`` and/or ``weights`` changed."""
        kw = {
            "cost": self.cost,
            "form": self.form,
            "temperature": self.temperature,
            "weights": self.weights,
            "stiffness": self.stiffness,
            "damping_scale": self.damping_scale,
        }
        kw.update(changes)
        out = PseudoLikelihood(self.data, self.moments, **kw)
        if (out.stiffness, out.damping_scale) == (self.stiffness, self.damping_scale):
            out._expansion = self._expansion  # same cut: share the polynomials
        return out

    def raw(self, theta, *, spectral_only: bool = False) -> dict[str, np.ndarray]:
        """Untempered, unweighted cost of each component at ``theta`` (without the
        ``moments`` component when ``spectral_only``).
        """
        th = np.asarray(theta, dtype=float)
        ts = th
        if self.stiffness is not None:
            ts = th.copy()
            ts[..., 2], ts[..., 3] = self.stiffness
        ex = self.expansion
        out = {}
        for c in self.components:
            if c == "moments":
                if not spectral_only:
                    out[c] = self.moments.cost(th)
            elif ex is None:
                out[c] = C.COSTS[c](ts, self.data)
            else:
                fast = ex.fast_cost(c, ts)
                out[c] = C.COSTS[c](ts, ex) if fast is None else fast
        return out

    def spectral_cost(self, theta) -> np.ndarray:
        """Weighted sum of the spectral components only (untempered)."""
        return sum(self.weights[c] * j for c, j in self.raw(theta, spectral_only=True).items())

    def pointwise(self, theta) -> dict[str, np.ndarray]:
        r"""Log pseudo-likelihood of each component, :math:`-w_c J_c/(2\tau)`."""
        out = {}
        for c, j in self.raw(theta).items():
            tau = self.temperatures[c]
            out[c] = np.where(np.isfinite(j), -0.5 * self.weights[c] * j / tau, -np.inf)
        return out

    def total_cost(self, theta) -> np.ndarray:
        r"""Weighted cost :math:`\sum_c w_c J_c` (untempered)."""
        return sum(self.weights[c] * j for c, j in self.raw(theta).items())

    def __call__(self, theta) -> np.ndarray:
        """Total log pseudo-likelihood at ``theta``."""
        return sum(self.pointwise(theta).values())
