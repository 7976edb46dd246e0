"""The true parameters of a simulated record: the sidecar ``REC.truths.json``."""

from __future__ import annotations

import json
import math
from pathlib import Path

from hosid.errors import HosidInputError

__all__ = ["read_truths"]


def read_truths(record_path: str | Path, path: str | Path | None = None) -> dict | None:
    """The true parameters of a simulated record: ``path`` (a JSON object of finite
    numbers), or else the sidecar ``REC.truths.json`` (or ``REC.csv.truths.json``) that
    ``hosid simulate`` writes; ``None`` when there is none.

    Raises
    ------
    HosidInputError
        If the file is missing (when given), unreadable or not such an object.
    """
    record_path = Path(record_path)
    path = Path(path) if path else None
    if path is None:
        for cand in (
            record_path.with_suffix(".truths.json"),
            record_path.with_name(record_path.name + ".truths.json"),
        ):
            if cand.is_file():
                path = cand
                break
    if path is None:
        return None
    try:
        data = json.loads(path.read_text())
    except FileNotFoundError:
        raise HosidInputError(f"{path}: no such file") from None
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise HosidInputError(f"{path}: not valid JSON ({exc})") from None
    ok = (
        isinstance(data, dict)
        and data
        and all(
            isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v)
            for v in data.values()
        )
    )
    if not ok:
        raise HosidInputError(f"{path}: truths must be a JSON object of finite numbers")
    return {k: float(v) for k, v in data.items()}
