"""Sphinx configuration of the hosid documentation site.

``make docs`` runs ``sphinx-build -W --keep-going -b html docs docs/_build/html``: every
warning fails the build.  The site is made of

* hand-written pages (MyST Markdown: getting started, the user guide, the theory);
* the API reference from the modules' numpydoc docstrings (``api.rst``; one page a
  module under ``gen_modules/``, written by ``_ext/hosid_docs.py``);
* the examples gallery: ``examples/plot_*.py`` executed by sphinx-gallery (under
  ``auto_examples/``), their figures scraped from pyplot and from the
  :class:`matplotlib.figure.Figure` objects hosid's plotting functions return
  (``_ext/hosid_docs.py``);
* the measured numbers, read from ``analyses/results/`` at build time
  (``_ext/hosid_docs.py`` writes one page a result file under ``measured/_generated/``):
  no number on the site is copied by hand.

Nothing needs the network (no intersphinx: a clean clone on an offline CI machine
builds the same site).
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
sys.path.insert(0, str(HERE / "_ext"))

# the examples and autodoc run single-threaded BLAS like the test suite (2 shared cores)
for var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(var, "1")
os.environ.setdefault("MPLBACKEND", "Agg")

import hosid  # noqa: E402

project = "hosid"
author = "the hosid developers"
copyright = "the hosid developers"
version = release = hosid.__version__

extensions = [
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "sphinx.ext.mathjax",
    "sphinx.ext.viewcode",
    "numpydoc",
    "myst_parser",
    "sphinx_gallery.gen_gallery",
    "hosid_docs",
]

source_suffix = {".rst": "restructuredtext", ".md": "markdown"}
root_doc = "index"
exclude_patterns = [
    "_build",
    "**.ipynb_checkpoints",
    # included by guide/commands.md, not a page of its own
    "guide/_generated/*",
    # sphinx-gallery writes these beside the pages it generates; they are not pages
    "auto_examples/*.py",
    "auto_examples/*.ipynb",
    "auto_examples/*.zip",
    "auto_examples/*.json",
    "auto_examples/*.md5",
    "auto_examples/*.codeobj.json",
]

# -- autodoc, autosummary, numpydoc ------------------------------------------------------

# the module pages are written by _ext/hosid_docs.py (gen_modules/); autosummary only
# draws the table of the top-level names in api.rst
autosummary_generate = False
autodoc_default_options = {"members": True, "show-inheritance": True}
autodoc_member_order = "bysource"
autodoc_typehints = "none"  # the numpydoc sections carry the types
# autodoc documents the members; numpydoc's member tables would repeat them
numpydoc_show_class_members = False
numpydoc_class_members_toctree = False
numpydoc_validation_checks: set[str] = set()
numpydoc_xref_param_type = False
nitpicky = False

# -- MyST ---------------------------------------------------------------------------------

myst_enable_extensions = ["dollarmath", "amsmath", "colon_fence", "deflist", "substitution"]
myst_heading_anchors = 3


def _settings() -> dict[str, str]:
    """The constants the pages quote as ``{{ name }}`` (never copied by hand)."""
    from hosid.check.diagnose import DEFAULT_REPLICATES
    from hosid.inference.gmm import HANSEN_P
    from hosid.inference.sampler import ESS_STOP, RHAT_STOP
    from hosid.screen import THRESHOLDS
    from hosid.spectra.blocks import MIN_BLOCKS, MIN_PERIODS
    from hosid.verdicts import ESS_MIN, RHAT_MAX

    return {
        "rhat_max": f"{RHAT_MAX:g}",
        "ess_min": f"{ESS_MIN:g}",
        "rhat_stop": f"{RHAT_STOP:g}",
        "ess_stop": f"{ESS_STOP:g}",
        "hansen_p": f"{HANSEN_P:g}",
        "replicates": f"{DEFAULT_REPLICATES}",
        "min_blocks": f"{MIN_BLOCKS}",
        "min_periods": f"{MIN_PERIODS:g}",
        "sampling_warn": f"{THRESHOLDS['sampling'][0]:g}",
        "sampling_fail": f"{THRESHOLDS['sampling'][1]:g}",
    }


myst_substitutions = _settings()

# -- sphinx-gallery -----------------------------------------------------------------------

sphinx_gallery_conf = {
    "examples_dirs": str(ROOT / "examples"),
    "gallery_dirs": "auto_examples",
    "filename_pattern": r"/plot_",
    "within_subsection_order": "FileNameSortKey",
    # the Figure objects hosid's plotting functions return (without pyplot), then pyplot's
    "image_scrapers": ("hosid_docs.figure_scraper", "matplotlib"),
    "reset_modules": ("matplotlib",),
    "capture_repr": (),
    "download_all_examples": False,
    "remove_config_comments": True,
    "show_memory": False,
    "min_reported_time": 0,
    "matplotlib_animations": False,
    "only_warn_on_example_error": False,
}

# -- HTML ---------------------------------------------------------------------------------

html_theme = "pydata_sphinx_theme"
html_title = f"hosid {release}"
html_static_path: list[str] = []
html_show_sourcelink = False
html_theme_options = {
    "navigation_with_keys": False,
    "show_toc_level": 2,
    "secondary_sidebar_items": ["page-toc"],
    "footer_start": ["copyright"],
    "footer_end": ["sphinx-version"],
}
html_sidebars = {"index": [], "getting-started": []}
