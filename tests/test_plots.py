"""Figures of a fit: structure (axes, labels, lines), never pixels.

The trees are SYNTHETIC (``synthetic_fit``): Gaussian draws, not a sampler's output.
"""

import math

import matplotlib.pyplot as plt
import numpy as np
import pytest
from matplotlib.collections import PathCollection, PolyCollection

from hosid import plots
from synthetic_fit import SIGMA_V, TRUTHS, synthetic_tree

LABELS = ["$a_1$", "$n_1$", "$a_2$", "$n_2$", "$S_0$"]


@pytest.fixture(scope="module")
def tree():
    return synthetic_tree()


def line(ax, label):
    (found,) = [ln for ln in ax.get_lines() if ln.get_label() == label]
    return found


def test_label():
    assert plots.label("a1") == "$a_1$"
    assert plots.label("S0") == "$S_0$"
    assert plots.label("b12") == "$b_{12}$"
    assert plots.label("gamma") == "gamma"


def test_corner_has_5x5_axes_labels_and_truths(tree):
    fig = plots.corner_plot(tree)
    axes = np.array(fig.axes).reshape(5, 5)
    assert [ax.get_xlabel() for ax in axes[-1]] == LABELS
    assert [ax.get_ylabel() for ax in axes[1:, 0]] == LABELS[1:]
    assert all(not ax.get_frame_on() for i in range(5) for ax in axes[i, i + 1 :])
    for i, name in enumerate(TRUTHS):
        # diagonal: 3 quantile lines and the truth line
        xs = sorted(ln.get_xdata()[0] for ln in axes[i, i].get_lines())
        assert len(xs) == 4
        assert any(x == TRUTHS[name] for x in xs)
        assert axes[i, i].get_title().startswith(LABELS[i][:-1])
    assert "J4A" in fig.texts[0].get_text()


def test_corner_without_truths_and_subset():
    fig = plots.corner_plot(synthetic_tree(truths=False), params=["a1", "a1eq"])
    axes = np.array(fig.axes).reshape(2, 2)
    assert [ax.get_xlabel() for ax in axes[-1]] == ["$a_1$", r"$a_{1\mathrm{eq}}$"]
    assert len(axes[0, 0].get_lines()) == 3  # the quantiles, no truth
    with pytest.raises(ValueError, match="not in the posterior: zeta"):
        plots.corner_plot(synthetic_tree(), params=["a1", "zeta"])


def test_contour_map_draws_boundary_and_truth(tree):
    fig = plots.contour_plot(tree)
    assert len(fig.axes) == 2  # the plane and the colour bar
    ax = fig.axes[0]
    assert (ax.get_xlabel(), ax.get_ylabel()) == ("$a_1$", "$n_1$")
    assert "J4A" in ax.get_title()
    assert "constrained" in ax.get_title()
    assert "unconstrained" not in ax.get_title()
    boundary = line(ax, "a1eq = 0")
    assert boundary.get_linestyle() == "--"
    a1, n1 = boundary.get_data()
    np.testing.assert_allclose(a1 + n1 * math.sqrt(8 / math.pi) * SIGMA_V, 0, atol=1e-12)
    truth = line(ax, "truth")
    assert (truth.get_xdata()[0], truth.get_ydata()[0]) == (TRUTHS["a1"], TRUTHS["n1"])
    (scatter,) = [c for c in ax.collections if isinstance(c, PathCollection)]
    assert scatter.get_label() == "posterior draws"
    assert len(scatter.get_offsets()) == plots.MAX_DRAWS  # 3200 draws thinned
    assert ax.collections[0].levels.size > 1  # the cost contours
    legend = [t.get_text() for t in ax.get_legend().get_texts()]
    assert "a1eq = 0" in legend


def test_contour_without_cost_map_or_sigma_v():
    tree = synthetic_tree(cost_map=False, truths=False)
    tree.attrs["constrained"] = 0
    del tree.attrs["sigma_v"]
    fig = plots.contour_plot(tree)
    assert len(fig.axes) == 1
    ax = fig.axes[0]
    assert "unconstrained" in ax.get_title()
    assert [ln.get_label() for ln in ax.get_lines()] == []
    assert len(ax.collections) == 1  # only the draws


def test_contour_keeps_few_draws():
    fig = plots.contour_plot(synthetic_tree(n_chain=4, n_draw=100))
    (scatter,) = [c for c in fig.axes[0].collections if isinstance(c, PathCollection)]
    assert len(scatter.get_offsets()) == 400


def test_restoring_force_band_median_truth(tree):
    fig = plots.restoring_force_plot(tree, n_x=51)
    (ax,) = fig.axes
    (band,) = [c for c in ax.collections if isinstance(c, PolyCollection)]
    assert band.get_label() == "90 % band"
    x, median = line(ax, "posterior median").get_data()
    assert len(x) == 51
    assert (x[0], x[-1]) == (-0.8, 0.8)
    x_true, true = line(ax, "truth").get_data()
    np.testing.assert_allclose(true, TRUTHS["a2"] * x_true + TRUTHS["n2"] * x_true**3)
    # the band brackets the median everywhere
    vertices = band.get_paths()[0].vertices
    assert vertices[:, 1].min() <= median.min()
    assert vertices[:, 1].max() >= median.max()
    assert ax.get_xlabel() == "$x$"


def test_restoring_force_x_max_fallback():
    tree = synthetic_tree(truths=False)
    del tree.attrs["x_max"]
    fig = plots.restoring_force_plot(tree)
    x = line(fig.axes[0], "posterior median").get_xdata()
    post = tree["posterior"]
    c, k, s0 = (float(np.median(post[v].values)) for v in ("a1eq", "a2", "S0"))
    assert x[-1] == pytest.approx(3 * math.sqrt(math.pi * s0 / (c * k)))
    assert [ln.get_label() for ln in fig.axes[0].get_lines()].count("truth") == 0
    with pytest.raises(ValueError, match="n_x"):
        plots.restoring_force_plot(tree, n_x=1)


def test_trace_rows_and_walkers(tree):
    fig = plots.trace_plot(tree, max_walkers=4)
    assert [ax.get_ylabel() for ax in fig.axes] == [*LABELS, r"$\log p$"]
    assert all(len(ax.get_lines()) == 4 for ax in fig.axes)
    assert fig.axes[-1].get_xlabel() == "step"
    assert len(fig.axes[0].get_lines()[0].get_xdata()) == 200
    assert len(plots.trace_plot(tree).axes[0].get_lines()) == 8


def test_figures_stay_out_of_pyplot(tree):
    before = plt.get_fignums()
    plots.contour_plot(tree)
    plots.trace_plot(tree)
    assert plt.get_fignums() == before
