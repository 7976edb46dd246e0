r"""What an estimate takes from records simulated at it (:func:`refined`): under Poisson
impulses the correction of its sampling bias (:mod:`hosid.inference.correction`), under
a shaping filter the weight of its equations, their covariance on those records.

The default weight of the estimating equations is the inverse of their covariance over
the record's own :math:`B` blocks (:func:`hosid.inference.gmm.quasi_likelihood`), with
the Wishart factor :math:`(\nu - k - 1)/\nu` for its noise.  Under a shaping filter
(``narrowband_excitation``) the :math:`k = 14` equations are nearly collinear (the
block covariance's condition number is about 2000 with the filter at the resonance of a
ship-roll-like oscillator): the covariance's small eigenvalues, estimated from 39
blocks, are then noisy beyond the Wishart factor's reach, and the weight's error is
correlated with the equations' own, both being taken from the same blocks (the
small-sample bias of two-step efficient GMM, Altonji & Segal 1996).  Measured on
records of that case (hosid's simulator, ``wf`` 0.6, ``zf`` 0.1, 4000 s): at the true
parameters each equation's scatter over 24 records was 0.7-1.24 times its block
standard error and the equations' :math:`J` with their covariance pooled over the
records averaged 12.4 for :math:`k = 14`, but with each record's own covariance 28 (12
records); over 16 records :math:`J(\theta_0) - J(\hat\theta)` averaged 15 for 7
parameters, and the Laplace z of ``a2``, ``wf`` and ``S0`` had sd 3.0, 3.1 and 2.7.

The remedy keeps the record's equations and takes their weight from elsewhere: ``n``
records simulated from the model at the estimate :math:`\hat\theta`, with the
record's duration, sampling and blocks, give the equations' block influences at
:math:`\hat\theta`, pooled (:class:`hosid.inference.gmm.BlockCovariance`, :math:`\sum
(B_r - 1)` degrees of freedom), independent of the record's own sampling error; the
estimate is solved again under that weight.  On the 24 records of
``analyses/coincident_resonances.py`` (variant ``simulated_weight``, 8 simulated records
a record) the Laplace 90 % intervals of ``a2``, ``wf``, ``S0`` held the truth in 0.62,
0.71, 0.71 of the records (0.38, 0.50, 0.58 with the record's own weight); their z's sd
stays 2.4-2.7, from a few records far out, and the equations' J at the truth averaged
15.7 for 14 equations (18.9 with the record's own weight).  With the filter above the
resonance (``wf`` 0.9, ``results/coincident_resonances_control.md``) both weights are
calibrated (z sd 0.84-1.22, against 0.80-1.16), and the simulated one scatters less
(``a2`` 1.46 % of its value against 1.57 %, ``wf^2`` 2.04 % against 2.37 %).  The
sampled posterior on the excitation study's 100 records
(``analyses/excitation_study.py``: independent simulator, 8 filters and 2 white forces,
10 records each): the drift's 90 % intervals pooled over the filtered cases held the
truth in 0.891 (0.866 with the record's own weight); with the broad filter at the ship's
resonance ``a1``'s root-mean-square error fell from 1.84 to 1.02 of its value; with the
narrow one there the pair stayed miscovered (``a2`` 7/10, ``wf`` 5/10; refitted after the
spectral derivatives' fix: 5/10 and 6/10, the drift's pooled coverage 0.884), the roots'
repulsion of ``analyses/coincident_resonances.py``, until the force's kurtosis took its
own scale (:mod:`hosid.components.cumulant`: 9/10 and 8/10, pooled 0.900).  The seed is
fixed by the record's samples, so that the estimate stays a function of the record.

The same records also give the estimator's spread: each is solved under the same weight,
and where their estimates scatter more than the quasi-likelihood's curvature says beyond
chance, it is widened along that parameter to their scatter (:func:`spread_widening`).
On the excitation study's 100 records (same records and seeds): the ship-roll-like
oscillator's ``wf`` under the narrow filter at its resonance held in 8/10 records' 90 %
intervals (was 7/10; at 50 % in 5/10, was 1/10), the drift's 90 % and 50 % intervals
pooled over the 80 filtered records 0.916 and 0.519 (were 0.897 and 0.494); the paper
oscillator's filtered cases moved by the sampler's noise (4 of their 280 intervals at
90 %, two in and two out).
"""

from __future__ import annotations

import numpy as np

from ..errors import HosidInputError
from ..progress import staged
from .correction import (
    DEFAULT_ITERATIONS,
    laplace_sd,
    relative,
    shifted,
    simulated_like,
    unbiased,
    widening,
)
from .gmm import pooled_covariance, quasi_likelihood, solve
from .solutions import typical_scale

__all__ = ["refined", "reweighted", "spread_widening"]


