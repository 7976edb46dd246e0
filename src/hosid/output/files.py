"""What every writer of results shares: PNG bytes of a figure, HTML from a jinja2
template, files written atomically (a temporary name in the directory, then
:func:`os.replace`) and output folders that are never half-written or mixed.

:func:`output_dir` is how a command writes its ``--out`` folder: it creates the folder
(call it once the input is validated), holds an exclusive lock on it (a second command on
the same folder stops at once with :class:`~hosid.errors.HosidInputError`), hands out a
staging directory inside it, and only when the work succeeds moves the staged files in
and removes the files that the folder's previous command wrote and this one did not
(listed in ``.hosid-manifest.json``).  On an error or Ctrl-C the staging directory is
removed, the previous files stay as they were, and a folder the command created is
removed again.
"""

from __future__ import annotations

import base64
import fcntl
import io
import json
import os
import secrets
import shutil
from collections.abc import Callable, Iterator, Mapping
from contextlib import contextmanager
from datetime import UTC, datetime
from pathlib import Path
from typing import TYPE_CHECKING

from ..errors import HosidInputError

if TYPE_CHECKING:  # pragma: no cover - matplotlib and jinja2 load with the first figure/page
    from matplotlib.figure import Figure

__all__ = [
    "LOCK_NAME",
    "MANIFEST_NAME",
    "b64",
    "locked_dir",
    "make_dir",
    "output_dir",
    "png",
    "render",
    "staged",
    "write_atomic",
]

#: The lock file inside an output folder (held with ``flock`` while a command writes).
LOCK_NAME = ".hosid.lock"
#: The list of files the folder's last command wrote.
MANIFEST_NAME = ".hosid-manifest.json"


def png(fig: Figure, dpi: int = 100) -> bytes:
    """The figure as PNG bytes."""
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=dpi)
    return buffer.getvalue()


def b64(data: bytes) -> str:
    """Base64 text of ``data`` (figures embedded in a page)."""
    return base64.b64encode(data).decode("ascii")


def render(template: str, filters: Mapping[str, Callable] | None = None, **context) -> str:
    """Render ``output/templates/<template>`` (autoescaped, strict about undefined names)."""
    import jinja2

    env = jinja2.Environment(
        loader=jinja2.PackageLoader("hosid", "output/templates"),
        autoescape=True,
        undefined=jinja2.StrictUndefined,
        trim_blocks=True,
        lstrip_blocks=True,
    )
    env.filters.update(filters or {})
    return env.get_template(template).render(**context)


def make_dir(path: str | Path) -> Path:
    """Create a directory (and its parents) or raise a one-line input error."""
    path = Path(path)
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise HosidInputError(f"cannot create {path}: {exc.strerror or exc}") from None
    return path


def write_atomic(path: Path, data: bytes | str) -> Path:
    """Write ``data`` to a temporary file beside ``path``, then rename it over ``path``."""
    if isinstance(data, str):
        data = data.encode("utf-8")
    tmp = path.with_name(f".{path.name}.{secrets.token_hex(4)}.tmp")
    try:
        with open(tmp, "xb") as f:
            f.write(data)
        os.replace(tmp, path)
    except OSError as exc:
        tmp.unlink(missing_ok=True)
        raise HosidInputError(f"cannot write {path}: {exc.strerror or exc}") from None
    return path


