"""The report of :func:`hosid.check.locate.locate` (``hosid diagnose`` of a system).

Files: ``report.json`` (:meth:`hosid.check.locate.Localisation.report`), ``evidence.png``
(every round's pairs: :math:`|z|` against the round's Bonferroni threshold) and
``report.html`` (the decision, the record checks, the pairs' table, the figure, the final
system's estimate), a self-contained page from ``output/templates/locate.html.j2``.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

from matplotlib.figure import Figure

from ..check.locate import Localisation
from ..verdicts import overall
from .files import b64, png, render, write_atomic
from .results import jsonable

__all__ = ["evidence_figure", "write_locate"]


def _threshold(level: float) -> float:
    """The two-sided normal quantile of ``level``: the :math:`|z|` a pair must exceed."""
    from scipy.special import ndtri

    return float(-ndtri(level / 2.0))


def evidence_figure(loc: Localisation) -> Figure:
    """One panel a round: each pair's :math:`|z|`, the named one in red, the level dashed."""
    k = len(loc.rounds)
    fig = Figure(figsize=(7.0, 1.2 + 0.35 * max(len(r.weighed) for r in loc.rounds) * k),
                 layout="constrained")  # fmt: skip
    axes = fig.subplots(k, 1, squeeze=False)[:, 0]
    for n, (ax, r) in enumerate(zip(axes, loc.rounds, strict=True)):
        labels = [w.label for w in r.weighed]
        z = [abs(w.z) for w in r.weighed]
        colours = ["C3" if r.named is w else "C0" for w in r.weighed]
        ax.barh(range(len(z)), z, color=colours)
        ax.set_yticks(range(len(z)), labels, fontsize=8)
        ax.invert_yaxis()
        cut = _threshold(r.level)
        ax.axvline(cut, color="k", linestyle="--", linewidth=1)
        ax.set_title(f"round {n + 1}: dashed, the level |z| = {cut:.2f} "
                     f"(alpha {loc.alpha:g} / {len(z)} pairs); red, the pair named",
                     fontsize=9)  # fmt: skip
        ax.set_xlabel("|z| = |estimate| / sd")
    return fig


def _num(value: Any, digits: int = 3) -> str:
    if value is None or (isinstance(value, float) and not math.isfinite(value)):
        return "-"
    return f"{value:.{digits}g}" if isinstance(value, float) else str(value)


def write_locate(loc: Localisation, out_dir: str | Path) -> list[Path]:
    """Write ``report.json``, ``evidence.png`` and ``report.html`` into ``out_dir``."""
    out = Path(out_dir)
    rep = jsonable(loc.report())
    rep["verdict"] = overall(loc.record_checks)
    image = png(evidence_figure(loc))
    html = render("locate.html.j2", {"num": _num}, rep=rep, image=b64(image),
                  thresholds=[_threshold(r.level) for r in loc.rounds])  # fmt: skip
    return [
        write_atomic(out / "report.html", html.encode("utf-8")),
        write_atomic(out / "report.json", json.dumps(rep, indent=1).encode("utf-8")),
        write_atomic(out / "evidence.png", image),
    ]
