r"""Figures of a fit: corner, likelihood map, restoring force, traces, spectrum.

Every function takes a fit's ``DataTree`` (:mod:`hosid.output.results`) and returns a
new :class:`matplotlib.figure.Figure`, made without ``pyplot`` (no global figure
registry, no backend switch): it renders with Agg through ``fig.savefig`` whatever the
session's backend.  Axis labels carry units (:mod:`hosid.output.labels`).
"""

from __future__ import annotations

import math

import numpy as np
import xarray as xr
from matplotlib.figure import Figure

from .labels import fit_title, known_truths, label, length_unit
from .results import attr, parameter_names

__all__ = [
    "MAX_DRAWS",
    "QUANTILES",
    "corner_plot",
    "likelihood_map_plot",
    "prepare_corner",
    "restoring_force_plot",
    "trace_plot",
]

#: Quantiles marked in the corner plot and spanned by the bands.
QUANTILES = (0.05, 0.5, 0.95)
#: Most posterior draws drawn as points or curves (evenly thinned; corner plot: ten times).
MAX_DRAWS = 2000

# figures with their K x K axes made ahead of the corner plot (prepare_corner), by K
_SPARE: dict[int, Figure] = {}

# stiffness coefficients and the power of x each multiplies
_STIFFNESS = {"a2": 1, "b2": 2, "n2": 3}


def _draws(tree: xr.DataTree, name: str) -> np.ndarray:
    """All draws of a posterior variable, flattened over walkers and steps."""
    return np.asarray(tree["posterior"][name].values, dtype=float).ravel()


def _thin(n: int, most: int = MAX_DRAWS) -> np.ndarray:
    """At most ``most`` evenly spaced indices into ``range(n)``."""
    if n <= most:
        return np.arange(n)
    return np.unique(np.linspace(0, n - 1, most).round().astype(int))


def _axes(tree: xr.DataTree, heading: str, size: tuple[float, float] = (5.5, 4.0)):
    """A new figure with one axes titled ``heading`` over the fit's title."""
    fig = Figure(figsize=size, layout="constrained")
    ax = fig.add_subplot()
    ax.set_title(f"{heading}\n{fit_title(tree)}", fontsize=9)
    return fig, ax


def _range(column: np.ndarray) -> tuple[float, float]:
    """Plot range of a column, widened when the column is constant."""
    lo, hi = float(np.min(column)), float(np.max(column))
    if lo == hi:
        pad = 0.5 * abs(lo) if lo else 1.0
        lo, hi = lo - pad, hi + pad
    return lo, hi


def corner_plot(tree: xr.DataTree) -> Figure:
    """Corner plot of the sampled parameters and ``a1eq``, truths marked when known.

    ``a1eq`` is left out when it equals a sampled parameter (a linear model's ``a1``).
    The 5 %, 50 % and 95 % quantiles are marked and quoted in the titles.

    Parameters
    ----------
    tree : xarray.DataTree
        A fit (:mod:`hosid.output.results`).

    Returns
    -------
    matplotlib.figure.Figure
        ``K x K`` axes for ``K`` variables.
    """
    import corner

    names = parameter_names(tree)
    if "a1eq" in tree["posterior"].data_vars:
        a1eq = _draws(tree, "a1eq")
        if not any(np.array_equal(a1eq, _draws(tree, p)) for p in names):
            names.append("a1eq")
    data = np.column_stack([_draws(tree, p) for p in names])
    data = data[_thin(len(data), 10 * MAX_DRAWS)]
    known = known_truths(tree)
    truths = [known.get(p) for p in names]
    length = length_unit(tree)
    k = len(names)
    fig = _SPARE.pop(k, None) or _corner_figure(k)
    corner.corner(
        data,
        fig=fig,
        range=[_range(c) for c in data.T],
        labels=[label(p, length) for p in names],
        truths=truths if any(t is not None for t in truths) else None,
        quantiles=list(QUANTILES),
        show_titles=True,
        title_fmt=".3g",
        title_kwargs={"fontsize": 8},
        label_kwargs={"fontsize": 9},
    )
    fig.suptitle(f"Posterior\n{fit_title(tree)}", fontsize=10)
    return fig


def _corner_figure(k: int) -> Figure:
    """An empty figure for a corner plot of ``k`` variables."""
    return Figure(figsize=(1.6 * k + 1.0, 1.6 * k + 1.0))


def prepare_corner(k: int) -> None:
    """Make the next :func:`corner_plot` of ``k`` variables's figure and its ``k x k``
    axes now, as :func:`corner.corner` would (a third of the plot's time at ``k = 6``):
    the figure processes do it while the command fits (:mod:`hosid.output.render`).
    A corner plot of another size makes its own.
    """
    if k > 0 and k not in _SPARE:
        fig = _corner_figure(k)
        fig.subplots(k, k)
        _SPARE[k] = fig


