r"""Figures of a fit: corner plot, cost contours, restoring force, traces.

Every function takes a fit's ``DataTree`` (the layout of :mod:`hosid.results`)
and returns a new :class:`matplotlib.figure.Figure`. The figures are made without
``pyplot`` (no global figure registry, no backend switch), so they render with
Agg whatever the session's backend; save them with ``fig.savefig``.
"""

from __future__ import annotations

import math
import re

import numpy as np
import xarray as xr
from matplotlib.figure import Figure

from hosid import results

__all__ = ["contour_plot", "corner_plot", "label", "restoring_force_plot", "trace_plot"]

#: Quantiles marked in the corner plot and spanned by the bands.
QUANTILES = (0.05, 0.5, 0.95)
#: Most posterior draws drawn as points or curves.
MAX_DRAWS = 2000
#: Label of the eq-65 boundary line in the contour plot.
BOUNDARY_LABEL = "a1eq = 0"

_LABELS = {
    "a1": r"$a_1$",
    "n1": r"$n_1$",
    "a2": r"$a_2$",
    "n2": r"$n_2$",
    "S0": r"$S_0$",
    "a1eq": r"$a_{1\mathrm{eq}}$",
    "lp": r"$\log p$",
}


def label(name: str) -> str:
    """Mathtext label of a parameter: ``"a1"`` -> ``"$a_1$"``; unknown names as ``x_{12}``."""
    if name in _LABELS:
        return _LABELS[name]
    match = re.fullmatch(r"([A-Za-z]+)(\d+)", name)
    return rf"${match[1]}_{{{match[2]}}}$" if match else name


def _draws(tree: xr.DataTree, name: str) -> np.ndarray:
    """All draws of a posterior variable, flattened over walkers and steps."""
    return np.asarray(tree["posterior"][name].values, dtype=float).ravel()


def _thin_index(n: int, most: int = MAX_DRAWS) -> np.ndarray:
    """At most ``most`` evenly spaced indices into ``range(n)`` (deterministic)."""
    if n <= most:
        return np.arange(n)
    return np.unique(np.linspace(0, n - 1, most).round().astype(int))


def _title(tree: xr.DataTree) -> str:
    a = tree.attrs
    kind = "constrained" if int(a.get("constrained", 0)) else "unconstrained"
    name = a.get("record")
    head = f"{a.get('cost', '?')} cost, {kind}"
    return f"{name}: {head}" if name else head


def _range(column: np.ndarray) -> tuple[float, float]:
    """Plot range of a column, widened when the column is constant."""
    lo, hi = float(np.min(column)), float(np.max(column))
    if lo == hi:
        pad = 0.5 * abs(lo) if lo else 1.0
        lo, hi = lo - pad, hi + pad
    return lo, hi


def corner_plot(tree: xr.DataTree, *, params: list[str] | None = None) -> Figure:
    """Corner plot of the sampled parameters, with truths when the fit stores them.

    Parameters
    ----------
    tree : xarray.DataTree
        A fit in the layout of :mod:`hosid.results`.
    params : list of str, optional
        Posterior variables to show; the sampled parameters by default.

    Returns
    -------
    matplotlib.figure.Figure
        ``K x K`` axes for ``K`` parameters; the 5 %, 50 % and 95 % quantiles are
        marked and quoted in the titles.
    """
    import corner

    names = list(params) if params is not None else results.parameter_names(tree)
    if not names:
        raise ValueError("no parameters to plot")
    missing = [p for p in names if p not in tree["posterior"].data_vars]
    if missing:
        raise ValueError(f"not in the posterior: {', '.join(missing)}")
    data = np.column_stack([_draws(tree, p) for p in names])
    known = results.truths(tree) or {}
    truths = [known.get(p) for p in names]
    k = len(names)
    fig = Figure(figsize=(2.0 * k + 1.0, 2.0 * k + 1.0))
    corner.corner(
        data,
        fig=fig,
        range=[_range(c) for c in data.T],
        labels=[label(p) for p in names],
        truths=truths if any(t is not None for t in truths) else None,
        quantiles=list(QUANTILES),
        show_titles=True,
        title_fmt=".3g",
        title_kwargs={"fontsize": 10},
    )
    fig.suptitle(_title(tree))
    return fig


