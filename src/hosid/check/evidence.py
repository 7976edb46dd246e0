r"""Evidence for one candidate effect from the fit itself.

For a model :math:`M` and a candidate effect :math:`c` (a term with one parameter
:math:`\psi`, null value :math:`\psi_0` when :math:`M` is right), :func:`weigh` fits the
extended model :math:`M + c` with the estimating equations of the default fit
(:func:`hosid.inference.estimate.components_for`; with a corner or measurement noise
the spectral tail, :class:`hosid.components.tail.Tail`) and the efficient-GMM
quasi-likelihood of :mod:`hosid.inference.gmm`, and returns two calibrated numbers:

1. **Wald z**: the estimate of the effect's *regular coordinate* :math:`u` (below)
   over its adjusted (Godambe) standard deviation,
   :math:`z = \hat u/\mathrm{sd}(\hat u)`; with the optimal weight the curvature of the
   quasi-likelihood is the inverse sandwich covariance, so :math:`z` is what the
   calibrated posterior of :func:`hosid.inference.fit.fit` says about :math:`\psi`.
2. **Quasi-likelihood ratio**: the distance-metric statistic
   :math:`D = J(\hat\theta) |_{u=0} - J(\hat\theta)`, the difference of the Hansen
   statistics of the fits with :math:`u = 0` and with :math:`u` free, with one weight
   :math:`W` for both when both fits use the same equations (Newey & West 1987;
   :func:`hosid.inference.gmm.j_difference`): :math:`\chi^2_1` for an interior null,
   :math:`\tfrac12\chi^2_0 + \tfrac12\chi^2_1` when the null lies on the boundary of the
   parameter space.

The equations and their weight are first prepared at ``start`` (the model's estimate)
with the effect at its null.  A drift effect's free fit then re-prepares them at its
estimate (a second round, as :func:`hosid.inference.estimate.estimate` does) and its
null fit is redone with the free fit's equations and weight, so that :math:`D` compares
both fits under the extended model's weight.  That weight is consistent under the null
and efficient under the alternative, where the null's own weight counts the missing
effect's signal as noise of the equations: on 12 ship-roll records with a quadratic
stiffness at 5 Cramer-Rao sd, :math:`(D - 1)/25` rose from 0.44 (the null's weight) to
0.67 and the mean :math:`z` from 3.4 to 4.1, while on 16 clean ship-roll records
:math:`D` kept its :math:`\chi^2_1` mean (0.99).  The noise's free fit keeps the null's
equations and weight (one round; the second was not measured).  The coloured force's free
fit takes three rounds (:attr:`Coordinate.rounds`), each re-preparing the equations and
their weight at its current estimate: the velocity restoration of the identities follows
the corner only between rounds, and the tail's weights are the efficient ones at the
estimate.  Both effects are seen by the spectral tail (:mod:`hosid.components.tail`),
which holds most of the sampled record's information on them (88 % and 92 % of
Whittle's bound at the paper's point, by quadrature); the identities' input power
:math:`\rho(\omega_c)` moves with :math:`1/\omega_c`, a model-based extrapolation
above the Nyquist frequency that the record does not see, and adds little (a rough
estimate at the paper's point, the energy balance known to 2 %: an sd of
:math:`1/\omega_c^2` some 20 times the tail's near 5 sd).  When
Hansen's test of the free fit rejects (:data:`hosid.inference.calibrate.HANSEN_P`) both
numbers are deflated by its dispersion (:func:`hosid.inference.gmm.hansen_test`), as the
posterior is widened.

**The weight.**  By default the equations' covariance is that of the record's own
:math:`B` blocks (:func:`hosid.inference.gmm.quasi_likelihood`): 38 degrees of freedom
for 11 equations in the ship-roll regime's 4000 s record, 96 in the paper's 2000 s.  Its
noise (larger than a Wishart's: the block values of products of the response are far
from Gaussian) makes :math:`D` a scale mixture whose far tail is heavier than
:math:`\chi^2`'s, and a calibrated round (:mod:`hosid.check.selection`) pays for that
tail in power.  With ``covariance`` (:func:`hosid.check.selection.null_covariances`)
the weight is instead the covariance of the null equations pooled over records simulated
from the model (a round of :func:`hosid.check.diagnose.diagnose` uses its R
posterior-predictive replicates: :math:`R(B - 1)` degrees of freedom), as
simulated-moment estimators do; the record and the replicates that calibrate it are
weighed alike.  Under the null this weight is consistent whenever the model's
simulations reproduce the record's block covariance; a record they do not describe
shows in Hansen's test, which deflates both numbers (above).  The coloured force keeps
the record's own weight (its equations move with the corner).

Regular coordinates (:data:`COORDINATES`): a drift coefficient is its own coordinate,
null 0 (two-sided; Coulomb friction :math:`\mu \ge 0` one-sided).  A white force is the
low-pass with :math:`\omega_c = \infty`: the coordinate is :math:`u = 1/\omega_c^2 \ge
0`, regular for the sampled record's spectrum (:math:`L = 1/(1 + u\omega^2)`), in which
the information limit is stated (:func:`hosid.model.information.spectral_bound`).
Measurement noise enters the spectra as :math:`\sigma_\epsilon^2`:
:math:`u = \sigma_\epsilon^2 \ge 0`.
"""

