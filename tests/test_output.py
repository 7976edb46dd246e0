"""The output layer: figures (structure, not pixels), the HTML report and summary.json."""

from __future__ import annotations

import json
import math
import os
from html import escape

import numpy as np
import pytest
from matplotlib.collections import PolyCollection
from matplotlib.figure import Figure

from hosid.errors import HosidInputError
from hosid.inference import fit
from hosid.model import PAPER_PARAMS, Model, simulate
from hosid.output import labels, plots, render, spectrum_plots
from hosid.output.files import png
from hosid.output.report import CAPTIONS, draw, figures, write_report
from hosid.output.results import attr, summarize

PAPER = ["a1", "n1", "a2", "n2", "S0"]
STEMS = ["corner", "likelihood_map", "restoring_force", "trace", "spectrum", "force_spectrum"]


def _record(seed: int):
    return simulate(PAPER_PARAMS, duration=500.0, rng=np.random.default_rng(seed))


@pytest.fixture(scope="module")
def paper_fit():
    return fit(_record(11), n_steps=300, seed=1, progress=False, truths=PAPER_PARAMS)


@pytest.fixture(scope="module")
def free_fit():
    return fit(_record(12), n_steps=300, seed=2, progress=False, constrained=False)


@pytest.fixture(scope="module")
def linear_fit():
    return fit(_record(13), model="linear", n_steps=300, seed=3, progress=False)


def _legend(ax) -> list[str]:
    legend = ax.get_legend()
    return [t.get_text() for t in legend.get_texts()] if legend else []


# ------------------------------------------------------------------ labels
def test_labels_and_units():
    assert labels.label("a1") == "$a_1$ (1/s)"
    assert labels.label("n2", "mm") == "$n_2$ (1/(mm² s²))"
    assert labels.unit("S0") == "m²/s³"
    assert labels.unit("a1eq") == "1/s"
    assert labels.unit("unknown") == ""
    assert labels.label("x12") == "$x_{12}$"


def test_known_truths_derive_a1eq(paper_fit):
    known = labels.known_truths(paper_fit)
    sigma_v = paper_fit.attrs["sigma_v"]
    expected = PAPER_PARAMS["a1"] + PAPER_PARAMS["n1"] * math.sqrt(8 / math.pi) * sigma_v
    assert known["a1eq"] == pytest.approx(expected, rel=1e-12)


# ------------------------------------------------------------------ figures
def test_corner_plot_has_parameters_a1eq_units_and_titles(paper_fit):
    fig = plots.corner_plot(paper_fit)
    assert isinstance(fig, Figure)
    k = len(PAPER) + 1
    assert len(fig.axes) == k * k
    bottom = [fig.axes[(k - 1) * k + j].get_xlabel() for j in range(k)]
    assert bottom == [labels.label(p) for p in [*PAPER, "a1eq"]]
    assert "(m²/s³)" in bottom[4] and "(1/m)" in bottom[1]
    titles = [fig.axes[i * k + i].get_title() for i in range(k)]
    assert all("=" in t for t in titles)  # median with 5/95 % offsets
    # truths drawn as vertical lines on the diagonal at the true a1
    xs = [line.get_xdata()[0] for line in fig.axes[0].get_lines()]
    assert any(x == pytest.approx(PAPER_PARAMS["a1"]) for x in xs)


def test_corner_plot_linear_model_drops_redundant_a1eq(linear_fit):
    fig = plots.corner_plot(linear_fit)
    assert len(fig.axes) == 9
    assert [fig.axes[6 + j].get_xlabel() for j in range(3)] == [
        labels.label(p) for p in ("a1", "a2", "S0")
    ]


def test_likelihood_map_constrained_shades_inadmissible(paper_fit):
    fig = plots.likelihood_map_plot(paper_fit)
    ax = fig.axes[0]
    assert len(fig.axes) == 2  # the map and its colour bar
    assert ax.get_xlabel() == "$a_1$ (1/s)" and ax.get_ylabel() == "$n_1$ (1/m)"
    assert {"posterior draws", "truth", "inadmissible"} <= set(_legend(ax))
    shade = [c for c in ax.collections if isinstance(c, PolyCollection)]
    assert shade, "no shaded region"
    # the shaded polygon lies where a1 + n1 sqrt(8/pi) sigma_v <= 0 (eq 65)
    c = math.sqrt(8 / math.pi) * paper_fit.attrs["sigma_v"]
    vertices = np.concatenate([p.vertices for p in shade[-1].get_paths()])
    assert np.all(vertices[:, 0] + c * vertices[:, 1] <= 1e-9 * c)
    lmap = paper_fit["likelihood_map"]
    assert ax.get_xlim() == pytest.approx((lmap["a1"].values[0], lmap["a1"].values[-1]))


