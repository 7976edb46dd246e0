"""The one progress bar of a long command (:mod:`tqdm`).

A command shows one labelled bar on stderr, with the stage it is in; it is silent with
``--no-progress`` (``enabled=False``) and whenever stderr is not a terminal (a pipe, a
log file, a batch worker).
"""

from __future__ import annotations

import sys

__all__ = ["bar"]


def bar(
    desc: str,
    *,
    total: float | None = None,
    enabled: bool = True,
    unit: str = "it",
    initial: int = 0,
):
    """A :class:`tqdm.tqdm` bar labelled ``desc`` (module docstring)."""
    from tqdm.auto import tqdm

    return tqdm(
        total=total,
        initial=initial,
        desc=desc,
        unit=unit,
        leave=False,
        file=sys.stderr,
        disable=None if enabled else True,  # None: off when stderr is not a terminal
    )
