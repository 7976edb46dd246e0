"""Sphinx helpers of the hosid site: generated pages, reference aliases, a figure scraper.

``gen_modules/``
    One page a module of hosid: a package's page has its docstring and a table of its
    modules, a module's page ``automodule`` with its members.  Written here rather than
    by autosummary's recursion, which resolves ``hosid.inference.fit`` to the function
    ``fit`` the package re-exports under the module's name (so do
    ``hosid.inference.estimate``, ``hosid.model.simulate``, ``hosid.check.gaps`` and
    ``hosid.check.measures``) and would document the function in place of the module.

``guide/_generated/commands.md``
    Every command's ``--help``, taken from hosid's own argument parser at build time
    (the command reference cannot fall behind the parser).

:func:`resolve_reexport`
    A reference to a name hosid re-exports (``hosid.fit``, ``hosid.batch.run_batch``,
    ``hosid.record.Record`` ...) is resolved to the object's page in the module that
    defines it, where it is documented once.

``measured/_generated/``
    At ``builder-inited`` every Markdown table of ``analyses/results/`` (the committed
    output of the studies in ``analyses/``) gets a page here that *includes* the file as
    it is, its figures beside it: the site shows the numbers the studies wrote, never
    numbers copied by hand.  A study that adds a result file gets a page at the next
    build; a study that renames a heading the summary page includes fails the build.
    The folder is rewritten on every build and is not kept in git.

:func:`figure_scraper`
    hosid's plotting functions return :class:`matplotlib.figure.Figure` objects made
    without ``pyplot`` (no global registry), which sphinx-gallery's matplotlib scraper
    cannot see.  This scraper saves every such figure an example's code block left in
    its global names (directly, or in a dict, list or tuple) and has not shown before.
"""

from __future__ import annotations

import re
import weakref
from pathlib import Path
from typing import Any

DOCS = Path(__file__).resolve().parents[1]
ROOT = DOCS.parent
RESULTS = ROOT / "analyses" / "results"
GENERATED = DOCS / "measured" / "_generated"

# -- the measured-numbers pages ------------------------------------------------------------

#: The script that writes each result file, by its folder under ``analyses/results`` or
#: its stem (the rest are named in ``analyses/README.md``).
_SCRIPTS = {
    "crb": "analyses/crb.py",
    "efficiency_default": "analyses/efficiency_study.py --cost default (efficiency_summary.py)",
    "efficiency_J4A": "analyses/efficiency_study.py --cost J4A (efficiency_summary.py)",
    "record_checks": "analyses/record_checks.py",
    "shaped_bound": "analyses/shaped_bound.py",
    "coverage_2x50": "analyses/efficiency_study.py (2 regimes x 50 seeds)",
    "diagnose_confusion": "analyses/diagnose_confusion.py",
    "diagnose_power": "analyses/diagnose_power.py (diagnose_power_summary.py)",
    "excitation": "analyses/excitation_study.py",
    "excitation_diagnose": "analyses/excitation_diagnose.py",
    "impulses": "analyses/impulse_study.py",
    "monitor": "analyses/monitor_study.py",
    "paper": "analyses/paper_figures.py (make paper)",
    "peers": "analyses/peers.py (make peers)",
    "silverbox": "analyses/silverbox.py and analyses/silverbox_coverage.py",
    "benchmarks": "benchmarks/run_benchmarks.py, batch_throughput.py and monitor_day.py",
}


def result_files() -> list[Path]:
    """Every Markdown result file, relative to the repository, sorted: the studies'
    (``analyses/results/**.md``) and the benchmarks' (``benchmarks/results.md``).
    """
    files = sorted(p.relative_to(ROOT) for p in RESULTS.rglob("*.md"))
    bench = ROOT / "benchmarks" / "results.md"
    return files + ([bench.relative_to(ROOT)] if bench.is_file() else [])


def _key(rel: Path) -> Path:
    """The path under ``analyses/results`` (or ``benchmarks/...`` as it is)."""
    return rel.relative_to("analyses/results") if rel.parts[:2] == ("analyses", "results") else rel


def _slug(rel: Path) -> str:
    """``analyses/results/excitation/summary.md`` -> ``excitation-summary``."""
    return re.sub(r"[^A-Za-z0-9]+", "-", str(_key(rel).with_suffix(""))).strip("-").lower()


def _title(path: Path) -> str | None:
    """The file's first level-1 heading, if it has one."""
    for line in path.read_text(encoding="utf-8").splitlines():
        if line.startswith("# "):
            return line[2:].strip()
    return None


def _write_if_changed(path: Path, text: str) -> None:
    # an unchanged page keeps its time stamp, so an incremental build skips it
    if not path.exists() or path.read_text(encoding="utf-8") != text:
        path.write_text(text, encoding="utf-8")


