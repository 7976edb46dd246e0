"""Model checking: discrepancy measures, posterior-predictive gaps and ``diagnose``.

:mod:`~hosid.check.measures` (the statistics a missing effect leaves its mark on),
:mod:`~hosid.check.gaps` (the record's standardized distance from replicates),
:mod:`~hosid.check.posterior` (parameter draws for the replicates),
:mod:`~hosid.check.model_check` (one model against the record),
:mod:`~hosid.check.evidence` (what the fit of model + effect says about the effect),
:mod:`~hosid.check.selection` (the calibrated decision of one round),
:mod:`~hosid.check.diagnose` (the workflow that names the missing effects: import
``diagnose`` from there, so that the submodule's name stays the module's) and
:mod:`~hosid.check.report` (its report content).
"""

from .diagnose import Diagnosis, Step
from .evidence import Evidence, screen, weigh
from .gaps import gaps, robust_z
from .measures import MeasureSpec, compare, drift_function, measures
from .model_check import ModelCheck, check_model

__all__ = [
    "Diagnosis",
    "Evidence",
    "MeasureSpec",
    "ModelCheck",
    "Step",
    "check_model",
    "compare",
    "drift_function",
    "gaps",
    "measures",
    "robust_z",
    "screen",
    "weigh",
]