from __future__ import annotations

import math
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..errors import HosidInputError
from ..inference.calibrate import HANSEN_P
from ..inference.estimate import estimate
from ..inference.gmm import (
    BlockCovariance,
    hansen_test,
    j_difference,
)
from ..model.coordinates import COORDINATES, WHITE_CORNER, Coordinate, critical_z, param_sd
from ..model.model import Model, get_term
from ..record import Record
from .effect_fit import Frame, fits
from .equations import null_moments

__all__ = [  # the coordinates are re-exported: the evidence is where users look for them
    "COORDINATES",
    "WHITE_CORNER",
    "Coordinate",
    "Evidence",
    "critical_z",
    "null_moments",
    "screen",
    "weigh",
]


@dataclass
class Evidence:
    """What the fit of ``model + effect`` says about the effect (module docstring).

    ``u``/``u_sd``: the regular coordinate and its adjusted sd; ``z``: their ratio;
    ``D``/``p_value``: the calibrated quasi-likelihood ratio and its p-value, ``log_p``
    its logarithm (exact where ``p_value`` underflows; from ``p_value`` when not given);
    ``estimate``: the extended model's parameters; ``hansen``: its over-identification
    test; ``dispersion``: the calibration's widening (1 when Hansen's test passes).
    """

    effect: str
    coordinate: Coordinate
    u: float
    u_sd: float
    z: float
    D: float
    p_value: float
    reference: str
    estimate: dict[str, float]
    sd: dict[str, float]
    hansen: dict[str, float]
    dispersion: float
    J_null: float
    seconds: float
    weight: str = "the record's own blocks"  #: where the weight's covariance comes from
    log_p: float | None = None

    def __post_init__(self):
        if self.log_p is None:
            self.log_p = math.log(self.p_value) if self.p_value > 0 else -math.inf

    @property
    def param(self) -> str:
        """The effect's parameter."""
        return self.coordinate.param

    def as_dict(self) -> dict[str, Any]:
        """Plain numbers for reports."""
        return {
            "effect": self.effect,
            "param": self.param,
            "coordinate": self.coordinate.label,
            "boundary_null": self.coordinate.boundary,
            "u": self.u,
            "u_sd": self.u_sd,
            "z": self.z,
            "D": self.D,
            "p_value": self.p_value,
            "log_p": self.log_p,
            "reference": self.reference,
            "value": self.estimate[self.param],
            "estimate": self.estimate,
            "sd": self.sd,
            "hansen": self.hansen,
            "dispersion": self.dispersion,
            "J_null": self.J_null,
            "seconds": self.seconds,
            "weight": self.weight,
        }