def write_measured_pages(app=None) -> list[Path]:
    """One page a result file under ``measured/_generated/`` and their index."""
    GENERATED.mkdir(parents=True, exist_ok=True)
    pages = []
    for rel in result_files():
        slug = _slug(rel)
        page = GENERATED / f"{slug}.md"
        key = _key(rel)
        script = _SCRIPTS.get(key.parts[0] if len(key.parts) > 1 else key.stem, "")
        made_by = f" by `{script}`" if script else ""
        raw = sorted(
            p.name for p in (ROOT / rel).parent.iterdir() if p.suffix in (".csv", ".json")
        )
        beside = f" Beside it, the raw numbers: {', '.join(f'`{n}`' for n in raw)}." if raw else ""
        # a file without a title of its own gets its path as the page's title
        heading = "" if _title(ROOT / rel) else f"# `{_key(rel).as_posix()}`\n\n"
        text = (
            f"<!-- generated by docs/_ext/hosid_docs.py from {rel.as_posix()}; "
            "do not edit -->\n\n"
            f"({slug})=\n\n{heading}"
            f"```{{include}} ../../../{rel.as_posix()}\n:relative-images:\n```\n\n"
            "```{admonition} Where this page comes from\n:class: note\n\n"
            f"This page is the file `{rel.as_posix()}`, written{made_by} and included "
            f"here when the site was built.{beside}\n```\n"
        )
        _write_if_changed(page, text)
        pages.append(page)
    index = GENERATED / "index.md"
    for stale in set(GENERATED.glob("*.md")) - {*pages, index}:
        stale.unlink()
    rows = "\n".join(
        f"| [{_title(ROOT / rel) or _key(rel).as_posix()}]({_slug(rel)}.md) | `{rel.as_posix()}` |"
        for rel in result_files()
    )
    text = (
        "<!-- generated by docs/_ext/hosid_docs.py; do not edit -->\n\n"
        "# Every result file\n\n"
        "Each page is one Markdown file a study or benchmark wrote, included as it is.\n\n"
        "| results | file |\n|---|---|\n"
        f"{rows}\n\n"
        "```{toctree}\n:hidden:\n\n" + "\n".join(_slug(rel) for rel in result_files()) + "\n```\n"
    )
    _write_if_changed(index, text)
    return pages


# -- the API pages ------------------------------------------------------------------------

API = DOCS / "gen_modules"
#: The order of the top-level modules in the API reference: the stages of the data flow;
#: a module not named here is listed after them.
API_ORDER = (
    "hosid.record",
    "hosid.model",
    "hosid.spectra",
    "hosid.state",
    "hosid.components",
    "hosid.inference",
    "hosid.check",
    "hosid.output",
    "hosid.screen",
    "hosid.verdicts",
    "hosid.datasets",
    "hosid.batch",
    "hosid.monitor",
    "hosid.cli",
    "hosid.commands",
    "hosid.progress",
    "hosid.errors",
)


def api_modules() -> dict[str, Any]:
    """Every public module of hosid by name (``hosid.__main__`` and ``_private`` ones
    left out), imported.
    """
    import importlib
    import pkgutil

    import hosid

    names = [
        m.name
        for m in pkgutil.walk_packages(hosid.__path__, "hosid.")
        if m.name != "hosid.__main__" and not any(p.startswith("_") for p in m.name.split("."))
    ]
    return {name: importlib.import_module(name) for name in sorted(names)}


def _summary(module) -> str:
    """The first paragraph of a module's docstring, for a table cell."""
    doc = (module.__doc__ or "").strip()
    first = doc.split("\n\n")[0].strip() if doc else "(no docstring)"
    if first.endswith("::"):  # it introduces a literal block the cell does not hold
        first = first[:-1]
    return " ".join(line.strip() for line in first.splitlines())


def _table(names, modules) -> str:
    rows = "".join(f"   * - :mod:`{n}`\n     - {_summary(modules[n])}\n" for n in names)
    return f".. list-table::\n   :widths: 30 70\n\n{rows}"


def _toctree(names, prefix: str = "") -> str:
    return ".. toctree::\n   :hidden:\n\n" + "".join(f"   {prefix}{n}\n" for n in names)


def write_api_pages(app=None) -> list[Path]:
    """``gen_modules/<module>.rst`` for every module, and ``gen_modules/modules.inc``
    (the table and toctree of the top-level modules that ``api.rst`` includes).
    """
    modules = api_modules()
    API.mkdir(parents=True, exist_ok=True)
    pages = []
    for name, module in modules.items():
        title = f"{name}\n{'=' * len(name)}\n\n"
        if hasattr(module, "__path__"):  # a package: its docstring and its modules
            children = [n for n in modules if n.rpartition(".")[0] == name]
            text = (
                f"{title}.. automodule:: {name}\n   :no-members:\n\n"
                f".. rubric:: Modules\n\n{_table(children, modules)}\n{_toctree(children)}"
            )
        else:
            text = f"{title}.. automodule:: {name}\n   :members:\n   :show-inheritance:\n"
        page = API / f"{name}.rst"
        _write_if_changed(page, text)
        pages.append(page)
    top = [n for n in modules if n.count(".") == 1]
    top = [n for n in API_ORDER if n in top] + [n for n in top if n not in API_ORDER]
    _write_if_changed(
        API / "modules.inc", f"{_table(top, modules)}\n{_toctree(top, 'gen_modules/')}"
    )
    for stale in set(API.glob("*.rst")) - set(pages):
        stale.unlink()
    return pages


