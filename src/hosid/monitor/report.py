"""The monitor's figure (``tracks.png``: every parameter's track with its 90 % band, the
level before any change, the named changes with their time interval) and its page
(``report.html``: settings, the changes, every window with its checks).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..output.files import b64, png, render, write_atomic

__all__ = ["plot_tracks", "write_report"]


def _time_unit(span: float) -> tuple[float, str]:
    if span > 2 * 86400:
        return 86400.0, "d"
    if span > 2 * 3600:
        return 3600.0, "h"
    return 1.0, "s"


def plot_tracks(tracks, changes):
    """One panel per parameter: window means at the window centres with their 5-95 %
    band, the level before the first change (dashed), each named change (a line at its
    time, its interval shaded, the level after it), failed windows as red crosses.

    Returns a new :class:`matplotlib.figure.Figure`, made without ``pyplot`` (as
    :mod:`hosid.output.plots`): the caller's backend and figure registry stay as they are.
    """
    from matplotlib.figure import Figure  # no pyplot: the session's backend stays

    params = list(tracks.values)
    n = max(len(params), 1)
    fig = Figure(figsize=(9, 1.9 * n + 0.8))
    axes = fig.subplots(n, 1, sharex=True, squeeze=False)[:, 0]
    span = float(tracks.end.max() - tracks.start.min()) if tracks.start.size else 1.0
    unit, label = _time_unit(span)
    mid = (tracks.start + tracks.end) / 2 / unit
    failed = tracks.failed
    for ax, p in zip(axes, params, strict=False):
        v = tracks.values[p]
        ok = np.isfinite(v["mean"])
        ax.fill_between(mid, v["q05"], v["q95"], where=ok, color="C0", alpha=0.25, lw=0)
        ax.plot(mid[ok], v["mean"][ok], "o-", ms=3, color="C0", lw=1)
        mine = [c for c in changes if c.parameter == p]
        if mine:
            first = mine[0]
            ax.axhline(first.before, ls="--", color="0.4", lw=1, label="before")
            for c in mine:
                ax.axvline(c.time / unit, color="C3", lw=1.2)
                ax.axvspan(c.time_lo / unit, c.time_hi / unit, color="C3", alpha=0.15)
                after = mid >= c.time / unit
                ax.plot(mid[after], np.full(after.sum(), c.before + c.size), ls=":", color="C3")
        elif ok.any():
            w = 1 / np.square(v["sd"][ok])
            ax.axhline(float(np.sum(w * v["mean"][ok]) / np.sum(w)), ls="--", color="0.4", lw=1)
        if failed:
            y = np.nanmin(v["q05"]) if ok.any() else 0.0
            ax.plot(mid[failed], np.full(len(failed), y), "x", color="C3", ms=6)
        ax.set_ylabel(p + (" (excitation)" if tracks.kinds.get(p) == "excitation" else ""))
    axes[-1].set_xlabel(f"time ({label})")
    title = f"{len(changes)} change(s) named" if changes else "no change named"
    if failed:
        title += f"; {len(failed)} window(s) without a posterior (x)"
    axes[0].set_title(title, fontsize=10)
    fig.tight_layout()
    return fig


def _num(value, digits: int = 4) -> str:
    try:
        v = float(value)
    except (TypeError, ValueError):
        return str(value)
    return f"{v:.{digits}g}" if np.isfinite(v) else "-"


def write_report(stage: Path, tracks, changes, *, settings, alpha, level) -> list[Path]:
    """``tracks.png`` and ``report.html`` into ``stage``."""
    image = png(plot_tracks(tracks, changes))
    fig_path = write_atomic(stage / "tracks.png", image)
    windows = [
        {
            "index": int(tracks.index[i]),
            "start": tracks.start[i],
            "end": tracks.end[i],
            "status": tracks.status[i],
            "verdict": tracks.verdict[i],
            "message": tracks.message[i],
            "values": {p: tracks.values[p]["mean"][i] for p in tracks.values},
        }
        for i in range(tracks.start.size)
    ]
    html = render(
        "monitor.html.j2",
        filters={"num": _num},
        settings=settings,
        layout=tracks.layout.as_dict(),
        changes=[tracks.change_row(c) for c in changes],
        windows=windows,
        params=list(tracks.values),
        untested=getattr(tracks, "reasons", {}),
        failed=len(tracks.failed),
        alpha=alpha,
        level=level,
        figure=b64(image),
    )
    return [fig_path, write_atomic(stage / "report.html", html)]
