"""Fast checks of the documentation sources (the site itself is built by `make docs`).

Every gallery example has a title and stays short and seeded; every file a page includes
exists and still holds the headings the page cuts it at, so that a renamed heading in a
result file shows here before the docs build fails on it.
"""

import ast
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = sorted((ROOT / "examples").glob("plot_*.py"))
PAGES = sorted(p for p in (ROOT / "docs").rglob("*.md") if "_build" not in p.parts)


def test_the_gallery_has_at_least_five_examples():
    assert len(EXAMPLES) >= 5
    assert (ROOT / "examples" / "GALLERY_HEADER.rst").is_file()


@pytest.mark.parametrize("path", EXAMPLES, ids=lambda p: p.name)
def test_an_example_has_a_title_and_is_short(path):
    text = path.read_text()
    doc = ast.get_docstring(ast.parse(text))
    assert doc, f"{path.name}: no module docstring (sphinx-gallery takes the title from it)"
    title, underline = doc.strip().splitlines()[:2]
    assert title.strip() and set(underline.strip()) == {"="}, f"{path.name}: no '===' title"
    assert len(underline.strip()) >= len(title.strip()), f"{path.name}: underline too short"
    assert len(text.splitlines()) <= 250, f"{path.name}: keep an example under 250 lines"


@pytest.mark.parametrize("path", EXAMPLES, ids=lambda p: p.name)
def test_an_example_draws_its_random_numbers_from_an_explicit_seed(path):
    text = path.read_text()
    # the legacy global generator (np.random.seed, np.random.normal ...) is not used
    legacy = re.findall(r"np\.random\.(?!default_rng|SeedSequence)\w+", text)
    assert not legacy, f"{path.name}: {legacy}"
    assert "default_rng()" not in text, f"{path.name}: default_rng without a seed"


def _includes(page: Path):
    for m in re.finditer(r"```\{include\}\s+(\S+)\n((?::[\w-]+:.*\n)*)", page.read_text()):
        options = dict(re.findall(r":([\w-]+):\s*(.*)", m.group(2)))
        yield page.parent / m.group(1), options


@pytest.mark.parametrize("page", PAGES, ids=lambda p: str(p.relative_to(ROOT / "docs")))
def test_what_a_page_includes_exists_with_its_markers(page):
    for target, options in _includes(page):
        if "_generated" in target.parts:  # written by the build itself
            continue
        assert target.is_file(), f"{page.name} includes {target}, which is missing"
        text = target.read_text()
        for key in ("start-after", "end-before"):
            if key in options:
                marker = options[key].strip().strip('"')
                assert marker in text, f"{page.name}: {target.name} has no {marker!r}"
