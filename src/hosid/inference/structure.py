r"""What a fit needs to know of what it fits: a single oscillator's model or a system.

:func:`hosid.inference.fit.fit` is one path for both; the few places where they differ
are here: which description a call names (:func:`resolve`), the damping coefficients,
eq (65)'s derived variables (``a1eq``, or one per damped element, ``a1eq[ground-x1]``),
the observed spectra (the displacement's and the inferred force's, one pair a dof for a
system: ``Sxx[x1]``, ``force[x1]``), and the attributes that name the description
(``model``, and for a system ``system``, :meth:`hosid.model.system.System.describe`).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from ..components.spectral import default_band, force_periodogram
from ..errors import HosidInputError
from ..model.measured import shape_attrs
from ..model.model import Model
from ..model.system import System
from ..model.system_priors import constraint_name, damped, equivalent_damping

__all__ = ["damping_columns", "derived", "describe", "modal", "observed", "resolve"]


def resolve(system, model) -> Model | System:
    """The description a fit names: ``system`` or ``model``, each a System, a system
    file's path (``.toml``), a Model or a model spec (default ``"paper"``).

    Raises
    ------
    HosidInputError
        If both are given, or the file does not describe a system.
    """
    if system is not None and model is not None:
        raise HosidInputError("give a system or a model, not both")
    given = system if system is not None else (model or "paper")
    if isinstance(given, System):
        return given
    if isinstance(given, str | Path) and str(given).lower().endswith(".toml"):
        return System.from_toml(given)
    return Model.from_spec(given)


def damping_columns(structure: Model | System) -> list[int]:
    """The positions of the damping (velocity) coefficients in ``theta``."""
    if isinstance(structure, System):
        return [c for c, (_, t) in enumerate(structure.columns) if t.variable == "v"]
    return [i for i, t in enumerate(structure.drift_terms) if t.variable == "v"]


def derived_names(structure: Model | System) -> list[str]:
    """The names of :func:`derived`'s variables (a single oscillator's ``a1eq`` or none)
    for a model; for a system, those of its elements.
    """
    if isinstance(structure, Model):
        damping = damping_columns(structure)
        terms = structure.drift_terms
        more = len(damping) > 1 or (damping and terms[damping[0]].params != ("a1",))
        return ["a1eq"] if more else []
    return [constraint_name(structure, e) for e in _more_than_a1(structure)]


def _more_than_a1(structure: System) -> list[int]:
    """The damped elements of ``structure`` with more damping than ``a1`` alone."""
    out = []
    for e in damped(structure):
        params = [t.params for t in structure.elements[e].terms if t.variable == "v"]
        if len(params) > 1 or params != [("a1",)]:
            out.append(e)
    return out


def derived(structure: Model | System, theta: np.ndarray, sigma_v) -> dict[str, np.ndarray]:
    """Eq (65)'s equivalent damping of ``theta`` ``(..., p)``: ``a1eq`` of a model (or an
    element) with more damping than ``a1`` alone, one variable an element of a system
    (:func:`derived_names`).
    """
    if isinstance(structure, Model):
        if derived_names(structure):
            return {"a1eq": structure.equivalent_damping(theta, sigma_v)}
        return {}
    out = {}
    eq = equivalent_damping(structure, theta, np.atleast_1d(sigma_v))
    for e in _more_than_a1(structure):
        out[constraint_name(structure, e)] = eq[..., e]
    return out


def observed(est, theta: np.ndarray, omega_max: float | None) -> dict[str, np.ndarray]:
    """``omega``, the displacement's block periodogram and the force inferred at
    ``theta`` (eq 45) on the J2 band, per dof for a system (module docstring).
    """
    structure, state = est.model, est.state
    if isinstance(structure, Model):
        band = (0.0, float(omega_max)) if omega_max is not None else default_band(state)
        bins = state.layout.bins(*band, k_min=1)
        return {
            "omega": bins * state.layout.d_omega,
            "Sxx": state.periodogram("x", bins),
            "force": force_periodogram(state, structure, theta, bins),
        }
    from ..components.chain_features import force_ffts, lam, restoration
    from ..components.chain_spectral import chain_band

    L = state.layout
    lo, hi = chain_band(state)
    bins = L.bins(lo, hi, k_min=1)
    norm = 2 * math.pi * L.T * state.window.k2
    rest = restoration(state, structure, theta)
    out = {"omega": bins * L.d_omega}
    for d, dof in enumerate(structure.dofs):
        Q = state.block_fft(("q", d), lambda b, d=d: b["q"][d], bins)
        X = np.tensordot(lam(structure, theta, d), force_ffts(state, structure, d, rest, bins), 1)
        tag = "" if structure.single_names else f"[{dof}]"
        out[f"Sxx{tag}"] = np.mean(Q.real**2 + Q.imag**2, axis=0) / norm
        out[f"force{tag}"] = np.mean(X.real**2 + X.imag**2, axis=0) / norm
    return out


def modal(est, theta: np.ndarray) -> dict:
    """The modal view over the posterior draws ``theta`` ``(..., p)``
    (:mod:`hosid.model.modal`): the attributes ``modes`` (at the record's response level),
    ``modes_small_amplitude`` and ``modes_linearisation``.  A single oscillator's model is
    its one-element chain's drift (the excitation's own parameters play no part).
    """
    from ..model.modal import LINEARISATION, response_slopes, small_slopes, summarize_modes

    structure = est.model
    if isinstance(structure, System):
        from ..components.chain_features import relative

        r, rd = relative(est.state, structure)
    else:
        drift = tuple(t.name for t in structure.drift_terms if t.variable in ("x", "v"))
        if not drift:
            return {}
        one = System(("x",), [(("ground", "x"), drift)], single_names=True)
        theta = np.asarray(theta)[..., [structure.param_names.index(n) for n in one.param_names]]
        structure, r, rd = one, est.state.x[None], est.state.v[None]
    slopes = response_slopes(structure, r, rd)
    return {
        "modes": summarize_modes(structure, theta, slopes),
        "modes_small_amplitude": summarize_modes(structure, theta, small_slopes(structure)),
        "modes_linearisation": LINEARISATION["response"],
    }


def describe(structure: Model | System) -> dict:
    """The attributes that name what was fitted: ``model`` (term names; a system's
    elements as ``"x1-x2: linear_damping + linear_stiffness"``) and ``system``.
    """
    if isinstance(structure, Model):
        return {"model": list(structure.names), **shape_attrs(structure)}
    return {"model": list(structure.names), "system": structure.describe()}
