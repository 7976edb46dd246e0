"""The package as people install it: the lock file against pyproject.toml's ranges, the
version's single source, the command line's messages for paths that are not a record,
and (slow) the wheel built by ``python -m build`` running ``hosid demo`` in a new venv.
"""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
import tomllib
import zipfile
from importlib.metadata import version
from pathlib import Path

import pytest
from packaging.requirements import Requirement
from packaging.utils import canonicalize_name

import hosid
from hosid import HosidInputError
from hosid.record import read_record

ROOT = Path(__file__).resolve().parents[1]
PYPROJECT = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))
LOCK = ROOT / "requirements" / "dev.lock"
#: The extras the development environment installs (make lock, make venv).
LOCKED_EXTRAS = ("test", "analyses", "docs")


def _locked() -> dict[str, str]:
    """``{canonical name: version}`` of the lock's ``name==version [; marker]`` lines."""
    pins = {}
    for line in LOCK.read_text(encoding="utf-8").splitlines():
        line = line.split("#", 1)[0].strip()
        if not line:
            continue
        m = re.fullmatch(r"([A-Za-z0-9][A-Za-z0-9._-]*)==([^\s;]+)\s*(;.*)?", line)
        assert m, f"{LOCK.name}: not a pinned requirement: {line!r}"
        pins[canonicalize_name(m[1])] = m[2]
    return pins


def _required() -> list[Requirement]:
    project = PYPROJECT["project"]
    extras = project["optional-dependencies"]
    specs = list(project["dependencies"])
    for extra in LOCKED_EXTRAS:
        specs += extras[extra]
    return [Requirement(s) for s in specs]


# ------------------------------------------------------------------ lock and version
def test_lock_pins_every_dependency_within_its_range():
    pins = _locked()
    for req in _required():
        name = canonicalize_name(req.name)
        assert name in pins, f"{req.name} ({req}) is not in {LOCK.name}: run make lock"
        assert req.specifier.contains(pins[name], prereleases=True), (
            f"{LOCK.name} pins {req.name}=={pins[name]}, outside pyproject's {req}: run make lock"
        )


def test_every_dependency_has_a_lower_bound():
    for spec in PYPROJECT["project"]["dependencies"]:
        req = Requirement(spec)
        assert any(s.operator in (">=", "==", "~=") for s in req.specifier), spec


def test_version_has_one_source():
    declared = PYPROJECT["project"]["version"]
    assert version("hosid") == declared, "installed metadata is stale: make venv"
    assert hosid.__version__ == declared
    out = subprocess.run(
        [sys.executable, "-m", "hosid", "--version"], capture_output=True, text=True, check=True
    )
    assert out.stdout.strip() == f"hosid {declared}"


# ------------------------------------------------------------------ paths that are not records
@pytest.mark.parametrize("name", ["adir", "d.csv"])
def test_a_folder_is_named_a_folder_exit_2(tmp_path, name):
    (tmp_path / name).mkdir()
    out = subprocess.run(
        [sys.executable, "-m", "hosid", "fit", name, "--out", "o"],
        cwd=tmp_path,
        capture_output=True,
        text=True,
    )
    assert out.returncode == 2
    assert out.stderr.splitlines() == [
        f"hosid: error: {name}: is a folder, not a record file (a .csv or .npz; "
        "hosid batch and hosid monitor take folders)"
    ]
    assert not (tmp_path / "o").exists()


def test_reading_rough_edges(tmp_path):
    def message(path) -> str:
        with pytest.raises(HosidInputError) as err:
            read_record(path)
        text = str(err.value)
        assert "\n" not in text
        return text

    assert message(tmp_path / "missing.csv").endswith("missing.csv: no such file")
    (tmp_path / "empty.csv").write_text("")
    assert "empty file" in message(tmp_path / "empty.csv")
    (tmp_path / "header.csv").write_text("t,x\n")
    assert "no data rows" in message(tmp_path / "header.csv")
    (tmp_path / "utf16.csv").write_text("t,x\n0,1\n", encoding="utf-16")
    assert "not a text file (byte 0xff at offset 0 is not UTF-8)" in message(
        tmp_path / "utf16.csv"
    )
    (tmp_path / "empty.npz").write_bytes(b"")
    assert "not an .npz archive" in message(tmp_path / "empty.npz")
    (tmp_path / "dangling.csv").symlink_to(tmp_path / "nowhere.csv")
    assert message(tmp_path / "dangling.csv").endswith("dangling.csv: no such file")
    os.mkfifo(tmp_path / "pipe.csv")
    assert "pipe.csv: not a regular file" in message(tmp_path / "pipe.csv")
    # a spreadsheet's "CSV UTF-8" starts with a byte-order mark: read, not "no column 't'"
    rows = "".join(f"{0.02 * i:.2f},{(-1) ** i * 0.1 * (i % 5)}\n" for i in range(40))
    (tmp_path / "bom.csv").write_text("t,x\n" + rows, encoding="utf-8-sig")
    assert read_record(tmp_path / "bom.csv").dt == pytest.approx(0.02)


# ------------------------------------------------------------------ the wheel, elsewhere
@pytest.mark.slow
def test_wheel_installs_in_a_new_venv_and_runs_the_demo(tmp_path):
    """``python -m build`` (an sdist, then the wheel from it), a new venv from
    tools/find-python.sh with the wheel alone (dependencies held to the lock), and
    ``hosid demo`` in a folder far from the repository. Several minutes.
    """
    dist = tmp_path / "dist"
    subprocess.run([sys.executable, "-m", "build", "--outdir", str(dist)], cwd=ROOT, check=True)
    (wheel,) = dist.glob("hosid-*.whl")
    assert wheel.name.startswith(f"hosid-{PYPROJECT['project']['version']}-")
    names = zipfile.ZipFile(wheel).namelist()
    for template in ("report", "diagnosis", "monitor"):
        assert f"hosid/output/templates/{template}.html.j2" in names
    assert "hosid/py.typed" in names
    assert not [n for n in names if n.startswith("tests/")]

    python = subprocess.run(
        [str(ROOT / "tools" / "find-python.sh")], capture_output=True, text=True, check=True
    ).stdout.strip()
    venv = tmp_path / "venv"
    subprocess.run([python, "-m", "venv", str(venv)], check=True)
    subprocess.run(
        [venv / "bin" / "python", "-m", "pip", "install", "--quiet", "-c", LOCK, wheel],
        check=True,
    )
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "VIRTUAL_ENV")}
    env["OPENBLAS_NUM_THREADS"] = "1"
    where = subprocess.run(
        [venv / "bin" / "python", "-c", "import hosid; print(hosid.__file__)"],
        cwd=elsewhere,
        env=env,
        capture_output=True,
        text=True,
        check=True,
    ).stdout
    assert Path(where).is_relative_to(venv), where
    subprocess.run(
        [venv / "bin" / "hosid", "demo", "--out", "d", "--no-progress"],
        cwd=elsewhere,
        env=env,
        check=True,
        timeout=1800,
    )
    d = elsewhere / "d"
    for name in ("report.html", "summary.json", "posterior.nc", "demo_record.csv"):
        assert (d / name).is_file(), name
    assert "<html" in (d / "report.html").read_text(encoding="utf-8").lower()
    assert json.loads((d / "summary.json").read_text(encoding="utf-8"))