def refined(state, model, components, theta, ql, n, search, progress=False):
    """The estimate ``theta`` and its quasi-likelihood ``ql`` refined with ``n`` records
    simulated from the model, and notes of what was done: under impulses, fewer than one
    a sample (where single impulses show; more make a force Gaussian at the record's
    scale, restored exactly), the sampling bias corrected
    (:func:`hosid.inference.correction.unbiased`); under a shaping filter, the equations
    weighed by :func:`reweighted`.  ``search``: the log-scaled parameters and the
    search's bounds.
    """
    notes = []
    if model.has("rate") and theta[model.index("rate")] * state.dt < 1.0:
        theta, ql = unbiased(state, model, components, theta, ql, n, progress)
        notes.append(
            "the estimate is corrected for the impulses' sampling bias (indirect inference: "
            f"{DEFAULT_ITERATIONS} x {n} records simulated near the estimate)"
        )
    if model.has("wf"):  # nearly collinear equations (module docstring)
        moved, weighed = reweighted(state, model, components, theta, n, *search, progress)
        if weighed is not None:
            theta, ql = moved, weighed
            notes.append(
                f"the equations are weighed with their covariance on {n} records simulated "
                "at the estimate (a shaping filter's equations are nearly collinear)"
            )
    return theta, ql, notes


def reweighted(state, model, components, theta, n, logs, lower, upper, progress=False):
    """The estimate of the record's ``state`` solved again with its equations weighed
    by :func:`hosid.inference.gmm.pooled_covariance` of ``n`` records simulated at
    ``theta`` (module docstring), and its quasi-likelihood, widened to the spread of the
    same weight's estimates on those records (:func:`spread_widening`); ``theta`` and
    ``None`` when fewer than two simulated records give the record's equations.
    """
    rng = np.random.default_rng(np.random.SeedSequence([int(state.record.hash[:16], 16), 2]))
    sets = []
    with staged(progress, "weight from simulated records", total=n, unit="record") as b:

        def simulated():  # each record's equations at theta
            for _ in range(n):
                st = simulated_like(state, model, theta, rng)
                sets.append([c.prepare(st, model, theta) for c in components])
                b.update(1)
                yield sets[-1]

        try:
            cov = pooled_covariance(simulated(), "records simulated at the estimate")
        except (HosidInputError, ValueError):
            cov = None
    if cov is None:
        return theta, None
    moments = [m for m in (c.prepare(state, model, theta) for c in components) if m.k]
    if tuple(lab for m in moments for lab in m.labels) != cov.labels:
        return theta, None
    ql = quasi_likelihood(moments, n_params=len(theta), covariance=cov)
    scale = typical_scale(model, state, theta)
    new = solve(ql, theta, log_params=logs, scale=0.1 * scale, lower=lower, upper=upper)
    if not np.all(np.isfinite(new)):
        return theta, None
    return new, spread_widening(ql, new, sets, theta, cov, logs, lower, upper, scale)


def spread_widening(ql, new, sets, theta, cov, logs, lower, upper, scale):
    r"""``ql`` widened about its mode ``new`` to the spread of the estimates that the same
    weight (``cov``) gives on the simulated records (their equations ``sets``, prepared
    at ``theta``, the truth of their simulation), where that spread exceeds the Laplace
    sd beyond chance (:func:`hosid.inference.correction.widening` on :math:`n - 1`
    degrees of freedom; relative for the positive parameters ``logs``).

    The equations' curvature understates the estimator's spread where the filter sits
    at the resonance: the roots of the oscillator and of the filter repel, and the
    estimate moves along their exchange.  Measured on 10 records of the ship-roll-like
    oscillator under the narrow filter at its resonance (independent simulator, 4000 s,
    seeds of our own): the simulated records' estimates scattered 1.67, 1.56, 1.51 and
    1.44 times the Laplace sd of ``a2``, ``wf``, ``n2`` and ``S0`` on average (0.91-1.05
    for ``a1``, ``n1`` and ``zf``; 1.09-1.32 under the broad filter there).
    """
    draws = []
    for sets_r in sets:
        try:
            q = quasi_likelihood(sets_r, n_params=len(theta), covariance=cov)
        except ValueError:
            continue
        d = solve(q, theta, log_params=logs, scale=0.1 * scale, lower=lower, upper=upper)
        if np.all(np.isfinite(d)):
            draws.append(d)
    if len(draws) < 3:
        return ql
    positive = np.zeros(len(theta), dtype=bool)
    positive[list(logs)] = True
    spread = relative(np.array(draws), positive).std(axis=0, ddof=1)
    widen = widening(spread, laplace_sd(ql, new, scale, positive), len(draws) - 1)
    if np.all(widen == 1.0):
        return ql
    return shifted(ql, np.zeros(len(theta)), positive, len(draws), centre=new, widen=widen,
                   shift=False)  # fmt: skip
