"""Simulation designs: parameters x seeds x record lengths, simulated in the worker.

A design is a table (CSV with a header, or a JSON list of objects), one row per
parameter set and record length:

=============  =====================================================================
column         meaning
=============  =====================================================================
``name``       the row's label (default ``row<i>``); records are ``<name>-<seed>``
``key``        the row's seed key, an integer (default its position); records of
               the row use ``SeedSequence(seed).spawn`` position ``(key, seed number)``
``seeds``      how many records (seed numbers ``0 .. seeds - 1``; default 1)
``duration``   record length in seconds (default 2000)
``dt``         sampling interval in seconds (default 0.02)
``simulator``  ``hosid`` (:func:`hosid.model.simulate`, default) or
               ``FILE.py:FUNCTION`` (relative to the design's folder) or
               ``module:function``, called as ``f(params, duration=, dt=, rng=, name=)``
               and returning a :class:`~hosid.record.Record` or ``(record, velocity)``
``entropy``    optional integers (a JSON list, or separated by spaces) that name the
               row's random streams instead of its key: record ``i`` uses
               ``SeedSequence([seed, *entropy, i])`` (a study's own streams, so that
               the batch reproduces records it made before)
a1 ... S0      the true parameters (:data:`hosid.model.simulate.SIM_KEYS`); empty = absent
change_at      a step (or with ``ramp``, a ramp) of the parameters ``a1_after``,
               ``n1_after``, ``a2_after``, ``n2_after``, ``S0_after`` ... at that time
               (s; :data:`hosid.model.change.FLAT_KEYS`)
=============  =====================================================================

Keys fix the records: adding rows, or seeds to a row, leaves every other record as it
was.  The simulated velocity, when the simulator returns it, gives the true equivalent
damping of eq (65).
"""

from __future__ import annotations

import csv
import functools
import importlib
import importlib.util
import json
import math
import sys
import zlib
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import HosidInputError
from ..model.change import FLAT_KEYS, Change
from ..model.simulate import SIM_KEYS
from ..model.simulate import _check as check_simulation
from ..record import Record
from .tasks import DesignPoint, Task, options_for

__all__ = ["COLUMNS", "DesignRow", "design_tasks", "load_simulator", "read_design", "simulate"]

#: Columns besides the parameters.
COLUMNS = ("name", "key", "seeds", "duration", "dt", "simulator", "entropy")


@dataclass(frozen=True)
class DesignRow:
    """One row of a design (module docstring)."""

    name: str
    key: int
    params: Mapping[str, float] = field(hash=False)
    seeds: int = 1
    duration: float = 2000.0
    dt: float = 0.02
    simulator: str = "hosid"
    folder: str = field(default=".", compare=False)  # the design file's (read_design)
    entropy: tuple[int, ...] = ()

    def points(self, folder: str | Path | None = None) -> list[DesignPoint]:
        """The row's records (``folder``, default the design file's, resolves a relative
        simulator file).
        """
        ref = _resolve(self.simulator, Path(self.folder if folder is None else folder))
        return [
            DesignPoint(
                self.name,
                self.key,
                i,
                dict(self.params),
                self.duration,
                self.dt,
                self.simulator,
                ref,
                tuple(self.entropy),
            )
            for i in range(self.seeds)
        ]


def _number(value: Any, what: str) -> float:
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise HosidInputError(f"{what}: not a number: {value!r}") from None
    if not math.isfinite(x):
        raise HosidInputError(f"{what}: must be finite, got {value!r}")
    return x


def _integer(value: Any, what: str, minimum: int) -> int:
    x = _number(value, what)
    if x != int(x) or x < minimum:
        raise HosidInputError(f"{what}: must be an integer >= {minimum}, got {value!r}")
    return int(x)


def _entropy(value: Any, what: str) -> tuple[int, ...]:
    items = value.split() if isinstance(value, str) else value
    if not isinstance(items, list | tuple) or not items:
        raise HosidInputError(f"{what}: a list of integers, got {value!r}")
    return tuple(_integer(v, what, 0) for v in items)


def _row(i: int, raw: Mapping[str, Any], where: str, folder: Path) -> DesignRow:
    if not isinstance(raw, Mapping):
        raise HosidInputError(f"{where}: row {i} is not an object of columns")
    cells = {str(k).strip(): v for k, v in raw.items() if v is not None and str(v).strip() != ""}
    keys = (*SIM_KEYS, *FLAT_KEYS)
    unknown = set(cells) - set(COLUMNS) - set(keys)
    if unknown:
        raise HosidInputError(
            f"{where}: unknown column(s) {', '.join(sorted(unknown))}; "
            f"valid: {', '.join((*COLUMNS, *keys))}"
        )
    at = f"{where} row {i}"
    params = {k: _number(cells[k], f"{at}, {k}") for k in keys if k in cells}
    row = DesignRow(
        name=str(cells.get("name", f"row{i}")).strip(),
        key=_integer(cells.get("key", i), f"{at}, key", 0),
        params=params,
        seeds=_integer(cells.get("seeds", 1), f"{at}, seeds", 1),
        duration=_number(cells.get("duration", 2000.0), f"{at}, duration"),
        dt=_number(cells.get("dt", 0.02), f"{at}, dt"),
        simulator=str(cells.get("simulator", "hosid")).strip(),
        folder=str(folder),
        entropy=_entropy(cells["entropy"], f"{at}, entropy") if "entropy" in cells else (),
    )
    try:
        base, change = Change.split(row.params)
        check_simulation(base, row.duration, row.dt, 1)
        if change is not None:
            change.validate(base, row.duration, row.dt, 1)
        load_simulator(_resolve(row.simulator, folder))
    except HosidInputError as exc:
        raise HosidInputError(f"{at}: {exc}") from None
    return row


