r"""Calibration of the quasi-likelihood: no record gets a silently overconfident posterior.

``"gmm"`` (default for the default components and for ``cost="J2"``)
    The optimally weighted quasi-likelihood of :mod:`hosid.inference.gmm` has the
    Godambe curvature built in.  Hansen's test guards it: when the estimating equations
    disagree beyond chance (:math:`p < 0.01`), the record holds more than the model
    describes and the quasi-likelihood is divided by the dispersion :math:`J/(k-p)`
    (the posterior widened by its square root), and the report says so.

``"bootstrap"`` (default for ``cost="J4A"`` and ``"J4B"``)
    The trispectral equations identify the split of :math:`a_1` from :math:`n_1` only
    weakly; their estimator is skewed and its curvature does not match its spread.  A
    parametric bootstrap measures what the curvature cannot: ``R`` records as long as
    the measured one are simulated from the fitted model (seeds spawned from one
    ``SeedSequence``) and re-estimated, giving the
    estimator's bias :math:`b` and covariance :math:`V`.  The quasi-likelihood is then
    curvature-adjusted (Ribatet, Cooley & Davison 2012) and bias-corrected (records are
    simulated from :func:`dissipative` of the estimate, whose damping law stays positive):

    .. math:: \ell_{adj}(\theta) = \ell\big(\hat\theta + A(\theta - \hat\theta + b)\big),
        \qquad A = L_qL_V^{-1},

    with :math:`L_q L_q^{\mathsf T}` the quasi-posterior covariance at the mode and
    :math:`L_VL_V^{\mathsf T} = V(1 + 1/R)` (the bias correction carries the
    bootstrap's own noise), so that the adjusted posterior is centred on
    :math:`\hat\theta - b` with covariance :math:`V` and keeps the shape of
    :math:`\ell`.  Without the eq-65 constraint the map is mirrored on the twin side.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from ..errors import HosidInputError
from .estimate import Estimate, estimate

__all__ = ["Calibrated", "calibrate"]

#: Hansen p-value below which the quasi-likelihood is widened by its dispersion.
HANSEN_P = 0.01
#: Default number of bootstrap records.
N_BOOTSTRAP = 40


@dataclass
class Calibrated:
    """A calibrated quasi-likelihood: ``by_component(theta)``, mode ``theta``, ``cov``."""

    est: Estimate
    theta: np.ndarray
    cov: np.ndarray
    method: str
    dispersion: float = 1.0
    A: np.ndarray | None = None
    shift: np.ndarray | None = None
    numbers: dict = field(default_factory=dict)

    def _map(self, theta: np.ndarray) -> np.ndarray:
        """The adjustment map (identity for ``"gmm"``; mirrored on the twin side)."""
        if self.A is None:
            return theta
        th = np.asarray(theta, dtype=float)
        m = self.est.model
        mirror = np.ones(th.shape[-1])
        mirror[[i for i, t in enumerate(m.drift_terms) if t.variable == "v"]] = -1.0
        neg = (m.equivalent_damping(th, self.est.sigma_v) < 0)[..., None]
        th = np.where(neg, th * mirror, th)
        out = self.est.theta + (th - self.est.theta + self.shift) @ self.A.T
        return np.where(neg, out * mirror, out)

    def by_component(self, theta: np.ndarray) -> dict[str, np.ndarray]:
        """The calibrated quasi-log-likelihood, split by component."""
        parts = self.est.ql.by_component(self._map(theta))
        return {k: v / self.dispersion for k, v in parts.items()}

    def describe(self) -> dict:
        """What was done and its numbers (attrs and report)."""
        return {"method": self.method, "dispersion": self.dispersion, **self.numbers}


def calibrate(
    est: Estimate,
    components: Sequence,
    *,
    method: str = "auto",
    cost: str | None = None,
    rng: np.random.Generator,
    n_bootstrap: int = N_BOOTSTRAP,
    progress: bool = False,
) -> Calibrated:
    """Calibrate the quasi-likelihood of ``est`` (module docstring).

    Raises
    ------
    HosidInputError
        For an unknown method.
    """
    if method == "auto":
        method = "bootstrap" if cost in ("J4A", "J4B") else "gmm"
    if method not in ("gmm", "bootstrap"):
        raise HosidInputError(f"unknown calibration {method!r}: auto, gmm or bootstrap")
    numbers = {**est.ql.info, "hansen": est.test}
    disp = 1.0
    if est.test["df"] > 0 and est.test["p_value"] < HANSEN_P:
        disp = est.test["J"] / est.test["df"]
        numbers["note"] = (
            f"Hansen's test rejects the model (J = {est.test['J']:.1f} on "
            f"{est.test['df']} df): posterior widened by sqrt({disp:.2f})"
        )
    if method == "gmm":
        return Calibrated(est, est.theta, est.cov * disp, "gmm", disp, numbers=numbers)
    return _bootstrap(est, components, rng, n_bootstrap, progress, numbers)


def _one(task) -> np.ndarray | None:
    """One bootstrap record: simulate from the fit and re-estimate (a worker's job)."""
    model, values, duration, dt, seed, components, start, block_seconds = task
    try:
        sim = model.simulate(values, duration=duration, dt=dt, rng=np.random.default_rng(seed))
        e = estimate(sim, model, components, start=start, rounds=1, block_seconds=block_seconds)
    except HosidInputError:
        return None
    return e.theta


def dissipative(model, theta: np.ndarray, sigma_v: float) -> np.ndarray:
    """``theta`` with every negative damping coefficient but ``a1`` moved into ``a1``
    (eq 65's equivalent damping kept): a stationary model to simulate from when the
    estimate's damping law turns negative at high speed (the response would escape).
    """
    th = np.array(theta, dtype=float)
    if not model.has("a1"):
        return th
    i1 = model.index("a1")
    for i, t in enumerate(model.drift_terms):
        c = t.damping_factor(sigma_v)
        if c and i != i1 and th[i] < 0:
            th[i1] += th[i] * c
            th[i] = 0.0
    return th


def _bootstrap(est, components, rng, R, progress, numbers) -> Calibrated:
    model = est.model
    rec = est.state.record
    source = dissipative(model, est.theta, est.sigma_v)
    values = model.params(source)
    seeds = np.random.SeedSequence(int(rng.integers(2**63))).spawn(R)
    tasks = [
        (
            model,
            values,
            rec.duration,
            rec.dt,
            seeds[r],
            list(components),
            est.theta,
            est.state.layout.T,
        )
        for r in range(R)
    ]
    bar = None
    if progress:
        from tqdm.auto import tqdm

        bar = tqdm(total=R, desc="calibrating (bootstrap)", leave=False)
    results = []
    for task in tasks:
        results.append(_one(task))
        if bar is not None:
            bar.update()
    if bar is not None:
        bar.close()
    draws = [r for r in results if r is not None]
    failed = R - len(draws)
    if len(draws) < max(len(est.theta) + 2, (R + 1) // 2):
        raise HosidInputError(
            f"the bootstrap calibration failed on {failed} of {R} simulated records"
        )
    D = np.array(draws)
    bias = D.mean(axis=0) - source
    # the bias correction carries the bootstrap's own noise, var V / R
    V = np.cov(D, rowvar=False) * (1.0 + 1.0 / len(draws))
    Lq = np.linalg.cholesky(_psd(est.cov))
    Lv = np.linalg.cholesky(_psd(V))
    A = Lq @ np.linalg.inv(Lv)
    names = model.param_names
    numbers.update(
        {
            "bootstrap_records": len(draws),
            "bootstrap_source": model.params(source),
            "bootstrap_failed": failed,
            "bias": dict(zip(names, bias.tolist(), strict=True)),
            "sd_ratio": dict(
                zip(names, (np.sqrt(np.diag(V) / np.diag(est.cov))).tolist(), strict=True)
            ),
        }
    )
    return Calibrated(est, est.theta - bias, V, "bootstrap", 1.0, A, bias, numbers)


def _psd(C: np.ndarray) -> np.ndarray:
    C = 0.5 * (C + C.T)
    w, U = np.linalg.eigh(C)
    floor = 1e-12 * max(float(w.max()), 1e-300)
    return (U * np.maximum(w, floor)) @ U.T