def test_likelihood_map_unconstrained(free_fit):
    fig = plots.likelihood_map_plot(free_fit)
    ax = fig.axes[0]
    labels = _legend(ax)
    assert "posterior draws" in labels and "inadmissible" not in labels
    assert any("eq 65" in t for t in labels)
    assert "unconstrained" in ax.get_title()


def test_likelihood_map_absent_for_linear_model(linear_fit):
    assert "likelihood_map" not in linear_fit.children
    assert plots.likelihood_map_plot(linear_fit) is None


def test_restoring_force_band_spans_four_sigma(paper_fit):
    fig = plots.restoring_force_plot(paper_fit)
    (ax,) = fig.axes
    sigma_x = attr(paper_fit, "state")["sigma_x"]
    median = next(line for line in ax.get_lines() if line.get_label() == "posterior median")
    x, y = median.get_xdata(), median.get_ydata()
    assert x[0] == pytest.approx(-4 * sigma_x) and x[-1] == pytest.approx(4 * sigma_x)
    post = paper_fit["posterior"]
    direct = np.median(post["a2"].values * x[-1] + post["n2"].values * x[-1] ** 3)
    assert y[-1] == pytest.approx(direct, rel=0.02)
    assert {"5-95 % band", "posterior median", "truth"} <= set(_legend(ax))
    assert ax.get_xlabel() == "$x$ (m)" and "(m/s²)" in ax.get_ylabel()


def test_restoring_force_linear_model(linear_fit):
    (ax,) = plots.restoring_force_plot(linear_fit).axes
    assert "a_2 x" in ax.get_ylabel() and "n_2" not in ax.get_ylabel()
    assert "truth" not in _legend(ax)


def test_trace_plot_rows_and_walkers(paper_fit):
    fig = plots.trace_plot(paper_fit, max_walkers=4)
    assert [ax.get_ylabel() for ax in fig.axes] == [labels.label(p) for p in [*PAPER, "lp"]]
    assert all(len(ax.get_lines()) == 4 for ax in fig.axes)
    assert fig.axes[-1].get_xlabel() == "step after burn-in"
    with pytest.raises(ValueError, match="max_walkers"):
        plots.trace_plot(paper_fit, max_walkers=0)


def test_spectrum_plot_linear_equivalent(paper_fit):
    (ax,) = spectrum_plots.spectrum_plot(paper_fit).axes
    assert ax.get_yscale() == "log"
    assert ax.get_xlabel() == r"$\omega$ (rad/s)" and "m² s" in ax.get_ylabel()
    data, model = ax.get_lines()
    obs = paper_fit["observed_data"]
    np.testing.assert_array_equal(data.get_ydata(), obs["Sxx"].values)
    w = obs["omega"].values
    a2eq = paper_fit.attrs["sigma_v"] ** 2 / attr(paper_fit, "state")["sigma_x"] ** 2
    s0, a1eq = (np.median(paper_fit["posterior"][p].values) for p in ("S0", "a1eq"))
    expected = s0 / ((a2eq - w**2) ** 2 + a1eq**2 * w**2)
    np.testing.assert_allclose(model.get_ydata(), expected, rtol=1e-12)
    # the linear equivalent follows the record within a factor of two over the band
    ratio = model.get_ydata() / data.get_ydata()
    assert np.median(ratio) == pytest.approx(1.0, abs=0.5)


def test_spectrum_median_level_without_the_draws_by_omega_array(paper_fit):
    """A white level is the median of S0 times 1: the same as the median over the
    ``(draws, omega)`` array it no longer builds.
    """
    omega = paper_fit["observed_data"]["omega"].values
    full = np.median(spectrum_plots._shape_draws(paper_fit, omega, None), axis=0)
    np.testing.assert_allclose(spectrum_plots._median_level(paper_fit, omega), full, rtol=1e-12)