def _levels(delta: np.ndarray) -> np.ndarray | None:
    """Contour levels of a log-likelihood drop: geometric from 0.5, two per decade."""
    finite = delta[np.isfinite(delta)]
    top = float(finite.max()) if finite.size else 0.0
    if not top > 0.5:
        return None
    return np.geomspace(0.5, top, int(np.clip(math.ceil(2 * math.log10(top / 0.5)) + 1, 3, 20)))


def likelihood_map_plot(tree: xr.DataTree) -> Figure | None:
    r"""The quasi-log-likelihood over :math:`(a_1, n_1)` with the posterior draws on top.

    Contours of :math:`\log_{10}(\max\ell - \ell)`, from a drop of 0.5, of the
    ``likelihood_map`` group (other parameters at the estimate): the valley of J2 along constant
    :math:`a_{1eq}` and, without the constraint, the twin minima of J4 (paper
    Figures 7-8).  The line of zero equivalent damping, eq (65),

    .. math:: a_1 + n_1 \sqrt{8/\pi}\,\sigma_{\dot x} = 0,

    is dashed, and the side where :math:`a_{1eq} < 0` is shaded as inadmissible when
    the fit was constrained.  The truth is starred when known.

    Parameters
    ----------
    tree : xarray.DataTree
        A fit (:mod:`hosid.output.results`).

    Returns
    -------
    matplotlib.figure.Figure or None
        One axes and a colour bar; ``None`` when the fit has no ``likelihood_map``.
    """
    if "likelihood_map" not in tree.children:
        return None
    lmap = tree["likelihood_map"]
    a1 = np.asarray(lmap["a1"].values, dtype=float)
    n1 = np.asarray(lmap["n1"].values, dtype=float)
    ll = np.asarray(lmap["log_likelihood"].values, dtype=float)
    length = length_unit(tree)
    fig, ax = _axes(tree, "Quasi-log-likelihood, other parameters at the estimate", (6.0, 4.5))
    delta = np.nanmax(np.where(np.isfinite(ll), ll, np.nan)) - ll
    levels = _levels(delta)
    if levels is not None:
        surface = np.log10(np.clip(np.nan_to_num(delta, nan=levels[-1]), 0.25, levels[-1]))
        cs = ax.contour(a1, n1, surface.T, levels=np.log10(levels), cmap="viridis")
        fig.colorbar(cs, ax=ax, format="%.1f", label=r"$\log_{10}(\max\ell - \ell)$")
    pa, pn = _draws(tree, "a1"), _draws(tree, "n1")
    idx = _thin(pa.size)
    ax.scatter(pa[idx], pn[idx], s=2, alpha=0.3, color="C3", label="posterior draws", zorder=2)
    known = known_truths(tree)
    if "a1" in known and "n1" in known:
        ax.plot(known["a1"], known["n1"], "k*", markersize=11, label="truth", zorder=3)
    sigma_v = attr(tree, "sigma_v")
    if sigma_v is not None and float(sigma_v) > 0:
        boundary = -a1 / (math.sqrt(8 / math.pi) * float(sigma_v))  # eq (65): a1eq = 0
        ax.plot(a1, boundary, "k--", linewidth=1.0, label=r"$a_{1\mathrm{eq}} = 0$ (eq 65)")
        if int(attr(tree, "constrained", 1)):
            upper = np.clip(boundary, n1[0], n1[-1])
            ax.fill_between(a1, n1[0], upper, fc="0.8", ec="none", label="inadmissible")
    ax.set_xlim(a1[0], a1[-1])
    ax.set_ylim(n1[0], n1[-1])
    ax.set_xlabel(label("a1", length))
    ax.set_ylabel(label("n1", length))
    ax.legend(loc="best", fontsize=7)
    return fig


def _sigma_x(tree: xr.DataTree) -> float:
    r"""The record's displacement sd: ``state["sigma_x"]``, else
    :math:`(2\int S_{xx}\,d\omega)^{1/2}` over the fitted band.
    """
    state = attr(tree, "state") or {}
    if state.get("sigma_x"):
        return float(state["sigma_x"])
    obs = tree["observed_data"]
    return math.sqrt(2.0 * float(np.trapezoid(obs["Sxx"].values, obs["omega"].values)))


