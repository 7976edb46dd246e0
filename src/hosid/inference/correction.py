r"""The sampling bias of an estimate under Poisson impulses, corrected by simulation.

Every component restores in closed form what a sampled record lacks above the Nyquist
frequency when the force is Gaussian (:func:`hosid.state.velocity_deficit`,
:func:`hosid.state.jet_deficit`).  Under Poisson impulses no closed form holds: a kick
(at the paper's level an area of sd 18-35 against a velocity sd of 5) is rounded off by
the quadratic damping within a few samples, so the sampled velocity misses the kicks'
peaks (:math:`E|\dot x|^3` 18 % low at 0.5 impulses a second) and the inferred force's
kurtosis their sharpness; the estimate is biased (paper oscillator at 0.5 a second:
:math:`a_2` 13 % and :math:`S_0` 18 % low, the rate 16 % high).  The model itself holds
the answer.  With :math:`\hat\theta` the estimate of the record and
:math:`b(\theta) = E_\theta[\hat\theta] - \theta` the estimator's bias on records of the
model at :math:`\theta` (the record's duration and sampling), estimated by the mean of
``n`` simulated records (:func:`hosid.model.simulate.simulate`), the corrected estimate
iterates

.. math:: \theta_0 = \hat\theta, \qquad \theta_{i+1} = \hat\theta - b(\theta_i)

(``iterations`` times; the bias grows with the impulses' area, which the raw estimate
understates, so one step falls short), the bias of a positive parameter (``S0``,
``rate``) taken as a ratio.  This is the bias-corrected estimator of indirect inference
(Gourieroux, Monfort and Renault 1993; MacKinnon and Smith 1998).  It is made only where
single impulses show, fewer than one a sample at the estimate: with more the force is
Gaussian at the record's scale, the closed forms hold, and the correction would only
widen the posterior (on 6 white records by the 6 % of its :math:`\sqrt{1 + 1/n}`).  The
quasi-likelihood is moved with it, :math:`\tilde\ell(\theta) = \ell(\theta + b)`, so
that its mode is the corrected estimate and the sampler draws around it, and it is
widened by :math:`1 + 1/n` for the noise of :math:`b`.  The same simulated records give
the estimator's spread: where a parameter's estimates scatter more than the
quasi-likelihood's curvature says, beyond the chance of :math:`2(n - 1)` degrees of
freedom (:func:`widening`; the rate whenever they scatter more, :data:`BOOTSTRAPPED`),
the quasi-likelihood is widened along that parameter to the spread (at 0.5 impulses a
second the rate's estimates scattered 1.6 times its curvature's sd: the kurtosis's block
values, a few impulses a block, are heavy-tailed, and their block covariance understates
the variance of their mean; the spread itself is an estimate on :math:`2(n - 1)` degrees
of freedom, taken with Student's t).  Measured on 40 records of the
independent simulator (``analyses/impulse_study.py``): the paper oscillator's drift
unbiased at 0.5-2 impulses a second (``a2`` 24.2-25.2 against 21.3-24.3 uncorrected),
``S0`` 100-103 (84-94), pooled 90 % coverage of the drift 0.90 (0.69).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable

import numpy as np

from ..errors import HosidInputError
from ..progress import staged
from .gmm import QuasiLikelihood

__all__ = [
    "BOOTSTRAPPED",
    "DEFAULT_ITERATIONS",
    "DEFAULT_SIMULATIONS",
    "bias",
    "laplace_sd",
    "moved",
    "relative",
    "shifted",
    "simulated_like",
    "unbiased",
    "widening",
]

#: Records simulated for each evaluation of the bias.
DEFAULT_SIMULATIONS = 8
#: Evaluations of the bias.
DEFAULT_ITERATIONS = 2
#: Parameters whose sd is the simulated records' spread whenever that is the larger (the
#: parametric bootstrap's), not only beyond chance (:func:`widening`): the rate is seen
#: only through the force's fourth cumulant, whose block values are heavy-tailed, and its
#: block covariance understates the variance of their mean on most records.  Measured on
#: 16 records at 0.5 impulses a second (uncorrected estimates): the rate's estimates
#: scattered 1.76 (hosid's simulator) and 1.11 (the independent one) times its mean
#: curvature sd, and on the impulse study's 10 records 1.58 times its posterior sd
#: (covered 6/10 at 90 %), while the gated widening of 14 degrees of freedom did not act.
#: With the spread as sd (and Student's t, :func:`widening`), on 40 records: covered at
#: 90 % in 34, at 50 % in 22 (``results/impulses/paper_kicks_0.5_40``).
BOOTSTRAPPED = ("rate",)


def bias(
    estimator: Callable[[object], np.ndarray],
    simulate: Callable[[np.ndarray, np.random.Generator], object],
    theta_hat: np.ndarray,
    positive: np.ndarray,
    rng: np.random.Generator,
    *,
    n: int = DEFAULT_SIMULATIONS,
    iterations: int = DEFAULT_ITERATIONS,
    progress: Callable[[], None] | None = None,
) -> np.ndarray:
    r"""The shift :math:`\beta` with corrected estimate :math:`\hat\theta - \beta`
    (additive) or :math:`\hat\theta e^{-\beta}` (where ``positive``), module docstring,
    and the estimator's spread on the simulated records: the sd of each parameter
    (relative where ``positive``) pooled within the iterations
    (:math:`\mathrm{iterations}(n - 1)` degrees of freedom).

    ``estimator(record) -> theta``; ``simulate(theta, rng) -> record``.
    """
    theta_hat = np.asarray(theta_hat, dtype=float)
    theta = theta_hat.copy()
    beta = np.zeros_like(theta)
    spread = []
    for _ in range(iterations):
        draws = []
        for _ in range(n):
            draws.append(estimator(simulate(theta, rng)))
            if progress is not None:
                progress()
        mean = np.mean(draws, axis=0)
        logs = relative(draws, positive)
        spread.append(logs - logs.mean(axis=0))
        beta = np.where(positive, np.log(np.where(positive, mean / theta, 1.0)), mean - theta)
        theta = moved(theta_hat, -beta, positive)
    dev = np.concatenate(spread)
    return beta, np.sqrt(np.sum(dev**2, axis=0) / (dev.shape[0] - iterations))


def moved(theta, beta, positive) -> np.ndarray:
    r""":math:`\theta + \beta`, or :math:`\theta e^{\beta}` where ``positive``."""
    th = np.asarray(theta, dtype=float)
    return np.where(positive, th * np.exp(beta), th + beta)


def relative(values, positive) -> np.ndarray:
    """``values`` as the spreads compare them: their logarithm where ``positive``."""
    v = np.asarray(values, dtype=float)
    return np.where(positive, np.log(np.abs(v)), v)


def laplace_sd(ql: QuasiLikelihood, theta, scale, positive) -> np.ndarray:
    """The Laplace sd of ``ql`` at ``theta``, relative where ``positive``."""
    sd = np.sqrt(np.maximum(np.diag(ql.laplace(theta, scale)), 0.0))
    return sd / np.where(positive, np.abs(theta), 1.0)


def shifted(
    ql: QuasiLikelihood,
    beta: np.ndarray,
    positive: np.ndarray,
    n: int,
    centre: np.ndarray | None = None,
    widen: np.ndarray | None = None,
    shift: bool = True,
):
    r""":math:`\ell(\theta + b)` (module docstring), widened by :math:`1 + 1/n` for the
    noise of :math:`b` estimated on ``n`` records (not where ``shift`` is false: ``beta``
    zero, only widened), and each parameter :math:`i` by ``widen[i]`` about ``centre``
    (:math:`\theta \to c + (\theta - c)/w`, relative where ``positive``).
    """
    beta = np.asarray(beta, dtype=float)
    w = np.ones_like(beta) if widen is None else np.asarray(widen, dtype=float)
    c = np.zeros_like(beta) if centre is None else np.asarray(centre, dtype=float)

    def narrowed(theta):  # the widening of the likelihood is a narrowing of its argument
        theta = np.asarray(theta, dtype=float)
        if widen is None:
            return theta
        rel = np.log(np.abs(theta / np.where(c == 0, 1.0, c)))
        return np.where(positive, c * np.exp(rel / w), c + (theta - c) / w)

    moments = [
        dataclasses.replace(
            m, mean=lambda theta, f=m.mean: f(moved(narrowed(theta), beta, positive))
        )
        for m in ql.moments
    ]
    key, noise = ("sampling_bias", 1.0 + 1.0 / n) if shift else ("simulated_spread", 1.0)
    info = {
        **ql.info,
        key: {
            "shift": beta.tolist(), "simulations": n, "positive": positive.tolist(),
            "widened": w.tolist(),
        },
    }  # fmt: skip
    return dataclasses.replace(ql, moments=moments, L_inv=ql.L_inv / math.sqrt(noise), info=info)


def simulated_like(state, model, theta, rng):
    """The state of a record of ``model`` at ``theta`` like the record's ``state``: its
    duration, sampling and blocks.
    """
    from .estimate import prepare_state

    rec = model.simulate(theta, duration=state.record.duration, dt=state.dt, rng=rng)
    return prepare_state(rec, model, block_seconds=state.layout.T)


def unbiased(state, model, components, theta, ql, n, progress):
    """The estimate ``theta`` of the record's ``state`` and its quasi-likelihood ``ql``,
    corrected (module docstring) by :func:`bias` of
    :func:`hosid.inference.estimate.estimate` on ``n`` records a step, drawn from a seed
    fixed by the record's samples (the estimate stays a function of the record); the
    positive parameters (log-uniform priors) are corrected as ratios.
    """
    from .estimate import estimate, log_params

    positive = np.zeros(len(theta), dtype=bool)
    positive[log_params(model, model.default_priors(state.scales))] = True
    seed = np.random.SeedSequence(int(state.record.hash[:16], 16))

    def estimator(st):
        return estimate(st, model, components, settle=False, simulations=0).theta

    rng = np.random.default_rng(seed)
    total = DEFAULT_ITERATIONS * n
    with staged(progress, "sampling-bias correction", total=total, unit="record") as b:
        try:
            beta, spread = bias(
                estimator, lambda th, r: simulated_like(state, model, th, r), theta,
                positive, rng, n=n, progress=lambda: b.update(1),
            )  # fmt: skip
        except HosidInputError as exc:
            raise HosidInputError(f"the sampling-bias correction failed: {exc}") from None
    corrected = moved(theta, -beta, positive)
    first = shifted(ql, beta, positive, n)
    from .solutions import typical_scale

    sd = laplace_sd(first, corrected, typical_scale(model, state, corrected), positive)
    always = np.array([name in BOOTSTRAPPED for name in model.param_names])
    widen = widening(spread, sd, DEFAULT_ITERATIONS * (n - 1), always=always)
    return corrected, shifted(ql, beta, positive, n, centre=corrected, widen=widen)


def widening(
    spread: np.ndarray,
    sd: np.ndarray,
    df: int,
    level: float = 0.95,
    always: np.ndarray | None = None,
) -> np.ndarray:
    r"""Per parameter, the factor that widens the quasi-likelihood to the estimator's
    spread on the simulated records where that spread exceeds the curvature's sd beyond
    chance: :math:`s/\sigma` when :math:`(s/\sigma)^2` exceeds the ``level`` point of
    :math:`\chi^2_{df}/df` (the spread's own noise), else 1.  Where ``always`` (the
    parametric bootstrap's sd, :data:`BOOTSTRAPPED`) the sd is the spread as a predictive
    interval takes an sd estimated on ``df`` degrees of freedom, Student's
    :math:`s\,t_{df}/z` at the 90 % level (:math:`t_{14}/z = 1.07`), whenever that exceeds
    :math:`\sigma`.  Measured at 0.5 impulses a second (paper oscillator, independent
    simulator): on 10 records the estimates of the rate scattered 1.6 times its
    posterior sd before the bootstrap; with the bootstrap's spread alone, on 40 records,
    1.12 times (covered at 90 % in 33, at 50 % in 20), with Student's t 1.08 times (34,
    22).
    """
    from scipy import stats

    ratio = np.asarray(spread, dtype=float) / np.maximum(np.asarray(sd, dtype=float), 1e-300)
    crit = math.sqrt(stats.chi2.ppf(level, df) / df)
    out = np.where(ratio > crit, ratio, 1.0)
    if always is None:
        return out
    student = float(stats.t.ppf(0.95, df) / stats.norm.ppf(0.95))
    return np.where(always, np.maximum(ratio * student, 1.0), out)