def read_design(path: str | Path) -> list[DesignRow]:
    """The rows of a design file (module docstring).

    Raises
    ------
    HosidInputError
        If the file cannot be read, a value is invalid, a simulator cannot be loaded,
        or names or keys repeat.
    """
    path = Path(path)
    try:
        text = path.read_text()
    except (OSError, UnicodeDecodeError) as exc:
        raise HosidInputError(f"cannot read the design {path}: {exc}") from None
    if path.suffix.lower() == ".json":
        try:
            raw = json.loads(text)
        except json.JSONDecodeError as exc:
            raise HosidInputError(f"{path}: not valid JSON ({exc})") from None
        if not isinstance(raw, list):
            raise HosidInputError(f"{path}: a design is a JSON list of row objects")
    elif path.suffix.lower() == ".csv":
        raw = list(csv.DictReader(text.splitlines()))
    else:
        raise HosidInputError(f"{path}: a design is a .csv or .json file")
    if not raw:
        raise HosidInputError(f"{path}: the design has no rows")
    rows = [_row(i, r, str(path), path.parent) for i, r in enumerate(raw)]
    for attr in ("name", "key"):
        values = [getattr(r, attr) for r in rows]
        twice = sorted({str(v) for v in values if values.count(v) > 1})
        if twice:
            raise HosidInputError(f"{path}: rows share the {attr} {', '.join(twice)}")
    return rows


def design_tasks(
    rows: Sequence[DesignRow],
    *,
    analysis: str,
    options: Mapping[str, Any],
    seed: int = 0,
    folder: str | Path | None = None,
) -> list[Task]:
    """One task per record of the design: row by row, seed number by seed number
    (``options`` as in :func:`hosid.batch.record_tasks`).

    ``folder`` resolves relative simulator files; default each row's own (the folder of
    the design file :func:`read_design` read it from; the working directory for rows
    built by hand).
    """
    options = options_for(analysis, options)
    return [
        Task(point.label, analysis, options, seed, point=point, truths=dict(row.params))
        for row in rows
        for point in row.points(folder)
    ]


def _resolve(simulator: str, folder: Path) -> str:
    """``hosid``, ``module:function`` or an absolute ``FILE.py:FUNCTION``."""
    if simulator == "hosid":
        return simulator
    file, sep, func = simulator.rpartition(":")
    if not sep or not file or not func.isidentifier():
        raise HosidInputError(
            f"simulator {simulator!r}: use hosid, FILE.py:FUNCTION or module:function"
        )
    if file.endswith(".py"):
        p = Path(file)
        return f"{(p if p.is_absolute() else folder / p).resolve()}:{func}"
    return simulator


@functools.cache
def load_simulator(ref: str) -> Callable[..., Any]:
    """The simulator function of a resolved reference (imported once a process).

    Raises
    ------
    HosidInputError
        If the file or module cannot be imported or has no such function.
    """
    if ref == "hosid":
        return _hosid_simulate
    where, _, func = ref.rpartition(":")
    try:
        if where.endswith(".py"):
            module = _import_file(Path(where))
        else:
            module = importlib.import_module(where)
    except HosidInputError:
        raise
    except Exception as exc:
        raise HosidInputError(f"cannot import the simulator {where}: {exc}") from None
    fn = getattr(module, func, None)
    if not callable(fn):
        raise HosidInputError(f"simulator {where} has no function {func!r}")
    return fn


def _hosid_simulate(params, **kw):
    """The package's simulator, given a design's flat change keys (:data:`FLAT_KEYS`)."""
    from ..model.simulate import simulate as hosid_simulate

    base, change = Change.split(params)
    return hosid_simulate(base, change=change, return_velocity=True, **kw)


def _import_file(path: Path):
    """Import a simulator file as the module named by its stem, registered in
    ``sys.modules`` (so numba's on-disk cache and pickle find it by that name when the
    script imports it too); a different module already of that name keeps it, and the
    file gets a name of its own.
    """
    if not path.is_file():
        raise HosidInputError(f"simulator file {path}: no such file")
    name = path.stem
    known = sys.modules.get(name)
    if known is not None:
        if Path(getattr(known, "__file__", "") or "").resolve() == path.resolve():
            return known
        name = f"hosid_batch_{name}_{zlib.crc32(str(path.resolve()).encode()):08x}"
    spec = importlib.util.spec_from_file_location(name, path)
    if spec is None or spec.loader is None:
        raise HosidInputError(f"simulator file {path}: not a Python module")
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    try:
        spec.loader.exec_module(module)
    except BaseException:
        del sys.modules[name]
        raise
    return module


def simulate(point: DesignPoint, *, rng: np.random.Generator) -> tuple[Record, np.ndarray | None]:
    """Simulate the record of ``point``; also the simulated velocity when the simulator
    returns it.
    """
    out = load_simulator(point.ref or point.simulator)(
        dict(point.params), duration=point.duration, dt=point.dt, rng=rng, name=point.label
    )
    record, velocity = out if isinstance(out, tuple) else (out, None)
    if not isinstance(record, Record):
        raise TypeError(f"the simulator {point.simulator} returned {type(record).__name__}")
    return record, None if velocity is None else np.asarray(velocity)
