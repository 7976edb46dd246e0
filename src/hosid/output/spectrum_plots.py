r"""Figures of a fit's spectra: the response against its linear equivalent, and the
inferred force against the excitation model.

Like :mod:`hosid.output.plots`, every function takes a fit's ``DataTree`` and returns a
new :class:`matplotlib.figure.Figure`.
"""

from __future__ import annotations

import numpy as np
import xarray as xr
from matplotlib.figure import Figure

from ..model.excitation import Spectrum
from .labels import length_unit
from .plots import _axes, _draws, _sigma_x, _thin
from .results import attr, stored_model

__all__ = ["force_spectrum_plot", "spectrum_plot"]


def _shape_draws(tree: xr.DataTree, omega: np.ndarray, most: int | None = 400):
    r"""The fitted force spectrum :math:`S_0L(\omega)` at the posterior draws (at most
    ``most`` of them, evenly thinned),
    ``(draws, omega)``, or ``None`` when the posterior lacks a parameter of the model.
    """
    model = stored_model(tree)
    post = tree["posterior"].data_vars
    if model is None:
        return None
    if not all(p in post for p in model.param_names):
        return None
    n = _draws(tree, model.param_names[0]).size
    idx = np.arange(n) if most is None else _thin(n, most)
    theta = np.column_stack([_draws(tree, p)[idx] for p in model.param_names])
    spectrum = Spectrum(model)
    return spectrum.S0(theta)[:, None] * spectrum.shape(omega, theta)


def _median_level(tree: xr.DataTree, omega: np.ndarray) -> np.ndarray | None:
    r"""The posterior median of :math:`S_0L(\omega)` at every ``omega`` over all draws, or
    ``None`` (:func:`_shape_draws`).  A shape that no parameter moves (white noise, a
    measured table) scales every draw alike: the median of :math:`S_0` times the shape,
    without the ``(draws, omega)`` array.
    """
    model = stored_model(tree)
    if model is None or not all(p in tree["posterior"].data_vars for p in model.param_names):
        return None
    spectrum = Spectrum(model)
    if spectrum.i_wb is None and not any(t.params for t, _ in spectrum.terms):
        theta = np.array([[float(_draws(tree, p)[0]) for p in model.param_names]])
        return float(np.median(_draws(tree, "S0"))) * spectrum.shape(omega, theta)[0]
    return np.median(_shape_draws(tree, omega, None), axis=0)


def spectrum_plot(tree: xr.DataTree) -> Figure | None:
    r"""The record's displacement spectrum and the fit's linear-equivalent prediction.

    The prediction is

    .. math:: S_{xx}(\omega) \approx \frac{S_0L(\omega)}{(a_{2eq} - \omega^2)^2 +
              a_{1eq}^2\omega^2}, \qquad a_{2eq} = \sigma_{\dot x}^2 / \sigma_x^2,

    at the posterior median of :math:`S_0L` (the excitation's shape, 1 for white noise)
    and of :math:`a_{1eq}`, with the fit's ``sigma_v`` and the record's ``sigma_x``.

    Parameters
    ----------
    tree : xarray.DataTree
        A fit (:mod:`hosid.output.results`).

    Returns
    -------
    matplotlib.figure.Figure or None
        One axes, logarithmic in the spectrum; ``None`` for a system's fit.
    """
    obs = tree["observed_data"]
    if "Sxx" not in obs:  # a system's: one spectrum a dof
        return None
    omega = np.asarray(obs["omega"].values, dtype=float)
    sxx = np.asarray(obs["Sxx"].values, dtype=float)
    length = length_unit(tree)
    fig, ax = _axes(tree, "Displacement spectrum")
    ax.plot(omega, sxx, color="0.4", linewidth=0.8, label="record (block average)")
    post = tree["posterior"].data_vars
    state = attr(tree, "state") or {}
    sigma_v = attr(tree, "sigma_v", state.get("sigma_v"))
    level = _median_level(tree, omega)
    if "a1eq" in post and level is not None and sigma_v is not None:
        a2eq = float(sigma_v) ** 2 / _sigma_x(tree) ** 2
        a1eq = float(np.median(_draws(tree, "a1eq")))
        model = level / ((a2eq - omega**2) ** 2 + a1eq**2 * omega**2)
        ax.plot(omega, model, color="C3", label="linear equivalent, posterior median")
    ax.set_yscale("log")
    ax.set_xlabel(r"$\omega$ (rad/s)")
    ax.set_ylabel(rf"$S_{{xx}}(\omega)$ ({length}² s)")
    ax.legend(loc="best", fontsize=8)
    return fig


def force_spectrum_plot(tree: xr.DataTree) -> Figure | None:
    r"""The inferred force's spectrum against the excitation model.

    The record's force inferred at the estimate, :math:`f = \ddot x + \sum_k\hat
    \theta_k\phi_k` (eq 45), as a block-averaged periodogram (``observed_data`` ``force``),
    and the fitted :math:`S_0L(\omega)`: posterior median and 5-95 % band.  Where they
    part, the excitation model does not describe the record (a white model under a
    narrow-band force shows a peak it cannot follow).  ``None`` for a fit without the
    force's periodogram.
    """
    obs = tree["observed_data"]
    if "force" not in obs:
        return None
    omega = np.asarray(obs["omega"].values, dtype=float)
    force = np.asarray(obs["force"].values, dtype=float)
    length = length_unit(tree)
    fig, ax = _axes(tree, "Inferred force and the excitation model")
    ax.plot(omega, force, color="0.4", linewidth=0.8, label="inferred force (block average)")
    model = _shape_draws(tree, omega)
    if model is not None:
        lo, med, hi = np.quantile(model, [0.05, 0.5, 0.95], axis=0)
        ax.fill_between(omega, lo, hi, color="C3", alpha=0.25, linewidth=0)
        ax.plot(omega, med, color="C3", label=r"$S_0L(\omega)$, posterior median, 5-95 %")
    ax.set_yscale("log")
    ax.set_xlabel(r"$\omega$ (rad/s)")
    ax.set_ylabel(rf"$S_{{ff}}(\omega)$ ({length}²/s³)")
    ax.legend(loc="best", fontsize=8)
    return fig