def weigh(
    record: Record,
    model: Model | str,
    effect: str,
    *,
    start: Mapping[str, float],
    rounds: int = 1,
    states: dict | None = None,
    covariance: BlockCovariance | None = None,
) -> Evidence:
    """Fit ``model + effect`` and weigh the effect (module docstring).

    Parameters
    ----------
    record : Record
    model : Model or str
        The model the effect would be added to.
    effect : str
        A candidate effect not in ``model`` (:data:`COORDINATES`).
    start : mapping
        ``model``'s estimate: the fits start there with the effect at its null.
    rounds : int
        The fewest rounds of (prepare the equations at the current value, solve); the
        coordinate's own (:attr:`Coordinate.rounds`) when more.  The first prepares them
        at ``start`` with the effect at its null, the next at the extended estimate (as
        :func:`hosid.inference.estimate.estimate` does); a drift effect's null fit is
        then redone with the last round's equations and weight (module docstring).
    states : dict, optional
        A cache of record states shared by the candidates of one record.
    covariance : BlockCovariance, optional
        The covariance of the null equations' block values estimated on the model's
        simulated records (:func:`hosid.check.selection.null_covariances`); default: the
        record's own blocks (module docstring).

    Raises
    ------
    HosidInputError
        If the extended model cannot be estimated on the record.
    """
    t0 = time.perf_counter()
    model = Model.from_spec(model)
    states = {} if states is None else states
    effect = get_term(effect).name
    if effect not in COORDINATES:
        raise HosidInputError(f"{effect} is not a candidate effect")
    frame = Frame.of(record, model, effect, states)
    try:
        u, ql, qlu, J0, scale = fits(record, model, frame, start, rounds, states, covariance)
    except ValueError as exc:
        raise HosidInputError(f"{effect}: {exc}") from None
    if not np.all(np.isfinite(u)):
        raise HosidInputError(f"{effect}: the estimating equations have no finite solution")
    coord, i, names = frame.coord, frame.i, frame.names
    t = hansen_test(float(-2.0 * qlu(u)), ql.k - len(names), ql.info)
    J, df, p_hansen = t["J"], t["df"], t["p_value"]
    disp = max(t["dispersion"], 1.0) if df > 0 and p_hansen < HANSEN_P else 1.0
    cov = qlu.laplace(u, scale) * disp
    sd_u = np.sqrt(np.maximum(np.diag(cov), 0.0))
    z = float(u[i] / sd_u[i]) if u[i] != 0.0 and sd_u[i] > 0 else 0.0
    test = j_difference(J0, J, df=coord.df, boundary=coord.boundary and coord.df == 1,
                        dispersion=disp)  # fmt: skip
    sd_theta = dict(zip(names, sd_u.tolist(), strict=True))
    sd_theta[coord.param] = param_sd(coord, float(u[i]), float(sd_u[i]))
    return Evidence(
        effect=effect,
        coordinate=coord,
        u=float(u[i]),
        u_sd=float(sd_u[i]),
        z=z,
        D=test["D"],
        p_value=test["p_value"],
        log_p=test["log_p"],
        reference=test["reference"],
        estimate=frame.ext.params(frame.to_theta(u)),
        sd=sd_theta,
        hansen={"J": J, "df": df, "p_value": p_hansen},
        dispersion=disp,
        J_null=J0,
        seconds=time.perf_counter() - t0,
        **({} if covariance is None else {"weight": covariance.source}),
    )


def screen(
    record: Record,
    model: Model,
    candidates: Sequence[str],
    *,
    start: Mapping[str, float] | None = None,
    covariances: Mapping[str, BlockCovariance] | None = None,
) -> tuple[dict[str, Evidence], dict[str, str]]:
    """:func:`weigh` every candidate against ``model`` (one record, shared states).

    ``start`` is ``model``'s estimate (default: :func:`hosid.inference.estimate.estimate`
    of the record); ``covariances`` the candidates' weights from simulated records
    (:func:`hosid.check.selection.null_covariances`; the record's own otherwise).
    Returns the evidence by effect and the candidates that could not be weighed, with
    why.

    Raises
    ------
    HosidInputError
        If ``model`` itself cannot be estimated (only when ``start`` is not given).
    """
    if start is None:
        start = estimate(record, model, simulations=0).values
    states: dict = {}
    found, failed = {}, {}
    for c in candidates:
        try:
            cov = (covariances or {}).get(c)
            found[c] = weigh(record, model, c, start=start, states=states, covariance=cov)
        except HosidInputError as exc:
            failed[c] = str(exc)
    return found, failed