def test_force_spectrum_plot_sets_the_inferred_force_against_the_model(paper_fit):
    (ax,) = spectrum_plots.force_spectrum_plot(paper_fit).axes
    assert ax.get_yscale() == "log" and "m²/s³" in ax.get_ylabel()
    data, model = ax.get_lines()
    obs = paper_fit["observed_data"]
    np.testing.assert_array_equal(data.get_ydata(), obs["force"].values)
    # a white model: the median of S0 over the thinned draws, flat
    assert np.ptp(model.get_ydata()) == 0.0
    s0 = np.median(paper_fit["posterior"]["S0"].values)
    assert model.get_ydata()[0] == pytest.approx(s0, rel=0.02)
    # the paper oscillator's inferred force is white at its level over the band (J2's
    # standardized periodogram: mean 1 within 10 %)
    assert np.mean(data.get_ydata()) / s0 == pytest.approx(1.0, abs=0.1)


def test_unit_attribute_relabels(paper_fit):
    tree = paper_fit.copy(deep=True)
    tree.attrs["unit"] = "mm"
    fig = plots.restoring_force_plot(tree)
    assert fig.axes[0].get_xlabel() == "$x$ (mm)"
    assert plots.likelihood_map_plot(tree).axes[0].get_ylabel() == "$n_1$ (1/mm)"


def test_figures_by_stem(paper_fit, linear_fit):
    assert list(figures(paper_fit)) == STEMS
    assert list(figures(linear_fit)) == [s for s in STEMS if s != "likelihood_map"]


# ------------------------------------------------------------------ report
def test_figures_drawn_in_other_processes_are_those_drawn_here(paper_fit, monkeypatch):
    monkeypatch.setenv("HOSID_FIGURE_PROCESSES", "1")  # whatever the load
    if not render.enabled():
        pytest.skip("no figure processes here")
    k = render.corner_size(Model.from_spec("paper"))  # its axes made while "fitting"
    with render.FigureProcesses(dpi=30, corner=k) as figures:
        assert figures.running
        images = figures.handed(paper_fit)()
    assert images == draw(paper_fit, dpi=30)
    assert sorted(images) == sorted(STEMS)
    monkeypatch.setenv("HOSID_FIGURE_PROCESSES", "0")
    with render.FigureProcesses() as figures:
        assert not figures.running and figures.handed(paper_fit) is None
    monkeypatch.delenv("HOSID_FIGURE_PROCESSES")  # the default: by the load average
    cores = os.cpu_count() or 1
    monkeypatch.setattr(os, "getloadavg", lambda: (cores - 0.5, 0.0, 0.0))
    assert render.enabled() == (cores > 1)
    monkeypatch.setattr(os, "getloadavg", lambda: (cores + 0.5, 0.0, 0.0))
    assert not render.enabled()
    with pytest.raises(RuntimeError, match="no figure process"):
        figures.send(paper_fit)


def test_a_corner_plot_on_axes_made_ahead_is_the_same_picture(paper_fit):
    k = render.corner_size(Model.from_spec("paper"))
    assert k == len(plots.corner_plot(paper_fit).axes) ** 0.5 == 6  # a1 n1 a2 n2 S0 a1eq
    assert render.corner_size(Model.from_spec("linear")) == 3  # a1 a2 S0: no a1eq
    plots.prepare_corner(k)
    ahead = png(plots.corner_plot(paper_fit), 30)
    assert k not in plots._SPARE  # taken
    assert ahead == png(plots.corner_plot(paper_fit), 30)


def test_write_report_takes_the_figures_drawn_elsewhere(paper_fit, tmp_path):
    given = draw(paper_fit, ["trace", "corner"], dpi=30)
    paths = write_report(paper_fit, tmp_path, images=lambda: given)
    assert [p.name for p in paths] == ["report.html", "summary.json", "corner.png", "trace.png"]
    assert (tmp_path / "trace.png").read_bytes() == given["trace"]
    html = paths[0].read_text(encoding="utf-8")
    assert html.index(CAPTIONS["corner"][:30]) < html.index(CAPTIONS["trace"][:30])


