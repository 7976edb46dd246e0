r"""What the figures and the report call a fit's quantities: symbols, units, the truths
and the title, without matplotlib (the report's page and summary are written by a
process that draws no figure: :mod:`hosid.output.render`).

The displacement unit is the root attribute ``unit`` when stored, else metres.
"""

from __future__ import annotations

import re

import xarray as xr

from .results import attr, stored_model

__all__ = ["fit_title", "known_truths", "label", "length_unit", "unit"]

# symbol and unit of each variable, ``{u}`` the displacement unit (force per unit mass)
_VARIABLES = {
    "a1": ("a_1", "1/s"),
    "n1": ("n_1", "1/{u}"),
    "a2": ("a_2", "1/s²"),
    "n2": ("n_2", "1/({u}² s²)"),
    "b2": ("b_2", "1/({u} s²)"),
    "S0": ("S_0", "{u}²/s³"),
    "a1eq": (r"a_{1\mathrm{eq}}", "1/s"),
    "mu": (r"\mu", "{u}/s²"),
    "m": ("m", "{u}/s²"),
    "wc": (r"\omega_c", "rad/s"),
    "wf": (r"\omega_f", "rad/s"),
    "zf": (r"\zeta_f", ""),
    "noise_sd": (r"\sigma_\epsilon", "{u}"),
    "lp": (r"\log p", ""),
}


def length_unit(tree: xr.DataTree) -> str:
    """Unit of the displacement: the root attribute ``unit``, else ``"m"``."""
    return str(attr(tree, "unit", None) or "m")


def unit(name: str, length: str = "m") -> str:
    """Unit of a parameter (``""`` when unknown): ``unit("n2") == "1/(m² s²)"``."""
    return _VARIABLES.get(name, ("", ""))[1].format(u=length)


def label(name: str, length: str = "m") -> str:
    """Mathtext axis label with unit: ``label("a1") == "$a_1$ (1/s)"``."""
    symbol = _VARIABLES.get(name, (None,))[0]
    if symbol is None:
        match = re.fullmatch(r"([A-Za-z]+)(\d+)", name)
        symbol = f"{match[1]}_{{{match[2]}}}" if match else None
    text = f"${symbol}$" if symbol else name
    u = unit(name, length)
    return f"{text} ({u})" if u else text


def known_truths(tree: xr.DataTree) -> dict[str, float]:
    r"""The stored truths, with ``a1eq`` from eq (65) when every parameter is known:
    :math:`a_{1eq} = a_1 + n_1\sqrt{8/\pi}\,\sigma_{\dot x}` (each damping term's
    factor) with the fit's ``sigma_v``.
    """
    known = {k: float(v) for k, v in (attr(tree, "truths") or {}).items() if v is not None}
    sigma_v, model = attr(tree, "sigma_v"), stored_model(tree)
    if "a1eq" not in known and sigma_v is not None and model is not None:
        if all(p in known for p in model.param_names) and model.has("a1"):
            theta = [known[p] for p in model.param_names]
            known["a1eq"] = float(model.equivalent_damping(theta, float(sigma_v)))
    return known


def fit_title(tree: xr.DataTree) -> str:
    """``record: cost, constrained``; an unnamed record by its hash."""
    name = attr(tree, "record") or f"record {attr(tree, 'record_hash', '?')}"
    kind = "constrained" if int(attr(tree, "constrained", 1)) else "unconstrained"
    return f"{name}: {attr(tree, 'cost', '?')} cost, {kind}"
