r"""The tasks of a batch: what one task is, its id and its random stream.

A task is one record through one analysis (``fit``, ``estimate`` or ``diagnose``) with
fixed options.  The record is a file (``hosid batch fit RECORD...``) or a design point
simulated in the worker (``hosid batch simulate-study``, :mod:`hosid.batch.design`).

Its **id** is a hash of everything its row depends on: the analysis, its options, the
root seed, the record's content hash (:attr:`hosid.record.Record.hash`) or the design
point, the true values and hosid's version.  A rerun finds the finished tasks by their
ids.

Its **random stream** is

.. math:: \mathrm{SeedSequence}(s,\ \mathrm{spawn\_key} = k),

the child ``SeedSequence(s).spawn`` would give at the position ``k``: for a record
``k = (h,)`` with ``h`` its 64-bit content hash, for the ``i``-th seed of a design row
with key ``r`` ``k = (r, i)``.  A design row may instead name its records' streams
by its own integers ``e`` (its ``entropy``, e.g. a hash of a study's cell name): the
``i``-th seed is then :math:`\mathrm{SeedSequence}([s, e_1, \dots, i])`, with no
spawn key.  Its two children (``spawn`` positions 0 and 1) drive the simulation and the
analysis.  Nothing depends on the worker that runs the task or on the order in which
tasks finish.

Options added to an analysis after batches had run (:data:`LATER`) enter the id only
when they differ from their default: the finished rows of those batches stay valid.
"""

from __future__ import annotations

import dataclasses
import glob
import hashlib
import json
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path
from typing import Any

import numpy as np

from ..check.diagnose import DEFAULT_REPLICATES
from ..errors import HosidInputError
from ..record import Record

__all__ = [
    "ANALYSES",
    "CHOICES",
    "LATER",
    "MANIFEST_SUFFIXES",
    "OPTIONS",
    "DesignPoint",
    "Task",
    "child_seed",
    "expand_inputs",
    "options_for",
    "record_tasks",
]

#: The analyses a task can run.
ANALYSES = ("fit", "estimate", "diagnose")
#: Every analysis's options and their defaults (the keyword arguments it is run with).
OPTIONS: dict[str, dict[str, Any]] = {
    "fit": {
        "model": "paper",
        "excitation_shape": None,
        "cost": None,
        "constrained": True,
        "n_walkers": 32,
        "n_steps": None,
        "block_seconds": None,
        "omega_max": None,
        "form": "scaled",
        "domain": "principal",
        "measured": None,
    },
    "estimate": {
        "model": "paper",
        "excitation_shape": None,
        "cost": None,
        "block_seconds": None,
        "omega_max": None,
        "form": "scaled",
        "domain": "principal",
        "measured": None,
    },
    "diagnose": {
        "model": "paper",
        "excitation_shape": None,
        "candidates": None,
        "replicates": DEFAULT_REPLICATES,
        "alpha": 0.05,
        "threshold": 3.0,
        "max_effects": None,
        "posterior": "emcee",
        "candidate_gaps": True,
    },
}
#: Options added after batches had run: left out of a task's id at their default.
LATER: dict[str, tuple[str, ...]] = {
    "fit": ("excitation_shape", "measured"),
    "estimate": ("excitation_shape", "measured"),
    "diagnose": ("posterior", "candidate_gaps", "excitation_shape"),
}
#: The values an option may take (the others are checked by the analysis itself).
CHOICES: dict[str, tuple[Any, ...]] = {
    "posterior": ("emcee", "screen"),
    "candidate_gaps": (True, False),
    "measured": (None, "displacement", "acceleration"),
}
#: Files read as lists of records (one path or glob a line, ``#`` comments).
MANIFEST_SUFFIXES = (".txt", ".lst", ".list")
_GLOB_CHARS = frozenset("*?[")


