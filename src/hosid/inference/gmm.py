r"""The calibrated quasi-likelihood of stacked estimating equations (efficient GMM).

The components' equations are stacked, :math:`\bar m(\theta) \in \mathbb R^k`, and their
per-block influences :math:`u_b` (delete-one-block jackknife pseudo-values, which
equal the block values for plain block means) give the covariance of the block mean,
:math:`\hat\Sigma/B` with :math:`\hat\Sigma = \frac{1}{B-1}\sum_b u_bu_b^{\mathsf T}`.
The quasi-log-likelihood is

.. math:: \ell(\theta) = -\frac{B}{2}\,\bar m(\theta)^{\mathsf T} W\,\bar m(\theta),
    \qquad W = c\,\hat\Sigma^{-1}.

Near its mode :math:`\hat\theta` the curvature of :math:`\ell` is :math:`B\,G^{\mathsf T}WG`
(:math:`G = \partial\bar m/\partial\theta`), whose inverse is the sandwich (Godambe)
covariance :math:`V_0 = (G^{\mathsf T}\Sigma^{-1}G)^{-1}/B` of the estimator when
:math:`\hat\Sigma = \Sigma` and :math:`c = 1`: with the optimal weight the curvature
adjustment of a composite likelihood (Chandler & Bate 2007) is built in, and the
quasi-posterior :math:`\propto\pi(\theta)e^{\ell(\theta)}` is calibrated to first order
(Chernozhukov & Hong 2003).

**The factor** :math:`c = (\nu-k-1)/\nu` (:func:`weight_factor`), with :math:`\nu = B-1`
the degrees of freedom of :math:`\hat\Sigma`, makes :math:`W` an unbiased estimate of
:math:`\Sigma^{-1}` (Wishart).  It is conservative when the equations are many for the
blocks.  With :math:`q = k - p` over-identifying equations and
:math:`\hat\Sigma \sim W_k(\Sigma/\nu, \nu)`, the feasible efficient estimator's covariance
is :math:`V_0(\nu-1)/(\nu-q-1)` (the weight's noise costs efficiency, as for feasible
GLS), while :math:`(G^{\mathsf T}\hat\Sigma^{-1}G)^{-1}` has mean :math:`(\nu-q)/\nu` of
its target, so the quasi-posterior's covariance is on average
:math:`(\nu-q)(\nu-q-1)/(c\,\nu(\nu-1))` times the estimator's (the Gaussian oracle of
``tests/test_gmm.py``): 1.36 for a three-dof chain (:math:`k = 28`, :math:`p = 15`,
:math:`B = 48`), 1.20 for a single oscillator's 600 s record (:math:`k = 7`, :math:`p = 5`,
:math:`B = 29`), 1.05 for its 2000 s.  The factor that removes this margin,
:math:`c = (\nu-q)(\nu-q-1)/(\nu(\nu-1))`, was tried: on 20 records of the three-dof
chain the element coefficients' Laplace intervals then covered 0.91 / 0.54 (90 % / 50 %;
0.955 / 0.59 with this :math:`c`), but the single oscillator's 500 s records (20 of the
efficiency study's ``short`` regime) fell to 0.84 at 90 % (0.90 with this :math:`c`):
there the margin pays for something the Gaussian oracle leaves out on a short record (not
traced), and the factor stays.
Over-identification (:math:`k > p`) gives Hansen's test: :math:`J/c = -2\ell(\hat\theta)/c`
is Hotelling's :math:`T^2` of the :math:`q` over-identifying directions,
:math:`T^2(\nu-q+1)/(q\nu) \sim F_{q,\nu-q+1}` (:func:`hansen`; :math:`\chi^2_q` as
:math:`\nu \to \infty`), reported with the fit.

The whitened residual :math:`r(\theta) = \sqrt B\,W^{1/2}\bar m(\theta)` is built with
:math:`W^{1/2}` from the Cholesky factor of :math:`\hat\Sigma` in the components' order,
so :math:`\ell = -\tfrac12\|r\|^2` splits exactly into one term per component (each
component given the ones before it): the ``log_likelihood`` group of a fit.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np
from scipy import linalg, optimize, stats

from ..components.base import Moments

__all__ = [
    "HANSEN_P",
    "BlockCovariance",
    "QuasiLikelihood",
    "Transformed",
    "j_difference",
    "pooled_covariance",
    "quasi_likelihood",
    "solve",
    "weight_factor",
]

#: The degrees of freedom given a covariance the components know from their model (the
#: weight's Wishart factor then 1 to six digits).
MODEL_DOF = 10**7
#: Hansen p-value below which the equations disagree beyond chance: the quasi-likelihood
#: is widened by its dispersion (:mod:`hosid.inference.calibrate`).
HANSEN_P = 0.01


@dataclass(frozen=True)
class BlockCovariance:
    r"""The covariance of one block's estimating equations, estimated elsewhere than on
    the record they weigh: :math:`\hat\Sigma` with ``dof`` degrees of freedom (the
    Wishart factor of the weight is then :math:`(\nu - k - 1)/\nu`), for the equations
    ``labels``, and a note of where it comes from.
    """

    S: np.ndarray
    dof: int
    labels: tuple[str, ...]
    source: str = "simulated records"


def pooled_covariance(moment_sets, source: str = "simulated records") -> BlockCovariance | None:
    r"""The covariance of one block's equations pooled over records, each given by its
    prepared :class:`~hosid.components.base.Moments` (``moment_sets``, iterable):
    :math:`\hat\Sigma = \sum_rU_r^{\mathsf T}U_r/\sum_r(B_r - 1)` on
    :math:`\sum_r(B_r - 1)` degrees of freedom.  A record whose equations are not the
    first one's (its state chose another band, so other labels) is left out; ``None``
    from fewer than two records.  ``source`` names the records in the note.
    """
    S, dof, labels, used = 0.0, 0, None, 0
    for moments in moment_sets:
        moments = [m for m in moments if m.k]
        these = tuple(lab for m in moments for lab in m.labels)
        if labels is not None and these != labels:
            continue
        U = np.concatenate([m.influence for m in moments], axis=1)
        labels, S, dof, used = these, S + U.T @ U, dof + U.shape[0] - 1, used + 1
    if used < 2:
        return None
    return BlockCovariance(S / dof, dof, labels, f"{used} {source}")


@dataclass
class QuasiLikelihood:
    """The stacked, whitened estimating equations (module docstring)."""

    moments: list[Moments]
    B: int
    L_inv: np.ndarray  # (k, k) inverse Cholesky factor of Sigma / c
    slices: dict[str, slice]
    info: dict = field(default_factory=dict)

    @property
    def k(self) -> int:
        """Number of estimating equations."""
        return self.L_inv.shape[0]

    def mean(self, theta) -> np.ndarray:
        """Stacked block means ``(..., k)``."""
        return np.concatenate([m.mean(theta) for m in self.moments], axis=-1)

    def residual(self, theta) -> np.ndarray:
        r"""Whitened residual :math:`r(\theta)`, ``(..., k)``."""
        return math.sqrt(self.B) * self.mean(theta) @ self.L_inv.T

    def __call__(self, theta) -> np.ndarray:
        """The quasi-log-likelihood."""
        r = self.residual(theta)
        out = -0.5 * np.sum(r * r, axis=-1)
        return np.where(np.isfinite(out), out, -np.inf)

    def by_component(self, theta) -> dict[str, np.ndarray]:
        """The exact split of :meth:`__call__` into one term per component."""
        r = self.residual(theta)
        return {name: -0.5 * np.sum(r[..., s] ** 2, axis=-1) for name, s in self.slices.items()}

    def jacobian(self, theta: np.ndarray, scale: np.ndarray) -> np.ndarray:
        """Central-difference Jacobian of :meth:`residual` at one ``theta``, ``(k, p)``."""
        theta = np.asarray(theta, dtype=float)
        steps = 1e-5 * scale
        E = np.diag(steps)
        plus = self.residual(theta + E)
        minus = self.residual(theta - E)
        return ((plus - minus) / (2 * steps)[:, None]).T

    def laplace(self, theta: np.ndarray, scale: np.ndarray) -> np.ndarray:
        r"""Covariance :math:`(G_r^{\mathsf T}G_r)^{-1}` of the quasi-posterior at a mode
        (the Godambe covariance of the estimator).
        """
        G = self.jacobian(theta, scale)
        return np.linalg.pinv(G.T @ G)


@dataclass
class Transformed(QuasiLikelihood):
    r"""The same equations and weight in other coordinates :math:`u`,
    :math:`\theta = \tau(u)` (``transform``): a parameter fixed at a value, or one
    that is regular at a boundary null (e.g. :math:`1/\omega_c^2` for :math:`\omega_c`).
    Every method of :class:`QuasiLikelihood` then works in :math:`u`.
    """

    transform: Callable[[np.ndarray], np.ndarray] = field(default=lambda u: u)

    @classmethod
    def of(cls, ql: QuasiLikelihood, transform: Callable) -> Transformed:
        """``ql`` seen through ``transform`` (``u (..., q) -> theta (..., p)``)."""
        return cls(ql.moments, ql.B, ql.L_inv, ql.slices, ql.info, transform)

    def mean(self, theta) -> np.ndarray:
        r"""Stacked block means at :math:`\tau(u)`."""
        return super().mean(self.transform(np.asarray(theta, dtype=float)))


def chi2_logsf(x: float, df: int) -> float:
    r""":math:`\log P(\chi^2_{df} \ge x)`, also where the tail underflows: there (scipy's
    ``logsf`` is :math:`-\infty` beyond :math:`x \approx 1500`) the upper incomplete
    gamma's asymptotic series, :math:`\log\Gamma(a, y) = (a-1)\log y - y +
    \log(1 + (a-1)/y + (a-1)(a-2)/y^2 + \dots)` with :math:`a = df/2`, :math:`y = x/2`,
    less :math:`\log\Gamma(a)` (relative error below :math:`10^{-6}` for :math:`y > 500`
    and :math:`df \le 10`).
    """
    out = float(stats.chi2.logsf(x, df))
    if math.isfinite(out):
        return out
    a, y = 0.5 * df, 0.5 * float(x)
    series = 1.0 + (a - 1.0) / y + (a - 1.0) * (a - 2.0) / y**2
    return (a - 1.0) * math.log(y) - y + math.log(series) - math.lgamma(a)


def j_difference(
    J_restricted: float,
    J_free: float,
    *,
    df: int = 1,
    boundary: bool = False,
    dispersion: float = 1.0,
) -> dict:
    r"""The distance-metric test of a nested restriction (Newey & West 1987).

    With one weight :math:`W` for both fits, :math:`D = J_{restricted} - J_{free}`
    (the difference of Hansen statistics, i.e. twice the drop of the quasi-log-likelihood)
    is :math:`\chi^2_{df}` under the restriction.  A single parameter whose null value
    lies on the boundary of its space (a friction coefficient, a noise variance, the
    inverse square of a filter corner: all :math:`\ge 0`) gives the chi-bar-square
    :math:`\tfrac12\chi^2_0 + \tfrac12\chi^2_1` instead (Self & Liang 1987), so
    :math:`p = \tfrac12 P(\chi^2_1 \ge D)` for :math:`D > 0`.  ``dispersion`` (Hansen's
    :math:`J/(k-p)` when the calibration widens the posterior) divides :math:`D`.
    ``log_p`` is :math:`\log p` from the tail's logarithm: it orders tests whose
    :math:`p` underflows to 0 (a narrow-band force's :math:`D` of some thousands).
    """
    if boundary and df != 1:
        raise ValueError("the chi-bar-square reference is implemented for one parameter")
    D = max(float(J_restricted) - float(J_free), 0.0) / float(dispersion)
    if boundary:
        log_p = math.log(0.5) + chi2_logsf(D, 1) if D > 0 else 0.0
        ref = "chi-bar-square: 0.5 chi2(0) + 0.5 chi2(1)"
    else:
        log_p = chi2_logsf(D, df)
        ref = f"chi2({df})"
    return {"D": D, "p_value": math.exp(log_p), "log_p": log_p, "reference": ref, "df": int(df)}


def quasi_likelihood(
    moments: Sequence[Moments],
    *,
    n_params: int,
    covariance: BlockCovariance | None = None,
) -> QuasiLikelihood:
    r"""Stack ``moments`` and weight them with the inverse influence covariance: the
    record's own (:math:`\hat\Sigma` of its :math:`B` blocks), the components' own model
    of it when every one gives it (:attr:`hosid.components.base.Moments.covariance`, taken
    as exact: :data:`MODEL_DOF`), or, when given, a ``covariance`` of the same equations
    estimated elsewhere (:class:`BlockCovariance`).

    Raises
    ------
    ValueError
        If the blocks are too few for the number of equations (``B <= k + 2``), the
        covariance is singular, or ``covariance`` holds other equations.
    """
    moments = [m for m in moments if m.k]  # a component may offer no equation here
    U = np.concatenate([m.influence for m in moments], axis=1)
    B, k = U.shape
    if B <= k + 2:
        raise ValueError(f"{B} blocks are too few for {k} estimating equations")
    S, dof = U.T @ U / (B - 1), B - 1
    if covariance is None and all(m.covariance is not None for m in moments):
        S, dof = linalg.block_diag(*(m.covariance for m in moments)), MODEL_DOF
    if covariance is not None:
        labels = tuple(lab for m in moments for lab in m.labels)
        if covariance.labels != labels:
            raise ValueError("the covariance is of other estimating equations")
        S, dof = covariance.S, covariance.dof
    d = np.sqrt(np.diag(S))
    if not np.all(d > 0):
        bad = [lab for m in moments for lab in m.labels]
        raise ValueError(
            "an estimating equation has no variance: "
            + ", ".join(b for b, di in zip(bad, d, strict=True) if not di > 0)
        )
    factor = weight_factor(dof, k)
    C = S / np.outer(d, d)
    try:
        Lc = linalg.cholesky(C / factor, lower=True)
    except linalg.LinAlgError:
        raise ValueError("the estimating equations are linearly dependent") from None
    L_inv = linalg.solve_triangular(Lc, np.eye(k), lower=True) / d[None, :]
    slices, start = {}, 0
    for m in moments:
        slices[m.component] = slice(start, start + m.k)
        start += m.k
    lag1 = [
        float(np.corrcoef(U[:-1, i], U[1:, i])[0, 1]) if B > 3 else float("nan") for i in range(k)
    ]
    info = {
        "weighting": "efficient GMM (inverse jackknife covariance, Godambe curvature)"
        + ("" if covariance is None else f"; covariance of {covariance.source}"),
        "covariance_dof": int(dof),
        "blocks": B,
        "equations": k,
        "parameters": n_params,
        "weight_factor": factor,
        "condition_number": float(np.linalg.cond(C)),
        "max_abs_lag1_correlation": float(np.nanmax(np.abs(lag1))),
    }
    return QuasiLikelihood(list(moments), B, L_inv, slices, info)


def weight_factor(dof: int, k: int) -> float:
    r"""The factor :math:`c = (\nu - k - 1)/\nu` of the weight :math:`W = c\,\hat\Sigma^{-1}`
    of ``k`` equations whose covariance has :math:`\nu` = ``dof`` degrees of freedom
    (module docstring).
    """
    return (dof - k - 1) / dof


def hansen(ql: QuasiLikelihood, theta: np.ndarray) -> dict:
    """Hansen's over-identification test at the estimate ``theta`` (:func:`hansen_test`)."""
    return hansen_test(float(-2.0 * ql(theta)), ql.k - int(ql.info["parameters"]), ql.info)


def hansen_test(J: float, df: int, info: dict) -> dict:
    r"""Hansen's test of :math:`J = -2\ell(\hat\theta)` on ``df`` :math:`= q` over-identifying
    equations, weighted as ``info`` says (:func:`quasi_likelihood`): :math:`J/c` is
    Hotelling's :math:`T^2` on :math:`\nu` degrees of freedom,
    :math:`T^2(\nu-q+1)/(q\nu) \sim F_{q,\nu-q+1}` (module docstring); ``dispersion`` is
    :math:`T^2` over its expectation :math:`q\nu/(\nu-q-1)`.
    """
    if df <= 0:
        return {"J": J, "df": df, "p_value": float("nan"), "dispersion": 1.0}
    nu = int(info["covariance_dof"])
    T2 = J / float(info["weight_factor"])
    p = float(stats.f.sf(T2 * (nu - df + 1) / (df * nu), df, nu - df + 1))
    return {"J": J, "df": df, "p_value": p, "dispersion": T2 * (nu - df - 1) / (df * nu)}


def solve(
    ql: QuasiLikelihood,
    start: np.ndarray,
    *,
    log_params: Sequence[int],
    scale: np.ndarray,
    lower: np.ndarray | None = None,
    upper: np.ndarray | None = None,
) -> np.ndarray:
    r"""Minimize :math:`\|r(\theta)\|^2` from ``start`` within ``[lower, upper]`` (the
    priors' supports; trust-region reflective least squares).

    Positive parameters (``log_params``) are solved for in their logarithm.
    """
    start = np.asarray(start, dtype=float)
    p = start.size
    lower = np.full(p, -np.inf) if lower is None else np.asarray(lower, dtype=float)
    upper = np.full(p, np.inf) if upper is None else np.asarray(upper, dtype=float)
    logs = np.zeros(p, dtype=bool)
    logs[list(log_params)] = True
    pad = 1e-9 * np.where(np.isfinite(upper - lower), upper - lower, 1.0)
    start = np.clip(start, lower + pad, upper - pad)
    s = np.where(logs, 1.0, scale)

    def to_z(theta):
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.where(logs, np.log(theta / start), (theta - start) / s)

    def to_theta(z):
        return np.where(logs, start * np.exp(np.where(logs, z, 0.0)), start + z * s)

    last = {}  # the residual at the last point, for the Jacobian's differences

    def fun(z):
        r = ql.residual(to_theta(z))
        r = np.where(np.isfinite(r), r, 1e150)
        if z.ndim == 1:
            last["z"], last["r"] = z.copy(), r
        return r

    lo = np.where(logs & (lower <= 0), -np.inf, to_z(lower))
    hi = to_z(upper)

    def jac(z):  # scipy's forward differences, the shifted points as one batch
        f0 = last["r"] if "z" in last and np.array_equal(last["z"], z) else fun(z)
        Z = z + np.diag(forward_steps(z, lo, hi))
        dx = np.diagonal(Z) - z
        return ((fun(Z) - f0) / dx[:, None]).T

    with warnings.catch_warnings(), np.errstate(over="ignore", invalid="ignore"):
        warnings.simplefilter("ignore", RuntimeWarning)
        res = optimize.least_squares(
            fun, np.zeros(p), jac=jac, bounds=(lo, hi), method="trf", x_scale=1.0,
            xtol=1e-12, ftol=1e-12, gtol=1e-12, max_nfev=4000,
        )  # fmt: skip
    return to_theta(res.x)


def forward_steps(x0: np.ndarray, lower: np.ndarray, upper: np.ndarray) -> np.ndarray:
    r"""The steps of scipy's forward differences (``least_squares(jac="2-point")``):
    :math:`\sqrt{\epsilon}\max(1, |x|)`, signed as :math:`x` (+ at 0), reversed where it
    leaves the bounds and fits the other way, else to the farther bound.  :func:`solve`
    evaluates the shifted points as one batch (scipy, one by one): the estimate of a ship
    record under a shaping filter took 22-26 % less time.
    """
    h = np.sqrt(np.finfo(float).eps) * np.where(x0 >= 0, 1.0, -1.0) * np.maximum(1.0, np.abs(x0))
    below, above = x0 - lower, upper - x0
    fitting = np.abs(h) <= np.maximum(below, above)
    h = np.where(((x0 + h < lower) | (x0 + h > upper)) & fitting, -h, h)
    return np.where(fitting, h, np.where(above >= below, above, -below))