def test_write_report_files_html_and_summary(paper_fit, tmp_path):
    out = tmp_path / "new" / "report"
    paths = write_report(paper_fit, out, dpi=40)
    names = ["report.html", "summary.json", *(f"{s}.png" for s in STEMS)]
    assert [p.name for p in paths] == names
    assert sorted(p.name for p in out.iterdir()) == sorted(names)  # no temporary files
    for p in paths[2:]:
        assert p.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    html = paths[0].read_text(encoding="utf-8")
    assert html.count("data:image/png;base64,") == len(STEMS)
    for p in [*PAPER, "a1eq"]:
        assert f"<td>{p}</td>" in html
    assert "gmm" in html and "Hansen" in html
    assert "m²/s³" in html and "<th>truth</th>" in html
    summary = json.loads(paths[1].read_text(encoding="utf-8"))
    assert set(summary["parameters"]) == {*PAPER, "a1eq"}
    assert summary["calibration"]["method"] == "gmm"
    assert set(summary["hansen"]) >= {"J", "df", "p_value"}
    assert summary["state"]["block_seconds"] > 0 and summary["state"]["blocks"] >= 1
    assert set(summary["timings"]) >= {"estimate", "sampling"}
    assert summary["units"]["n2"] == "1/(m² s²)"
    notes = summary["record_notes"]  # what the record's spectrum showed, in the report too
    assert notes and notes[0].startswith("response spectrum:") and 'id="record-notes"' in html
    expected = summarize(paper_fit, warn=False)
    assert summary["converged"] == expected["converged"]
    assert ("Not converged" in html) == (not expected["converged"])


def test_write_report_linear_model(linear_fit, tmp_path):
    paths = write_report(linear_fit, tmp_path, dpi=40)
    assert "likelihood_map.png" not in [p.name for p in paths]
    html = paths[0].read_text(encoding="utf-8")
    assert "<td>n1</td>" not in html and "<td>a2</td>" in html
    assert "<th>truth</th>" not in html
    assert "n1" not in json.loads(paths[1].read_text(encoding="utf-8"))["parameters"]


def test_report_banner_lists_failures(paper_fit, tmp_path):
    tree = paper_fit.copy(deep=True)
    tree["posterior"] = tree["posterior"].isel(draw=slice(0, 30))
    html = write_report(tree, tmp_path, dpi=30)[0].read_text(encoding="utf-8")
    failures = summarize(tree, warn=False)["diagnostic_failures"]
    assert failures and "Not converged" in html
    assert all(f"<li>{escape(f)}</li>" in html for f in failures)


def test_report_calibration_note_and_escaping(paper_fit, tmp_path):
    tree = paper_fit.copy(deep=True)
    cal = attr(tree, "calibration")
    cal.update(dispersion=5.0, note="Hansen's test rejects the model <here>")
    tree.attrs["calibration_json"] = json.dumps(cal)
    tree.attrs["record"] = "<b>rec</b>"
    html = write_report(tree, tmp_path, dpi=30)[0].read_text(encoding="utf-8")
    assert "dispersion 5" in html and "rejects the model &lt;here&gt;" in html
    assert "&lt;b&gt;rec&lt;/b&gt;" in html and "<b>rec</b>" not in html


def test_write_report_replaces_files_and_reports_errors(paper_fit, tmp_path):
    (tmp_path / "report.html").write_text("old")
    write_report(paper_fit, tmp_path, dpi=30)
    assert (tmp_path / "report.html").read_text(encoding="utf-8").startswith("<!DOCTYPE html>")
    assert not list(tmp_path.glob(".*.tmp"))
    blocker = tmp_path / "file"
    blocker.write_text("x")
    with pytest.raises(HosidInputError, match="cannot create"):
        write_report(paper_fit, blocker / "sub", dpi=30)


# ------------------------------------------------------------------ versions, summary, netCDF
CORE = ("hosid", "numpy", "scipy", "emcee", "arviz", "numba", "matplotlib")


def test_versions_in_the_tree_the_netcdf_and_summary_json(paper_fit, tmp_path):
    import importlib.metadata

    from hosid.output.results import load, save, versions

    stored = attr(paper_fit, "versions")
    assert stored == versions()
    for name in CORE:
        assert stored[name] == importlib.metadata.version(name), name
    assert attr(load(save(paper_fit, tmp_path / "p.nc")), "versions") == stored
    paths = write_report(paper_fit, tmp_path / "report", dpi=30)
    assert json.loads(paths[1].read_text(encoding="utf-8"))["versions"] == stored
    html = paths[0].read_text(encoding="utf-8")
    assert f"numpy {stored['numpy']}" in html and f"hosid {stored['hosid']}" in html


