"""Output folders: staged, locked, never half-written or mixed (hosid.output.files)."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

from hosid.errors import HosidInputError
from hosid.output.files import LOCK_NAME, MANIFEST_NAME, output_dir
from hosid.verdicts import Check, overall


def _visible(path):
    return sorted(p.name for p in path.iterdir() if not p.name.startswith("."))


def test_files_appear_only_when_the_block_succeeds(tmp_path):
    out = tmp_path / "out"
    with output_dir(out, command="test") as stage:
        (stage / "a.txt").write_text("1")
        assert _visible(out) == []  # nothing visible while the command works
    assert _visible(out) == ["a.txt"]
    manifest = json.loads((out / MANIFEST_NAME).read_text())
    assert manifest["files"] == ["a.txt"] and manifest["command"] == "test"
    assert not [p for p in out.iterdir() if p.name.startswith(".staging")]


def test_a_second_command_replaces_the_first_ones_files_and_keeps_user_files(tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    (out / "notes.txt").write_text("mine")
    with output_dir(out, command="fit") as stage:
        (stage / "posterior.nc").write_text("fit")
        (stage / "corner.png").write_text("fit")
    with output_dir(out, command="diagnose") as stage:
        (stage / "posterior.nc").write_text("diagnose")
        (stage / "gaps.png").write_text("diagnose")
    assert _visible(out) == ["gaps.png", "notes.txt", "posterior.nc"]
    assert (out / "posterior.nc").read_text() == "diagnose"


def test_a_failure_leaves_the_previous_files_and_removes_a_new_folder(tmp_path):
    out = tmp_path / "out"
    with output_dir(out, command="first") as stage:
        (stage / "a.txt").write_text("first")
    with pytest.raises(KeyboardInterrupt), output_dir(out, command="second") as stage:
        (stage / "a.txt").write_text("second")
        raise KeyboardInterrupt
    assert (out / "a.txt").read_text() == "first"
    fresh = tmp_path / "fresh"
    with pytest.raises(RuntimeError), output_dir(fresh, command="x") as stage:
        (stage / "b.txt").write_text("half")
        raise RuntimeError("boom")
    assert not fresh.exists()


def test_a_locked_folder_stops_a_second_command_at_once(tmp_path):
    out = tmp_path / "out"
    with output_dir(out, command="hosid fit rec.csv") as stage:
        (stage / "a.txt").write_text("first")
        code = (
            "import sys\n"
            "from hosid.output.files import output_dir\n"
            "from hosid.errors import HosidInputError\n"
            "try:\n"
            f"    with output_dir({str(out)!r}, command='other'): pass\n"
            "except HosidInputError as e:\n"
            "    print(e); sys.exit(2)\n"
        )
        res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
        assert res.returncode == 2
        assert "is in use by 'hosid fit rec.csv'" in res.stdout
    assert (out / "a.txt").read_text() == "first"
    assert not (out / LOCK_NAME).exists()  # removed as the command ends


def test_an_existing_file_is_not_a_folder(tmp_path):
    f = tmp_path / "f"
    f.write_text("x")
    with pytest.raises(HosidInputError, match="not a directory"), output_dir(f, command="x"):
        pass


def test_checks_and_overall():
    checks = [Check("offset", "pass", 0.01, "ok"), Check("clipping", "warn", 0.2, "w")]
    assert overall(checks) == "warn"
    assert overall([]) == "pass"
    assert Check.from_dict(checks[1].as_dict()) == checks[1]
    assert Check("x", "fail", float("nan"), "m").value is None
    with pytest.raises(ValueError, match="status"):
        Check("x", "bad", None, "m")
