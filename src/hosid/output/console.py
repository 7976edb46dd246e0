"""What the commands print: numbers to four digits and aligned plain-text tables."""

from __future__ import annotations

import math
import sys
from collections.abc import Sequence

__all__ = ["FIT_COLUMNS", "fmt", "print_fit", "table"]

#: The columns of the posterior table a fit prints.
FIT_COLUMNS = ("mean", "sd", "q05", "q50", "q95", "r_hat", "ess_bulk")


def fmt(value) -> str:
    """A number to four significant digits; ``-`` for ``None`` and NaN; other values as text."""
    if value is None:
        return "-"
    try:
        number = float(value)
    except (TypeError, ValueError):
        return str(value)
    return "-" if math.isnan(number) else f"{number:.4g}"


def table(header: Sequence[str], rows: Sequence[Sequence[str]]) -> str:
    """``rows`` under ``header`` in left-aligned columns, a rule under the header."""
    widths = [max(len(r[i]) for r in [header, *rows]) for i in range(len(header))]
    lines = [
        "  ".join(c.ljust(w) for c, w in zip(r, widths, strict=True)).rstrip()
        for r in [header, *rows]
    ]
    lines.insert(1, "  ".join("-" * w for w in widths))
    return "\n".join(lines)


def print_fit(summary: dict) -> None:
    """A fit's summary (``summary.json``): one line, the posterior table, and the failed
    convergence diagnostics as a warning on stderr.
    """
    params = summary["parameters"]
    print(
        f"{summary.get('record') or 'record'}: {' + '.join(summary.get('model') or [])}, "
        f"components {', '.join(summary.get('components') or [])}; "
        f"{summary['n_walkers']} walkers x {summary['n_draws']} draws, "
        f"{fmt(summary.get('fit_seconds'))} s"
    )
    rows = [[k, *(fmt(r.get(c)) for c in FIT_COLUMNS)] for k, r in params.items()]
    print(table(["parameter", *FIT_COLUMNS], rows))
    if summary.get("diagnostic_failures"):
        print(
            "hosid: warning: convergence diagnostics failed: "
            + "; ".join(summary["diagnostic_failures"]),
            file=sys.stderr,
        )