def options_for(analysis: str, options: Mapping[str, Any] | None = None) -> dict[str, Any]:
    """The analysis's full options: ``options`` over :data:`OPTIONS`'s defaults (so a
    default given explicitly or left out gives the same task id).

    Raises
    ------
    HosidInputError
        For an unknown analysis or option, or a value outside :data:`CHOICES`.
    """
    if analysis not in ANALYSES:
        raise HosidInputError(f"unknown analysis {analysis!r}: {', '.join(ANALYSES)}")
    given = dict(options or {})
    unknown = set(given) - set(OPTIONS[analysis])
    if unknown:
        raise HosidInputError(
            f"option(s) {', '.join(sorted(unknown))} do not apply to {analysis}; "
            f"its options: {', '.join(OPTIONS[analysis])}"
        )
    if isinstance(given.get("model"), Sequence) and not isinstance(given["model"], str):
        given["model"] = ",".join(given["model"])
    if given.get("candidates") is not None:
        given["candidates"] = list(given["candidates"])
    for name, value in given.items():
        allowed = CHOICES.get(name)
        if allowed is not None and not any(
            value is a or (type(value) is type(a) and value == a) for a in allowed
        ):
            choices = ", ".join(repr(a) for a in allowed)
            raise HosidInputError(f"option {name} of {analysis}: {choices}; got {value!r}")
    return {**OPTIONS[analysis], **given}


def child_seed(seed: np.random.SeedSequence, i: int) -> np.random.SeedSequence:
    """The ``i``-th child of ``seed`` as ``seed.spawn`` gives it on a fresh sequence,
    whatever ``seed`` has spawned before.
    """
    return np.random.SeedSequence(seed.entropy, spawn_key=(*seed.spawn_key, i))


@dataclass(frozen=True)
class DesignPoint:
    """One record to simulate: parameters, length, simulator, and its place in the
    design (row ``name`` with seed key ``key``, seed number ``index``; ``entropy``, when
    given, names its random stream instead of the key: module docstring).
    """

    name: str
    key: int
    index: int
    params: Mapping[str, float] = field(hash=False)
    duration: float = 2000.0
    dt: float = 0.02
    simulator: str = "hosid"
    ref: str = field(default="", compare=False)  # the resolved simulator, not in the id
    entropy: tuple[int, ...] = ()

    @property
    def label(self) -> str:
        """The record's name in the results table, ``<row name>-<seed number>``."""
        return f"{self.name}-{self.index}"

    def describe(self) -> dict[str, Any]:
        """What the simulated record depends on (part of the task's id)."""
        out = {
            "params": {k: float(v) for k, v in sorted(self.params.items())},
            "duration": float(self.duration),
            "dt": float(self.dt),
            "simulator": self.simulator,
            "key": [int(self.key), int(self.index)],
        }
        if self.entropy:  # absent otherwise: the ids of keyed designs stay as they were
            out["entropy"] = [int(e) for e in self.entropy]
        return out


@dataclass(frozen=True, eq=False)
class Task:
    """One record through one analysis.

    Parameters
    ----------
    label : str
        The record column of the results table (the path as given, or the design
        point's label).
    analysis : {"fit", "estimate", "diagnose"}
    options : mapping
        Keyword options of the analysis (JSON values): ``model``, ``cost`` ...
    seed : int
        Root seed of the batch.
    path : str, optional
        A record file, read by :meth:`prepare`.
    record : Record, optional
        The record (after :meth:`prepare`).
    point : DesignPoint, optional
        A record to simulate in the worker.
    truths : mapping, optional
        True parameter values (a record's ``.truths.json``, a design's parameters).
    """

    label: str
    analysis: str
    options: Mapping[str, Any] = field(hash=False)
    seed: int = 0
    path: str | None = None
    record: Record | None = field(default=None, hash=False, repr=False)
    point: DesignPoint | None = None
    truths: Mapping[str, float] | None = field(default=None, hash=False)

    def __post_init__(self) -> None:
        if self.analysis not in ANALYSES:
            raise HosidInputError(f"unknown analysis {self.analysis!r}: {', '.join(ANALYSES)}")
        if (self.path is None) + (self.record is None) + (self.point is None) != 2:
            raise ValueError("a task needs exactly one of path, record or point")

    @property
    def ready(self) -> bool:
        """Whether the task can be sent to a worker (its record read, or simulated there)."""
        return self.path is None

    def prepare(self) -> Task:
        """The task with its record read from :attr:`path` and the true values of its
        ``.truths.json`` beside it.

        Raises
        ------
        HosidInputError
            If the record or its truths cannot be read.
        """
        if self.ready:
            return self
        from ..record import read_record, read_truths  # the sidecar, as ``hosid fit``

        record = read_record(self.path)
        truths = read_truths(self.path)
        return dataclasses.replace(self, path=None, record=record, truths=truths)

    @cached_property
    def source(self) -> dict[str, Any]:
        """The record's identity: content hash, or design point."""
        if self.point is not None:
            return {"design": self.point.describe()}
        if self.record is None:
            raise ValueError("prepare() the task first")
        return {"record_hash": self.record.hash}

    @cached_property
    def id(self) -> str:
        """16 hex digits of the SHA-256 of the analysis, options, seed, source, true values
        and hosid's version.
        """
        from .. import __version__

        defaults = OPTIONS[self.analysis]
        later = LATER.get(self.analysis, ())
        options = {k: v for k, v in self.options.items() if not (k in later and v == defaults[k])}
        text = json.dumps(
            {
                "analysis": self.analysis,
                "options": options,
                "seed": int(self.seed),
                **self.source,
                "truths": dict(self.truths or {}),
                "hosid": __version__,
            },
            sort_keys=True,
        )
        return hashlib.sha256(text.encode()).hexdigest()[:16]

    @property
    def spawn_key(self) -> tuple[int, ...]:
        """The task's position among ``SeedSequence(seed).spawn`` (module docstring);
        empty for a design point with its own entropy.
        """
        if self.point is not None:
            if self.point.entropy:
                return ()
            return (int(self.point.key), int(self.point.index))
        return (int(self.source["record_hash"], 16),)

    def seed_sequence(self) -> np.random.SeedSequence:
        """The task's random stream (module docstring)."""
        if self.point is not None and self.point.entropy:
            words = [int(self.seed), *(int(e) for e in self.point.entropy), int(self.point.index)]
            return np.random.SeedSequence(words)
        return np.random.SeedSequence(int(self.seed), spawn_key=self.spawn_key)


