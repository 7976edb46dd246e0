"""The one-page HTML report and its files, from SYNTHETIC fits (``synthetic_fit``)."""

import html
import json
from html.parser import HTMLParser

import pytest

from hosid import report, results
from hosid.errors import HosidInputError
from synthetic_fit import synthetic_tree

FILES = ("corner.png", "contour.png", "restoring_force.png", "trace.png", "summary.json")
VOID = {"meta", "img", "br", "hr", "link", "input"}


class Structure(HTMLParser):
    """Tag balance, table rows and images of a page."""

    def __init__(self):
        super().__init__()
        self.stack, self.errors, self.rows, self.images = [], [], [], []
        self._row = None

    def handle_starttag(self, tag, attrs):
        attrs = dict(attrs)
        if tag == "img":
            self.images.append(attrs)
        if tag == "tr":
            self._row = {"class": attrs.get("class"), "cells": []}
        if tag not in VOID:
            self.stack.append(tag)

    def handle_endtag(self, tag):
        if not self.stack or self.stack.pop() != tag:
            self.errors.append(tag)
        if tag == "tr":
            self.rows.append(self._row)

    def handle_data(self, data):
        if self._row is not None and self.stack and self.stack[-1] in ("td", "th"):
            self._row["cells"].append(data)


def parse(text):
    page = Structure()
    page.feed(text)
    page.close()
    assert not page.errors
    assert not page.stack
    return page


@pytest.fixture(scope="module")
def passing(tmp_path_factory):
    out = tmp_path_factory.mktemp("passing")
    return report.write_report(synthetic_tree(), out, dpi=30)


def stuck_tree():
    """Walkers stuck apart, and S0 constant so that its R-hat is NaN."""
    tree = synthetic_tree(stuck=True, truths=False)
    tree["posterior"]["S0"] = tree["posterior"]["S0"] * 0 + 100.0
    return tree


@pytest.fixture(scope="module")
def failing(tmp_path_factory):
    out = tmp_path_factory.mktemp("failing")
    return report.write_report(stuck_tree(), out, dpi=30)


NAMES = ("a1", "n1", "a2", "n2", "S0", "a1eq")


def summary_rows(page):
    return {r["cells"][0]: r for r in page.rows if r["cells"] and r["cells"][0] in NAMES}


def test_files_written(passing):
    assert passing.name == "report.html"
    for name in FILES:
        assert (passing.parent / name).stat().st_size > 0
    for stem, _, _ in report.FIGURES:
        assert (passing.parent / f"{stem}.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_summary_json_is_the_summary(passing):
    data = json.loads((passing.parent / "summary.json").read_text())
    assert set(data["parameters"]) == set(NAMES)
    assert data["converged"] is True
    assert data["cost"] == "J4A"
    assert data["settings"]["window"] == "hann"
    assert data["truths"]["a2"] == 25.0


def test_summary_json_nan_becomes_null(failing):
    text = (failing.parent / "summary.json").read_text()
    data = json.loads(text, parse_constant=pytest.fail)
    assert data["parameters"]["S0"]["r_hat"] is None
    assert data["parameters"]["S0"]["sd"] == 0.0


def test_html_passing(passing):
    text = passing.read_text()
    page = parse(text)
    header = next(r for r in page.rows if r["cells"][:1] == ["parameter"])
    assert header["cells"] == ["parameter", *report.SUMMARY_COLUMNS, "truth"]
    rows = summary_rows(page)
    assert set(rows) == set(NAMES)
    assert all(r["class"] is None for r in rows.values())
    assert rows["a2"]["cells"][-1] == "25"
    assert rows["a1eq"]["cells"][-1] != "-"  # derived from eq (65)
    assert 'class="warning"' not in text
    assert "diagnostics passed" in text
    assert "<title>hosid fit: synthetic: J4A cost, constrained</title>" in text
    for key in ("block_seconds", "omega_max", "fit time (s)", "method"):
        assert [key] == next(r["cells"][:1] for r in page.rows if r["cells"][:1] == [key])
    fit_time = next(r for r in page.rows if r["cells"][:1] == ["fit time (s)"])
    assert fit_time["cells"] == ["fit time (s)", "12.5"]
    assert [img["alt"] for img in page.images] == [s for s, _, _ in report.FIGURES]
    assert all(img["src"].startswith("data:image/png;base64,iVBOR") for img in page.images)
    assert text.count("<figcaption>") == 4


def test_html_failing_banner_and_rows(failing):
    text = failing.read_text()
    page = parse(text)
    assert 'class="warning"' in text
    assert "convergence diagnostics failed" in text
    expected = results.summarize(stuck_tree(), warn=False)["diagnostic_failures"]
    assert expected
    banner = text[text.index('class="warning"') : text.index("</div>")]
    assert banner.count("<li>") == len(expected)
    for failure in expected:
        assert f"<li>{html.escape(failure)}</li>" in banner
    rows = summary_rows(page)
    assert set(rows) == set(NAMES)
    assert all(r["class"] == "fail" for r in rows.values())
    assert rows["S0"]["cells"][6] == "-"  # NaN R-hat
    header = next(r for r in page.rows if r["cells"][:1] == ["parameter"])
    assert "truth" not in header["cells"]
    data = json.loads((failing.parent / "summary.json").read_text())
    assert data["converged"] is False
    assert data["diagnostic_failures"] == expected


def test_report_needs_writable_dir(tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("")
    with pytest.raises(HosidInputError, match="cannot create"):
        report.write_report(synthetic_tree(), blocker / "sub")
