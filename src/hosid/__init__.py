r"""hosid: Bayesian, output-only identification of randomly excited nonlinear oscillators.

.. math:: \ddot x + a_1\dot x + n_1\dot x|\dot x| + a_2x + n_2x^3 = f(t),

:math:`f` white noise of two-sided level :math:`S_0`, identified from the measured
:math:`x(t)` alone.  The data flow one way:
record -> state -> likelihood components -> calibrated quasi-likelihood -> emcee ->
arviz ``DataTree`` -> report (:mod:`hosid.record`, :mod:`hosid.state`,
:mod:`hosid.components`, :mod:`hosid.inference`, :mod:`hosid.output`); the model (terms,
priors, simulator, information limit) lives in :mod:`hosid.model`, the discrepancy
workflow in :mod:`hosid.check`.

The names below are imported when first used (``from hosid import fit`` works as
always), so that ``import hosid`` and the command line's parser do not load numba,
scipy, xarray, arviz or matplotlib until a command needs them.
"""

from __future__ import annotations

import importlib
from importlib.metadata import PackageNotFoundError, version

from .errors import HosidInputError

try:  # the version in pyproject.toml, as installed: its single source
    __version__ = version("hosid")
except PackageNotFoundError:  # pragma: no cover - a source tree that was never installed
    __version__ = "0+unknown"

#: Where each public name lives (imported on first use, :func:`__getattr__`).
_LAZY = {
    "components_for": "hosid.inference",
    "estimate": "hosid.inference",
    "fit": "hosid.inference",
    "FitOptions": "hosid.inference",
    "PAPER_PARAMS": "hosid.model",
    "System": "hosid.model",
    "simulate_chain": "hosid.model",
    "Model": "hosid.model",
    "simulate": "hosid.model",
    "Record": "hosid.record",
    "read_record": "hosid.record",
    "write_record": "hosid.record",
}

__all__ = [
    "PAPER_PARAMS",
    "FitOptions",
    "HosidInputError",
    "Model",
    "Record",
    "System",
    "components_for",
    "estimate",
    "fit",
    "read_record",
    "simulate",
    "simulate_chain",
    "write_record",
]


def __getattr__(name: str):
    """Import a public name's module on first use (PEP 562) and keep the name here."""
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module 'hosid' has no attribute {name!r}")
    value = getattr(importlib.import_module(module), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted({*globals(), *__all__})