def restoring_force_plot(tree: xr.DataTree, *, n_x: int = 201) -> Figure | None:
    r"""Posterior of the restoring force :math:`f_R(x) = a_2 x + b_2 x^2 + n_2 x^3`.

    Median and 5-95 % band over at most :data:`MAX_DRAWS` draws, on
    :math:`|x| \le 4\sigma_x` (the record's displacement sd), with the true curve when
    known.  Terms absent from the model count as zero.

    Parameters
    ----------
    tree : xarray.DataTree
        A fit (:mod:`hosid.output.results`).
    n_x : int
        Number of displacement points.

    Returns
    -------
    matplotlib.figure.Figure or None
        One axes; ``None`` when the model has no stiffness term.
    """
    if n_x < 2:
        raise ValueError(f"n_x must be at least 2, got {n_x}")
    present = [p for p in _STIFFNESS if p in tree["posterior"].data_vars]
    if not present:
        return None
    sx = _sigma_x(tree)
    x = np.linspace(-4.0 * sx, 4.0 * sx, n_x)
    idx = _thin(_draws(tree, present[0]).size)
    force = sum(_draws(tree, p)[idx, None] * x ** _STIFFNESS[p] for p in present)
    lo, mid, hi = np.quantile(force, QUANTILES, axis=0)
    length = length_unit(tree)
    fig, ax = _axes(tree, r"Restoring force, $|x| \leq 4\sigma_x$")
    ax.fill_between(x, lo, hi, color="C0", alpha=0.3, linewidth=0, label="5-95 % band")
    ax.plot(x, mid, color="C0", label="posterior median")
    known = known_truths(tree)
    if all(p in known for p in present):
        ax.plot(x, sum(known[p] * x ** _STIFFNESS[p] for p in present), "k--", label="truth")
    ax.axhline(0.0, color="0.7", linewidth=0.5)
    ax.axvline(0.0, color="0.7", linewidth=0.5)
    terms = " + ".join({"a2": "a_2 x", "b2": "b_2 x^2", "n2": "n_2 x^3"}[p] for p in present)
    ax.set_xlabel(f"$x$ ({length})")
    ax.set_ylabel(f"$f_R(x) = {terms}$ ({length}/s²)")
    ax.legend(loc="best", fontsize=8)
    return fig


def trace_plot(tree: xr.DataTree, *, max_walkers: int = 6) -> Figure:
    """Draws against step of a few walkers, one row per parameter and one for ``lp``.

    Parameters
    ----------
    tree : xarray.DataTree
        A fit (:mod:`hosid.output.results`).
    max_walkers : int
        Most walkers drawn (evenly chosen among all).

    Returns
    -------
    matplotlib.figure.Figure
        One axes per sampled parameter, plus one for ``lp`` when stored.
    """
    if max_walkers < 1:
        raise ValueError(f"max_walkers must be positive, got {max_walkers}")
    series = [(p, tree["posterior"][p].values) for p in parameter_names(tree)]
    if "sample_stats" in tree.children and "lp" in tree["sample_stats"].data_vars:
        series.append(("lp", tree["sample_stats"]["lp"].values))
    n_chain, n_draw = series[0][1].shape
    chains = _thin(n_chain, max_walkers)
    steps = _thin(n_draw)
    length = length_unit(tree)
    height = 1.1 * len(series) + 0.8
    fig = Figure(figsize=(6.5, height))  # fixed margins (inches): half the cost of a layout
    fig.subplots_adjust(left=0.85 / 6.5, right=0.98, bottom=0.5 / height, top=1 - 0.5 / height)
    axes = fig.subplots(len(series), 1, sharex=True, squeeze=False)[:, 0]
    for ax, (name, values) in zip(axes, series, strict=True):
        values = np.asarray(values, dtype=float)
        for c in chains:
            ax.plot(steps, values[c, steps], linewidth=0.6, alpha=0.8)
        ax.set_ylabel(label(name, length), fontsize=8)
        ax.tick_params(labelsize=7)
    axes[-1].set_xlabel("step after burn-in")
    axes[0].set_title(
        f"Traces of {len(chains)} of {n_chain} walkers\n{fit_title(tree)}", fontsize=9
    )
    return fig


def mode_shapes_plot(tree: xr.DataTree) -> Figure | None:
    """A system's mode shapes drawn along the chain (the ground at 0, then its dofs in
    the system's order), one panel a mode: at the record's response level (solid) and at
    small amplitude (dashed), titled with the frequency and damping ratio; ``None`` for a
    single oscillator (:mod:`hosid.model.modal`).
    """
    modes, small = attr(tree, "modes") or [], attr(tree, "modes_small_amplitude") or []
    dofs = (attr(tree, "system") or {}).get("dofs") or []
    if not modes or len(dofs) < 2:
        return None
    fig = Figure(figsize=(min(2.2 * len(modes) + 1.0, 12.0), 3.8), layout="constrained")
    axes = fig.subplots(1, len(modes), sharey=True, squeeze=False)[0]
    levels = np.arange(len(dofs) + 1)
    for k, (ax, m) in enumerate(zip(axes, modes, strict=True)):
        ax.plot([0.0, *m["shape"]], levels, "o-", color="C0", label="response level")
        if k < len(small):
            ax.plot([0.0, *small[k]["shape"]], levels, "s--", color="C1", label="small amplitude")
        ax.axvline(0.0, color="0.7", lw=0.8)
        f, z = m["frequency_hz"]["mean"], m["damping_ratio"]["mean"]
        ax.set_title(f"mode {k + 1}: {f:.4g} Hz, ζ {z:.3g}", fontsize=9)
        ax.set_xlim(-1.15, 1.15)
        ax.set_xlabel("shape")
    axes[0].set_yticks(levels, ["ground", *dofs])
    axes[0].legend(fontsize=7, loc="lower left")
    fig.suptitle(f"Mode shapes\n{fit_title(tree)}", fontsize=9)
    return fig