# -- the command reference ---------------------------------------------------------------


def _subparsers(parser):
    import argparse

    for action in parser._actions:  # argparse keeps no public list of the subcommands
        if isinstance(action, argparse._SubParsersAction):
            return action.choices
    return {}


def write_command_reference(app=None) -> Path:
    """``guide/_generated/commands.md``: ``hosid --help`` and every command's help."""
    import os

    from hosid.cli import build_parser

    os.environ["COLUMNS"] = "88"  # argparse wraps to the terminal: fix it for the site
    parser = build_parser()
    parts = [
        "<!-- generated by docs/_ext/hosid_docs.py from hosid.cli.build_parser(); "
        "do not edit -->\n",
        f"```text\n{parser.format_help().rstrip()}\n```\n",
    ]
    for name, sub in _subparsers(parser).items():
        parts.append(f"## hosid {name}\n\n```text\n{sub.format_help().rstrip()}\n```\n")
        for inner, leaf in _subparsers(sub).items():
            parts.append(
                f"### hosid {name} {inner}\n\n```text\n{leaf.format_help().rstrip()}\n```\n"
            )
    path = DOCS / "guide" / "_generated" / "commands.md"
    path.parent.mkdir(parents=True, exist_ok=True)
    _write_if_changed(path, "\n".join(parts))
    return path


# -- the figure scraper ---------------------------------------------------------------------

_shown: dict[str, weakref.WeakSet] = {}


def _figures(value: Any, depth: int = 0):
    from matplotlib.figure import Figure

    if isinstance(value, Figure):
        yield value
    elif depth == 0 and isinstance(value, dict):
        for v in value.values():
            yield from _figures(v, 1)
    elif depth == 0 and isinstance(value, (list, tuple)):
        for v in value:
            yield from _figures(v, 1)


def figure_scraper(block, block_vars: dict, gallery_conf: dict) -> str:
    """Save the new :class:`~matplotlib.figure.Figure` objects of an example's globals.

    Runs before sphinx-gallery's matplotlib scraper: the figures pyplot holds open are
    marked as shown and left to it (it saves and closes them after this one).
    """
    import matplotlib.pyplot as plt
    from sphinx_gallery.scrapers import figure_rst

    shown = _shown.setdefault(str(block_vars["src_file"]), weakref.WeakSet())
    for num in plt.get_fignums():
        shown.add(plt.figure(num))
    new = []
    for name, value in list(block_vars["example_globals"].items()):
        if name.startswith("_"):
            continue
        for fig in _figures(value):
            if fig not in shown and fig not in new:
                new.append(fig)
    paths = []
    for fig, path in zip(new, block_vars["image_path_iterator"], strict=False):
        fig.savefig(path, dpi=100)
        shown.add(fig)
        paths.append(path)
    return figure_rst(paths, gallery_conf["src_dir"])


# -- references to re-exported names ---------------------------------------------------


def _defining_name(target: str) -> str | None:
    """Where ``target`` (``hosid.fit``) is defined (``hosid.inference.fit.fit``), if
    elsewhere.
    """
    import importlib
    import sys

    parts = target.split(".")
    for i in range(len(parts) - 1, 0, -1):
        try:
            obj = importlib.import_module(".".join(parts[:i]))
        except ImportError:
            continue
        try:
            for attr in parts[i:]:
                obj = getattr(obj, attr)
        except AttributeError:
            return None
        break
    else:
        return None
    if isinstance(obj, type(sys)):
        return obj.__name__ if obj.__name__ != target else None
    module, qualname = getattr(obj, "__module__", None), getattr(obj, "__qualname__", None)
    if module and qualname and module.startswith("hosid"):
        real = f"{module}.{qualname}"
        return real if real != target else None
    # data (a dict, a tuple ...): the module below the package that lists it in __all__
    name = parts[-1]
    homes = [
        m.__name__
        for m in list(sys.modules.values())
        if getattr(m, "__name__", "").startswith("hosid.")
        and not hasattr(m, "__path__")
        and name in getattr(m, "__all__", ())
        and getattr(m, name, None) is obj
    ]
    return f"{max(homes, key=len)}.{name}" if homes else None


def resolve_reexport(app, env, node, contnode):
    """``missing-reference``: retry a ``hosid.*`` Python reference at its definition."""
    target = node.get("reftarget", "")
    if node.get("refdomain") != "py" or not target.startswith("hosid."):
        return None
    real = _defining_name(target)
    if real is None:
        return None
    return env.get_domain("py").resolve_xref(
        env, node["refdoc"], app.builder, "obj", real, node, contnode
    )


def setup(app):
    """Register the generated pages (written before the sources are read)."""
    app.connect("builder-inited", write_api_pages)
    app.connect("builder-inited", write_measured_pages)
    app.connect("builder-inited", write_command_reference)
    app.connect("missing-reference", resolve_reexport)
    return {"version": "1", "parallel_read_safe": True, "parallel_write_safe": True}
