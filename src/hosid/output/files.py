"""What every report writer shares: PNG bytes of a figure, HTML from a jinja2 template,
and files written atomically (a temporary name in the directory, then :func:`os.replace`).
"""

from __future__ import annotations

import base64
import io
import os
import secrets
from collections.abc import Callable, Mapping
from pathlib import Path

import jinja2
from matplotlib.figure import Figure

from ..errors import HosidInputError

__all__ = ["b64", "make_dir", "png", "render", "write_atomic"]


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