def test_a_fit_written_before_the_versions_reports_none(paper_fit, tmp_path):
    tree = paper_fit.copy(deep=True)
    del tree.attrs["versions_json"]
    paths = write_report(tree, tmp_path, dpi=30)
    assert json.loads(paths[1].read_text(encoding="utf-8"))["versions"] is None
    assert "numpy " not in paths[0].read_text(encoding="utf-8")


def test_summary_columns_are_arviz_summary_s(paper_fit):
    import warnings

    import arviz as az

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        table = az.summary(paper_fit, kind="all", ci_prob=0.9, round_to="none")
    params = summarize(paper_fit, warn=False)["parameters"]
    assert list(params) == list(table.index)
    for name, row in params.items():
        for column in ("mean", "sd", "r_hat", "ess_bulk", "ess_tail"):
            assert row[column] == pytest.approx(float(table.loc[name, column]), rel=1e-12)


def test_saving_a_fit_neither_loads_distributed_nor_hides_it(paper_fit, tmp_path):
    """xarray's writer asks dask for its scheduler; ``save`` answers without importing
    ``distributed``, and dask finds it again afterwards.
    """
    import subprocess
    import sys

    pytest.importorskip("distributed")
    from hosid.output.results import save

    path = save(paper_fit, tmp_path / "p.nc")
    code = f"""
import sys
from hosid.output.results import load, save
save(load({str(path)!r}), {str(tmp_path / "q.nc")!r})
import dask.base
print("distributed" in sys.modules, dask.base._distributed_available())
"""
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    assert done.stdout.split() == ["False", "True"]


def test_the_lock_file_goes_with_the_command_and_a_removed_one_is_not_held(tmp_path, monkeypatch):
    import builtins
    import os

    from hosid.output import files

    out = tmp_path / "out"
    with files.locked_dir(out, command="first"):
        assert (out / files.LOCK_NAME).read_text().startswith("'first' (pid ")
    assert not (out / files.LOCK_NAME).exists()
    calls = []

    def opened_as_the_last_command_ends(path, mode):
        fh = builtins.open(path, mode)
        if not calls:  # the command before removes its lock file between open and flock
            os.unlink(path)
        calls.append(path)
        return fh

    monkeypatch.setattr(files, "open", opened_as_the_last_command_ends, raising=False)
    with files.locked_dir(out, command="second"):
        assert len(calls) == 2  # the removed file's lock was dropped, the new file locked
        assert (out / files.LOCK_NAME).read_text().startswith("'second' (pid ")
    assert not (out / files.LOCK_NAME).exists()


def test_the_monitor_s_figure_leaves_the_session_s_backend_alone():
    from types import SimpleNamespace

    import matplotlib

    from hosid.monitor.report import plot_tracks

    start = 100.0 * np.arange(5)
    values = {"mean": np.ones(5), "q05": np.zeros(5), "q95": np.full(5, 2.0), "sd": np.ones(5)}
    tracks = SimpleNamespace(
        values={"a1": values, "S0": values}, start=start, end=start + 100, failed=[], kinds={}
    )
    before = matplotlib.get_backend()
    matplotlib.use("pdf")
    try:
        fig = plot_tracks(tracks, [])
        assert matplotlib.get_backend() == "pdf"
    finally:
        matplotlib.use(before)
    assert isinstance(fig, Figure)
    assert [ax.get_ylabel() for ax in fig.axes] == ["a1", "S0"]
    assert png(fig)[:4] == b"\x89PNG"


def test_a_stage_uses_the_commands_bar_or_its_own():
    """``staged``: under a command's :class:`Stages` the stage relabels its one bar (left
    open for the next stage); alone it makes a bar of its own and closes it.
    """
    from hosid.progress import Stages, staged

    stages = Stages("hosid fit", enabled=False)
    with staged(stages, "weight", total=8, unit="record") as b:
        pass
    assert b is stages.bar and b.total == 8 and b.unit == "record"
    stages.close()
    with staged(False, "weight", total=2) as own:
        pass
    assert own is not stages.bar and own.total == 2 and own.disable
