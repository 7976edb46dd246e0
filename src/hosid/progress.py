"""The one progress bar of a long command (:mod:`tqdm`).

A command shows one labelled bar on stderr whose label names the stage it is in
(``hosid fit: sampling``, ``hosid fit: report``); it is silent with ``--no-progress``
(``enabled=False``) and whenever stderr is not a terminal (a pipe, a log file, a batch
worker).
"""

from __future__ import annotations

import sys
from collections.abc import Iterator
from contextlib import contextmanager

__all__ = ["Stages", "bar", "staged"]


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


class Stages:
    """One bar for a whole command; :meth:`stage` relabels and resets it.

    Examples
    --------
    >>> stages = Stages("hosid fit", enabled=False)
    >>> b = stages.stage("sampling", total=100, unit="step")
    >>> stages.close()
    """

    def __init__(self, command: str, *, enabled: bool = True):
        self.command = command
        self.bar = bar(command, enabled=enabled)

    def stage(self, name: str, *, total: float | None = None, initial: int = 0, unit: str = "it"):
        """Switch to stage ``name``; returns the bar, to ``update``."""
        b = self.bar
        b.set_description(f"{self.command}: {name}", refresh=False)
        b.unit = unit
        b.reset(total=total)
        b.total = total  # reset() keeps the old total when given None
        if initial:
            b.update(initial)
        return b

    def relabel(self, name: str, *, grow: int = 0):
        """Name stage ``name`` on the same count, its total grown by ``grow`` (work
        found on the way); returns the bar, to ``update``.
        """
        b = self.bar
        if grow:
            b.total = (b.total or 0) + grow
        b.set_description(f"{self.command}: {name}", refresh=True)
        return b

    def close(self) -> None:
        """Remove the bar."""
        self.bar.close()


@contextmanager
def staged(progress, name: str, *, total: float | None = None, unit: str = "it") -> Iterator:
    """The bar of stage ``name`` of a long step: the command's own when ``progress`` is its
    :class:`Stages`, else a bar ``hosid: name`` of its own (shown when ``progress``),
    closed at the end.
    """
    if isinstance(progress, Stages):
        yield progress.stage(name, total=total, unit=unit)
        return
    b = bar(f"hosid: {name}", total=total, enabled=bool(progress), unit=unit)
    try:
        yield b
    finally:
        b.close()