def _manifest(path: Path) -> list[str]:
    try:
        lines = path.read_text().splitlines()
    except (OSError, UnicodeDecodeError) as exc:
        raise HosidInputError(f"cannot read the manifest {path}: {exc}") from None
    items = []
    for line in lines:
        item = line.split("#", 1)[0].strip()
        if item:
            p = Path(item)
            items.append(str(p if p.is_absolute() else path.parent / p))
    return items


def expand_inputs(items: Iterable[str]) -> list[str]:
    """Record paths from paths, glob patterns and manifest files, in the order given
    (each glob's matches sorted), each path once.

    A manifest (suffix ``.txt``, ``.lst`` or ``.list``) lists one path or pattern a line,
    relative to its own folder; ``#`` starts a comment.  A path that does not exist stays
    in the list (its task fails with an error row).

    Raises
    ------
    HosidInputError
        If a pattern matches nothing or no record is named at all.
    """
    out: list[str] = []
    seen: set[str] = set()

    def add(item: str, depth: int) -> None:
        if _GLOB_CHARS & set(item):
            matches = sorted(glob.glob(item, recursive=True))
            if not matches:
                raise HosidInputError(f"no file matches {item!r}")
            for m in matches:
                add(m, depth)
            return
        p = Path(item)
        if p.suffix.lower() in MANIFEST_SUFFIXES:
            if depth > 4:
                raise HosidInputError(f"{item}: manifests nested too deeply")
            for sub in _manifest(p):
                add(sub, depth + 1)
            return
        key = str(p.resolve())
        if key not in seen:
            seen.add(key)
            out.append(item)

    for item in items:
        add(str(item), 0)
    if not out:
        raise HosidInputError("no records given")
    return out


def record_tasks(
    inputs: Sequence[str | Record],
    *,
    analysis: str,
    options: Mapping[str, Any],
    seed: int = 0,
) -> list[Task]:
    """One task per record: paths (read when the batch reaches them) or records.

    Parameters
    ----------
    inputs : sequence of str or Record
        Paths (already expanded, :func:`expand_inputs`) or records in memory.
    analysis : {"fit", "estimate", "diagnose"}
    options : mapping
        The analysis's options (:data:`OPTIONS`; the others keep their defaults).
    seed : int
        Root seed.
    """
    options = options_for(analysis, options)
    tasks = []
    for i, item in enumerate(inputs):
        if isinstance(item, Record):
            label = item.name or f"record-{i}"
            tasks.append(Task(label, analysis, options, seed, record=item))
        else:
            tasks.append(Task(str(item), analysis, options, seed, path=str(item)))
    return tasks
