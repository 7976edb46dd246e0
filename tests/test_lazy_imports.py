"""What the command line imports before a command needs it (structure, not timing: the
times are in ``benchmarks/cli_overhead.py``).

``import hosid`` and ``import hosid.cli`` load neither numba, arviz, matplotlib nor dask
(nor scipy or xarray), and parsing ``hosid --help`` or a single command's options builds
that command's parser alone.
"""

import importlib.metadata
import json
import subprocess
import sys

import pytest

import hosid
from hosid import cli

HEAVY = ("numba", "arviz", "matplotlib", "dask", "scipy", "xarray", "corner", "emcee")


def _loaded_after(code: str) -> list[str]:
    """The heavy packages in ``sys.modules`` after ``code`` ran in a fresh interpreter."""
    probe = f"""
import json, sys
{code}
print(json.dumps(sorted(m for m in {HEAVY!r} if m in sys.modules)))
"""
    done = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    return json.loads(done.stdout.splitlines()[-1])


@pytest.mark.parametrize("module", ["hosid", "hosid.cli", "hosid.commands", "hosid.__main__"])
def test_importing_the_command_line_loads_no_heavy_library(module):
    assert _loaded_after(f"import {module}") == []


@pytest.mark.parametrize(
    "argv", [["--help"], ["fit", "--help"], ["simulate", "--help"], ["report", "--help"]]
)
def test_help_loads_no_heavy_library(argv):
    code = f"from hosid.cli import main\ntry:\n    main({argv!r})\nexcept SystemExit:\n    pass"
    assert _loaded_after(code) == []


def test_a_bad_command_line_fails_before_any_heavy_import():
    code = "from hosid.cli import main\nassert main(['fit', '--no-such-option', 'r.csv']) == 2"
    assert _loaded_after(code) == []


def test_the_top_level_names_load_on_first_use():
    assert set(hosid.__all__) <= set(dir(hosid))
    from hosid import PAPER_PARAMS, Record, fit, read_record  # noqa: F401

    assert fit is importlib.import_module("hosid.inference").fit
    assert hosid.Model is importlib.import_module("hosid.model").Model
    with pytest.raises(AttributeError, match="no_such_name"):
        _ = hosid.no_such_name


def test_the_version_is_the_installed_distribution_s():
    assert hosid.__version__ == importlib.metadata.version("hosid")


def test_each_command_s_parser_lists_every_command_alike():
    """``main`` builds the running command's options alone; the help of ``hosid`` and
    the commands it lists read the same whichever command is built.
    """
    full = cli.build_parser()
    text = full.format_help()
    for name in cli.COMMANDS:
        assert name in text
        assert cli.build_parser(name).format_help() == text
    assert cli.build_parser("").format_help() == text
    sub = next(a for a in full._actions if a.dest == "command")
    assert list(sub.choices) == list(cli.COMMANDS)
    assert {a.dest: a.help for a in sub._choices_actions} == cli.COMMANDS


@pytest.mark.parametrize(
    ("argv", "command"),
    [
        (["fit", "r.csv", "--out", "d"], "fit"),
        (["--version"], ""),
        ([], ""),
        (["nosuch", "fit"], ""),
        (["batch", "fit", "r.csv"], "batch"),
    ],
)
def test_the_command_of_a_command_line(argv, command):
    assert cli._command(argv) == command


def test_an_unknown_command_is_still_a_one_line_error(capsys):
    assert cli.main(["nosuch"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("hosid: error: ") and "invalid choice" in err
    assert "\n" not in err


def test_the_fit_and_its_components_load_no_numba_until_a_kernel_runs():
    fit_path = (
        "import hosid.cli\n"
        "from hosid.inference import fit\n"
        "import hosid.components.polyspectral, hosid.model.chain, hosid.model.simulate\n"
    )
    assert "numba" not in _loaded_after(fit_path)
    run = fit_path + (
        "import numpy as np, hosid\n"
        "hosid.simulate(hosid.PAPER_PARAMS, duration=5.0, dt=0.05, rng=np.random.default_rng(0))\n"
    )
    assert "numba" in _loaded_after(run)


def test_kernels_marked_before_and_after_the_first_call_compile():
    """In a fresh interpreter: a placeholder compiles at its first call, and a kernel
    marked after that is compiled at once (so the answer does not depend on test order).
    """
    probe = """
from hosid import _jit
first = _jit.njit(cache=False)(lambda a: a + 1.0)
assert type(first).__name__ == "_Kernel" and not _jit._DONE
assert first(1.0) == 2.0 and _jit._DONE
assert type(first).__name__ == "CPUDispatcher"  # the module's name now holds the dispatcher
later = _jit.njit(lambda a: a * 2.0)
assert later(3.0) == 6.0 and type(later).__name__ == "CPUDispatcher"
print("ok")
"""
    done = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True)
    assert done.returncode == 0 and done.stdout.strip() == "ok", done.stderr