def _log_levels(delta: np.ndarray) -> np.ndarray | None:
    """Geometric contour levels of a non-negative surface, two per decade from its
    smallest positive value (at most nine decades below the top); ``None`` when flat.
    """
    positive = delta[np.isfinite(delta) & (delta > 0)]
    if positive.size == 0:
        return None
    top = float(positive.max())
    bottom = max(float(positive.min()), top * 1e-9)
    if bottom >= top:
        return None
    n = int(np.clip(math.ceil(2 * math.log10(top / bottom)) + 1, 5, 20))
    return np.geomspace(bottom, top, n)


def contour_plot(tree: xr.DataTree) -> Figure:
    r"""Cost over the :math:`(a_1, n_1)` plane with the posterior draws on top.

    The background is the ``cost_map`` group (the untempered cost with the other
    parameters at their posterior medians, shifted to a minimum of zero and
    contoured on geometric levels), as in the paper's Figures 7-8. The dashed line
    is the boundary of positive equivalent damping, eq (65),

    .. math:: a_1 + n_1 \sqrt{8/\pi}\,\sigma_{\dot x} = 0,

    drawn when the tree stores ``sigma_v``; the truth is marked when known.

    Parameters
    ----------
    tree : xarray.DataTree
        A fit in the layout of :mod:`hosid.results`; ``cost_map`` is optional.

    Returns
    -------
    matplotlib.figure.Figure
        One axes (plus a colour bar when the cost map is drawn).
    """
    fig = Figure(figsize=(6.5, 5.0), layout="constrained")
    ax = fig.add_subplot()
    if "cost_map" in tree.children:
        cmap = tree["cost_map"]
        cost = np.asarray(cmap["cost"].values, dtype=float)
        delta = cost - np.nanmin(cost)
        levels = _log_levels(delta)
        if levels is not None:
            # contours of log10(cost - min); the minimum itself is clipped below the levels
            surface = np.log10(np.maximum(np.nan_to_num(delta, nan=levels[-1]), levels[0] / 2))
            cs = ax.contour(
                np.asarray(cmap["a1"].values),
                np.asarray(cmap["n1"].values),
                surface.T,  # dims (a1, n1): rows are a1
                levels=np.log10(levels),
                cmap="viridis",
                linewidths=0.8,
            )
            fig.colorbar(cs, ax=ax, label=r"$\log_{10}$(cost $-$ min), untempered")
    a1, n1 = _draws(tree, "a1"), _draws(tree, "n1")
    idx = _thin_index(a1.size)
    ax.scatter(a1[idx], n1[idx], s=3, alpha=0.3, color="C3", label="posterior draws", zorder=2)
    known = results.truths(tree) or {}
    if "a1" in known and "n1" in known:
        ax.plot(known["a1"], known["n1"], "k*", markersize=12, label="truth", zorder=3)
    sigma_v = tree.attrs.get("sigma_v")
    if sigma_v is not None and math.isfinite(float(sigma_v)) and float(sigma_v) > 0:
        slope = math.sqrt(8 / math.pi) * float(sigma_v)
        xlim, ylim = ax.get_xlim(), ax.get_ylim()
        n_line = np.linspace(*ylim, 2)
        ax.plot(-slope * n_line, n_line, "k--", linewidth=1.0, label=BOUNDARY_LABEL)  # eq (65)
        ax.set_xlim(xlim)
        ax.set_ylim(ylim)
    ax.set_xlabel(label("a1"))
    ax.set_ylabel(label("n1"))
    ax.set_title(_title(tree))
    ax.legend(loc="best", fontsize=8)
    return fig


def _x_max(tree: xr.DataTree) -> float:
    r"""Half-width of the displacement axis.

    ``attrs["x_max"]`` when stored; else three standard deviations of the
    equivalent linear oscillator at the posterior medians,
    :math:`\sigma_x^2 = \pi S_0 / (a_{1eq} a_2)`; else 3.
    """
    stored = tree.attrs.get("x_max")
    if stored is not None and math.isfinite(float(stored)) and float(stored) > 0:
        return float(stored)
    post = tree["posterior"]
    needed = ("a1eq", "a2", "S0")
    if all(k in post.data_vars for k in needed):
        c, k, s0 = (float(np.median(_draws(tree, k))) for k in needed)
        if c > 0 and k > 0 and s0 > 0:
            return 3.0 * math.sqrt(math.pi * s0 / (c * k))
    return 3.0