def _lock(out: Path, command: str):
    """Hold an exclusive, non-blocking ``flock`` on ``out/.hosid.lock`` or raise.

    A command removes the file before it lets go of it (:func:`locked_dir`): a lock
    taken on a file no longer at the path is dropped and the path's new file locked.
    """
    path = out / LOCK_NAME
    for _ in range(100):
        try:
            fh = open(path, "a+")  # held until the command ends
        except OSError as exc:
            raise HosidInputError(f"cannot write into {out}: {exc.strerror or exc}") from None
        try:
            fcntl.flock(fh.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            fh.seek(0)
            holder = fh.read().strip() or "another hosid command"
            fh.close()
            raise HosidInputError(
                f"{out} is in use by {holder}; wait for it to finish or choose another --out"
            ) from None
        try:
            if os.stat(path).st_ino == os.fstat(fh.fileno()).st_ino:
                break
        except FileNotFoundError:
            pass
        fh.close()  # the file of a command that just ended: lock the path's own
    else:  # pragma: no cover - commands starting and ending on the folder without pause
        raise HosidInputError(f"{out} is in use by other hosid commands; try again")
    fh.seek(0)
    fh.truncate()
    fh.write(f"'{command}' (pid {os.getpid()})")
    fh.flush()
    return fh


def _commit(stage: Path, out: Path, command: str, keep: tuple[str, ...] = ()) -> None:
    """Move the staged files into ``out``; drop the previous command's other files
    (except ``keep``).
    """
    manifest = out / MANIFEST_NAME
    try:
        previous = set(json.loads(manifest.read_text())["files"])
    except (OSError, ValueError, KeyError, TypeError):
        previous = set()
    staged = sorted(p.name for p in stage.iterdir())
    for name in staged:
        os.replace(stage / name, out / name)
    names = sorted(set(staged) | (previous & set(keep)))
    for name in previous - set(names):
        if "/" not in name and not name.startswith("."):
            (out / name).unlink(missing_ok=True)
    record = {"command": command, "written_at": datetime.now(UTC).isoformat(), "files": names}
    write_atomic(manifest, json.dumps(record, indent=1) + "\n")


@contextmanager
def locked_dir(path: str | Path, *, command: str) -> Iterator[Path]:
    """Create ``path`` if needed and hold its lock while the block runs (a second command
    on the folder stops at once; the lock file ``.hosid.lock`` is removed when the block
    ends); a folder created here is removed again when the block raises and left nothing
    in it (a chain to resume from stays).  :func:`output_dir` builds on it; commands that
    write many results one by one (``hosid batch``) use it directly with
    :func:`write_atomic`.

    Raises
    ------
    HosidInputError
        If ``path`` exists and is not a directory, cannot be created or written, or is
        locked by another command.
    """
    out = Path(path)
    if out.exists() and not out.is_dir():
        raise HosidInputError(f"{out}: exists and is not a directory")
    created = not out.exists()
    make_dir(out)
    try:
        fh = _lock(out, command)
    except HosidInputError:
        if created:
            shutil.rmtree(out, ignore_errors=True)
        raise
    ok = False
    try:
        yield out
        ok = True
    finally:
        # a folder made here goes again on failure, unless something to resume from is in it
        if created and not ok and {p.name for p in out.iterdir()} <= {LOCK_NAME}:
            shutil.rmtree(out, ignore_errors=True)
        try:  # the lock file goes while it is held; then the lock
            (out / LOCK_NAME).unlink(missing_ok=True)
        except OSError:
            pass
        fh.close()


@contextmanager
def staged(out: Path, *, command: str, keep: tuple[str, ...] = ()) -> Iterator[Path]:
    """A staging directory inside ``out``, committed into it when the block succeeds
    (module docstring); the caller holds ``out``'s lock (:func:`locked_dir`).  ``keep``
    names files of the previous command that stay (``hosid report`` rewrites the report
    beside the fit's ``posterior.nc``).
    """
    stage = Path(out) / f".staging-{secrets.token_hex(4)}"
    try:
        stage.mkdir()
        yield stage
        _commit(stage, Path(out), command, keep)
    finally:
        shutil.rmtree(stage, ignore_errors=True)


@contextmanager
def output_dir(path: str | Path, *, command: str, keep: tuple[str, ...] = ()) -> Iterator[Path]:
    """Create, lock and stage the output folder ``path`` (module docstring):
    :func:`locked_dir` and :func:`staged` in one.

    Yields the staging directory: write every result file into it (with any writer);
    the files replace the folder's contents only when the ``with`` block ends without
    an exception.

    Raises
    ------
    HosidInputError
        If ``path`` exists and is not a directory, cannot be created or written, or is
        locked by another command.
    """
    with locked_dir(path, command=command) as out, staged(out, command=command, keep=keep) as st:
        yield st
