r"""
Your first fit: the paper's oscillator
======================================

Simulate the oscillator of Vasta & Roberts (1998),

.. math:: \ddot x + a_1\dot x + n_1\dot x|\dot x| + a_2x + n_2x^3 = f(t),

driven by white noise of level :math:`S_0`, then identify :math:`a_1, n_1, a_2, n_2,
S_0` from the displacement alone: first the quick estimate (mode and sd, no sampling),
then the emcee posterior as an arviz ``DataTree``, its summary, its checks and its
figures. This is what ``hosid demo`` does (the full-size record: 2000 s at
``dt = 0.02`` s, about ten seconds).
"""

# %%
# A record
# --------
# :func:`hosid.simulate` integrates the equation of motion; the only randomness is the
# generator passed in. :data:`hosid.PAPER_PARAMS` are the paper's values
# (``a1 = n1 = 0.5``, ``a2 = 25``, ``n2 = 5``) with ``S0 = 100``.
import numpy as np

import hosid

truth = dict(hosid.PAPER_PARAMS)
record = hosid.simulate(truth, duration=2000.0, dt=0.02, rng=np.random.default_rng(1))
print(truth)
print(record, f"{record.duration:.0f} s")

# %%
# The estimate: a second, no sampling
# -----------------------------------
# :func:`hosid.estimate` checks the record, solves the estimating equations and gives
# the calibrated quasi-likelihood's mode with its sd (``hosid estimate rec.csv`` on the
# command line). ``test`` is Hansen's test of whether the equations agree with each
# other: a small p-value says that the model does not describe the record (and the sd
# are widened).
est = hosid.estimate(record, "paper")
for name, value in est.values.items():
    print(f"{name:>3} = {value:8.4g} +- {est.sd[name]:.2g}   (truth {truth[name]:g})")
print(
    f"Hansen's test: J = {est.test['J']:.2f} on {est.test['df']} df, p = {est.test['p_value']:.2f}"
)

# %%
# The posterior
# -------------
# :func:`hosid.fit` samples the posterior with emcee until R-hat < 1.007 and the bulk and
# tail ESS of every parameter reach 500. The result is an arviz ``DataTree``: the
# ``posterior`` group holds every parameter and the equivalent linear damping
# ``a1eq = a1 + n1 sqrt(8/pi) sigma_v`` of the paper's eq (65).
tree = hosid.fit(record, seed=1, progress=False)
print(tree["posterior"])

# %%
# The summary and its verdicts
# ----------------------------
# :func:`hosid.output.results.summarize` is the table of ``summary.json``: quantiles,
# R-hat and ESS per parameter, and the verdicts the fit carries (the record checks, the
# calibration, the convergence). The same numbers come from arviz directly.
import arviz as az

from hosid.output.results import summarize

summary = summarize(tree)
for name, row in summary["parameters"].items():
    print(
        f"{name:>4}: mean {row['mean']:8.4g}  90 % [{row['q05']:.4g}, {row['q95']:.4g}]"
        f"  r_hat {row['r_hat']:.3f}  ess_bulk {row['ess_bulk']:.0f}"
    )
print("verdict:", summary["verdict"])
for check in summary["checks"]:
    print(f"  {check['name']:>12}: {check['status']:4}  {check['message']}")
print(az.summary(tree, var_names=["a1eq", "S0"], kind="stats", ci_prob=0.9, round_to=4))

# %%
# The figures of the report
# -------------------------
# Every plotting function of :mod:`hosid.output.plots` takes the ``DataTree`` and returns
# a :class:`matplotlib.figure.Figure` (in a notebook it displays itself; in a script
# call ``fig.savefig(...)``). The corner plot marks the true values, which a simulated
# record knows.
from hosid.output.plots import corner_plot, restoring_force_plot

corner = corner_plot(tree)

# %%
# The restoring force :math:`a_2x + n_2x^3` with its 90 % band over the range of the
# record, against the truth.
force = restoring_force_plot(tree)

# %%
# The record's response spectrum beside the fitted model's.
from hosid.output.spectrum_plots import spectrum_plot

spectrum = spectrum_plot(tree)

# %%
# The report
# ----------
# ``hosid fit rec.csv --out fit/`` writes the same ``DataTree`` as ``posterior.nc``,
# ``summary.json``, the figures and ``report.html``; from Python
# :func:`hosid.output.report.write_report` does it (here into a temporary folder).
import tempfile
from pathlib import Path

from hosid.output.report import write_report

with tempfile.TemporaryDirectory() as tmp:
    written = write_report(tree, tmp)
    print(sorted(Path(p).name for p in written))