def restoring_force_plot(tree: xr.DataTree, *, n_x: int = 200) -> Figure:
    r"""Posterior of the restoring force :math:`f_R(x) = a_2 x + n_2 x^3`.

    The median curve and the 90 % band over at most 2000 posterior draws, on
    ``x`` in ``[-x_max, x_max]``, with the true curve when known (the paper's
    Figure 3 with an uncertainty band).

    Parameters
    ----------
    tree : xarray.DataTree
        A fit in the layout of :mod:`hosid.results`; needs ``a2`` (``n2`` is taken
        as zero when absent).
    n_x : int, optional
        Number of displacement points.

    Returns
    -------
    matplotlib.figure.Figure
        One axes with the band, the median and, when known, the truth.
    """
    if n_x < 2:
        raise ValueError(f"n_x must be at least 2, got {n_x}")
    a2 = _draws(tree, "a2")
    n2 = _draws(tree, "n2") if "n2" in tree["posterior"].data_vars else np.zeros_like(a2)
    idx = _thin_index(a2.size)
    x_max = _x_max(tree)
    x = np.linspace(-x_max, x_max, n_x)
    force = a2[idx, None] * x + n2[idx, None] * x**3
    lo, mid, hi = np.quantile(force, QUANTILES, axis=0)
    fig = Figure(figsize=(6.0, 4.5), layout="constrained")
    ax = fig.add_subplot()
    ax.fill_between(x, lo, hi, color="C0", alpha=0.3, label="90 % band")
    ax.plot(x, mid, color="C0", label="posterior median")
    known = results.truths(tree) or {}
    if "a2" in known:
        true = known["a2"] * x + known.get("n2", 0.0) * x**3
        ax.plot(x, true, "k--", label="truth")
    ax.axhline(0.0, color="0.7", linewidth=0.5)
    ax.axvline(0.0, color="0.7", linewidth=0.5)
    ax.set_xlabel(r"$x$")
    ax.set_ylabel(r"$f_R(x) = a_2 x + n_2 x^3$")
    ax.set_title(f"Restoring force ({_title(tree)})")
    ax.legend(loc="best", fontsize=8)
    return fig


def trace_plot(tree: xr.DataTree, *, max_walkers: int = 8) -> Figure:
    """Draws against step for a few walkers, one row per parameter plus ``lp``.

    Parameters
    ----------
    tree : xarray.DataTree
        A fit in the layout of :mod:`hosid.results`.
    max_walkers : int, optional
        Most walkers drawn (evenly chosen among all).

    Returns
    -------
    matplotlib.figure.Figure
        One axes per sampled parameter, and one for ``lp`` when sampled stats hold it.
    """
    if max_walkers < 1:
        raise ValueError(f"max_walkers must be positive, got {max_walkers}")
    series = [(p, tree["posterior"][p].values) for p in results.parameter_names(tree)]
    if "sample_stats" in tree.children and "lp" in tree["sample_stats"].data_vars:
        series.append(("lp", tree["sample_stats"]["lp"].values))
    n_chain, n_draw = series[0][1].shape
    chains = _thin_index(n_chain, max_walkers)
    steps = _thin_index(n_draw)
    height = 1.6 * len(series) + 0.8
    fig = Figure(figsize=(8.0, height))
    fig.subplots_adjust(left=0.1, right=0.97, bottom=0.5 / height, top=1 - 0.4 / height)
    axes = fig.subplots(len(series), 1, sharex=True, squeeze=False)[:, 0]
    for ax, (name, values) in zip(axes, series, strict=True):
        values = np.asarray(values, dtype=float)
        for c in chains:
            ax.plot(steps, values[c, steps], linewidth=0.6, alpha=0.8)
        ax.set_ylabel(label(name))
    axes[-1].set_xlabel("step")
    axes[0].set_title(f"Traces of {len(chains)} of {n_chain} walkers ({_title(tree)})")
    return fig
