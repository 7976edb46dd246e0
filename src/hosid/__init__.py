r"""hosid: Bayesian, output-only identification of randomly excited nonlinear oscillators.

.. math:: \ddot x + a_1\dot x + n_1\dot x|\dot x| + a_2x + n_2x^3 = f(t),

:math:`f` white noise of two-sided level :math:`S_0`, identified from the measured
:math:`x(t)` alone.  The data flow one way:
record -> state -> likelihood components -> calibrated quasi-likelihood -> emcee ->
arviz ``DataTree`` -> report (:mod:`hosid.record`, :mod:`hosid.state`,
:mod:`hosid.components`, :mod:`hosid.inference`, :mod:`hosid.output`); the model (terms,
priors, simulator, information limit) lives in :mod:`hosid.model`, the discrepancy
workflow in :mod:`hosid.check`.
"""

__version__ = "0.2.0"

from .errors import HosidInputError
from .inference import components_for, estimate, fit
from .model import PAPER_PARAMS, Model, simulate
from .record import Record, read_record, write_record

__all__ = [
    "PAPER_PARAMS",
    "HosidInputError",
    "Model",
    "Record",
    "components_for",
    "estimate",
    "fit",
    "read_record",
    "simulate",
    "write_record",
]
