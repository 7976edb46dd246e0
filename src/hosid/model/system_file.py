r"""A system's description checked, and read from a TOML file (standard-library ``tomllib``).

The file names the degrees of freedom (the record's columns) and the elements, each
between two of them or the ground and one, with drift terms of the single oscillator's
library (:mod:`hosid.model.system` for the equations):

.. code-block:: toml

    dofs = ["x1", "x2"]
    driven = ["x2"]                  # optional: the dofs with a white force (default all)
    measured = "acceleration"        # optional: or a table by dof (default displacement)
    sensor_noise = true              # optional: each channel's white noise level N[dof]
                                     # a parameter (or a list of dofs; default: when a
                                     # linear system's accelerations need it)
    excitation = "narrowband_excitation"  # optional: the driven forces' shared spectral
                                     # shape (parameters wf, zf; or "white"; default:
                                     # white unless a linear system's record rejects it)

    [[element]]
    between = ["ground", "x1"]
    terms = ["linear_damping", "quadratic_damping", "linear_stiffness", "cubic_stiffness"]

    [[element]]
    between = ["x1", "x2"]
    terms = ["linear_damping", "linear_stiffness"]

    [masses]                         # optional: known masses (x1: 1 unless given)
    x2 = 0.5

    [values]                         # optional: parameter values (a simulation's truth)
    "a1[ground-x1]" = 0.5

Every mistake is one line of :class:`hosid.errors.HosidInputError` naming the file and
what is wrong: an unknown key, dof or term, an element between a dof and itself or two
elements between the same pair, a dof no element touches or one not joined to the
ground, a non-positive mass, an unknown or non-finite value.
"""

from __future__ import annotations

import math
import numbers
import re
import tomllib
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

from ..errors import HosidInputError
from ..record.core import MEASURED
from .model import _ORDER, ALIASES, get_term
from .terms import DriftTerm

if TYPE_CHECKING:  # pragma: no cover
    from .system import System

__all__ = ["GROUND", "MEASURED_KINDS", "RESERVED", "read_system", "system_from_dict"]

#: The name of the fixed end of an element.
GROUND = "ground"
#: What a channel of a record may hold (the record's own list).
MEASURED_KINDS = MEASURED
#: Names a degree of freedom may not take (the ground, a record file's other columns).
RESERVED = (GROUND, "t", "dt", "segment", "dofs", "measured")
#: The keys of a system file and of one of its elements.
KEYS = ("dofs", "element", "masses", "driven", "measured", "sensor_noise", "excitation", "values")
#: The spectral shapes a system's forces may share (:mod:`hosid.model.excitation`).
SHAPES = ("coloured_excitation", "narrowband_excitation", "bandpass_excitation")
ELEMENT_KEYS = ("between", "terms")
_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")


def check_dofs(dofs: Any) -> tuple[str, ...]:
    """The dof names: a non-empty list of distinct identifiers, none reserved."""
    if isinstance(dofs, str) or not isinstance(dofs, Sequence) or not len(dofs):
        raise HosidInputError("dofs must be a non-empty list of names, e.g. ['x1', 'x2']")
    for d in dofs:
        if not isinstance(d, str) or not _NAME.fullmatch(d) or d in RESERVED:
            raise HosidInputError(
                f"bad degree of freedom name {d!r}: letters, digits and _, not starting with "
                f"a digit, and none of {', '.join(RESERVED)}"
            )
    dup = [d for k, d in enumerate(dofs) if d in dofs[:k]]
    if dup:
        raise HosidInputError(f"degree of freedom {dup[0]!r} given twice")
    return tuple(dofs)


def check_element(item: Any, dofs: Sequence[str], k: int) -> tuple[tuple[str, str], tuple]:
    """``(between, terms)`` of element ``k`` checked: the ground first, the terms drift
    terms of the library in its order.
    """
    where = f"element {k + 1}"
    try:
        between, terms = item
    except (TypeError, ValueError):
        raise HosidInputError(f"{where}: give between and terms") from None
    if (
        isinstance(between, str)
        or not isinstance(between, Sequence)
        or len(between) != 2
        or not all(isinstance(b, str) for b in between)
    ):
        raise HosidInputError(f"{where}: between must be two names, e.g. ['ground', 'x1']")
    a, b = between
    for end in (a, b):
        if end != GROUND and end not in dofs:
            raise HosidInputError(
                f"{where}: unknown degree of freedom {end!r}; dofs: {', '.join(dofs)} (or ground)"
            )
    if a == b:
        raise HosidInputError(f"{where}: between {a!r} and itself")
    a, b = (b, a) if b == GROUND else (a, b)
    if isinstance(terms, str) or not isinstance(terms, Sequence) or not len(terms):
        raise HosidInputError(f"{where} ({a}-{b}): terms must be a non-empty list of names")
    found: list[DriftTerm] = []
    names = [n for t in terms for n in (ALIASES.get(t, (t,)) if isinstance(t, str) else (t,))]
    for t in names:
        try:
            term = t if isinstance(t, DriftTerm) else get_term(t)
        except HosidInputError as exc:
            raise HosidInputError(f"{where} ({a}-{b}): {exc}") from None
        if not isinstance(term, DriftTerm):
            raise HosidInputError(
                f"{where} ({a}-{b}): {term.name} is not a drift term (an element holds forces "
                "of its relative motion; the excitation is given by driven and S0)"
            )
        if term.name in (f.name for f in found):
            raise HosidInputError(f"{where} ({a}-{b}): term {term.name} given twice")
        found.append(term)
    found.sort(key=lambda t: _ORDER.get(t.name, len(_ORDER)))
    return (a, b), tuple(found)


def check_topology(dofs: Sequence[str], elements: Sequence[tuple[tuple[str, str], tuple]]):
    """One element a pair, every dof touched and joined to the ground, and a restoring
    and a damping term somewhere.
    """
    pairs = [frozenset(between) for between, _ in elements]
    for k, p in enumerate(pairs):
        if p in pairs[:k]:
            raise HosidInputError(
                f"two elements between {'-'.join(elements[k][0])}: give one element with "
                "all its terms"
            )
    touched = {d for between, _ in elements for d in between}
    for d in dofs:
        if d not in touched:
            raise HosidInputError(f"no element touches degree of freedom {d!r}")
    reached, frontier = {GROUND}, [GROUND]
    while frontier:
        node = frontier.pop()
        for between, _ in elements:
            if node in between:
                other = between[1] if between[0] == node else between[0]
                if other not in reached:
                    reached.add(other)
                    frontier.append(other)
    loose = [d for d in dofs if d not in reached]
    if loose:
        raise HosidInputError(
            f"{', '.join(loose)} not joined to the ground by elements: the response would "
            "have no stationary state"
        )
    variables = {t.variable for _, terms in elements for t in terms}
    if "x" not in variables or "v" not in variables:
        raise HosidInputError("the system needs a restoring term and a damping term")


def _positive(value: Any, what: str) -> float:
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise HosidInputError(f"{what} must be a number, got {value!r}")
    if not (math.isfinite(value) and value > 0):
        raise HosidInputError(f"{what} must be finite and positive, got {value!r}")
    return float(value)


def check_masses(masses: Any, dofs: Sequence[str]) -> tuple[float | None, ...]:
    """A known mass or ``None`` (a parameter) per dof, from a mapping by dof (the first
    dof's mass 1 unless given) or that tuple itself.
    """
    if isinstance(masses, Mapping):
        for d in masses:
            if d not in dofs:
                raise HosidInputError(f"masses: unknown degree of freedom {d!r}")
        return tuple(
            _positive(masses[d], f"mass of {d}") if d in masses else (1.0 if k == 0 else None)
            for k, d in enumerate(dofs)
        )
    if isinstance(masses, str) or not isinstance(masses, Sequence):
        raise HosidInputError("masses must be a table of known masses by degree of freedom")
    if not len(masses):
        return (1.0, *([None] * (len(dofs) - 1)))
    if len(masses) != len(dofs):
        raise HosidInputError(f"masses: {len(masses)} given for {len(dofs)} degrees of freedom")
    return tuple(
        None if m is None else _positive(m, f"mass of {d}")
        for d, m in zip(dofs, masses, strict=True)
    )


def check_driven(driven: Any, dofs: Sequence[str]) -> tuple[str, ...]:
    """The driven dofs in dof order (default all)."""
    if isinstance(driven, str) or not isinstance(driven, Sequence):
        raise HosidInputError("driven must be a list of degrees of freedom, e.g. ['x2']")
    for d in driven:
        if d not in dofs:
            raise HosidInputError(f"driven: unknown degree of freedom {d!r}")
    if len(set(driven)) != len(driven):
        raise HosidInputError("driven lists a degree of freedom twice")
    return tuple(d for d in dofs if d in driven) if len(driven) else tuple(dofs)


def check_sensor_noise(noise: Any, dofs: Sequence[str]) -> tuple[str, ...] | None:
    """The dofs whose channels carry a white sensor noise of their own level (a parameter
    ``N[dof]``), in dof order: ``true`` for all, ``false`` or empty for none, or a list;
    ``None`` (not given) leaves it to the record (:mod:`hosid.inference.system_estimate`).
    """
    if noise is None:
        return None
    if isinstance(noise, bool):
        return tuple(dofs) if noise else ()
    if isinstance(noise, str) or not isinstance(noise, Sequence):
        raise HosidInputError("sensor_noise must be true, false or a list of degrees of freedom")
    for d in noise:
        if d not in dofs:
            raise HosidInputError(f"sensor_noise: unknown degree of freedom {d!r}")
    return tuple(d for d in dofs if d in noise)


def check_excitation(excitation: Any) -> tuple | None:
    """The shape term the driven dofs' forces share (one of :data:`SHAPES`, by name or as
    a term), as a tuple: empty for ``"white"`` or an empty list; ``None`` (not given: the
    record chooses, :func:`hosid.inference.spectral_pilot.settled_shape`) stays ``None``.
    """
    if excitation is None:
        return None
    if excitation == "white":
        return ()
    items = [excitation] if isinstance(excitation, str) else excitation
    if not isinstance(items, Sequence):
        raise HosidInputError(f"excitation must be 'white' or one of {', '.join(SHAPES)}")
    terms = tuple(get_term(t) if isinstance(t, str) and t in SHAPES else t for t in items)
    bad = [t for t in terms if getattr(t, "name", None) not in SHAPES]
    if bad or len(terms) > 1:
        what = f"{bad[0]!r} is not" if bad else "several shapes are not"
        raise HosidInputError(f"excitation: {what} a system's force shape; give 'white' or one "
                              f"of {', '.join(SHAPES)}")  # fmt: skip
    return terms


def check_values(values: Mapping, names: Sequence[str]) -> tuple[tuple[str, float], ...]:
    """Parameter values by name as ``(name, value)`` pairs in ``names`` order."""
    unknown = [k for k in values if k not in names]
    if unknown:
        raise HosidInputError(
            f"values: unknown parameter {unknown[0]!r}; parameters: {', '.join(names)}"
        )
    for k, v in values.items():
        if isinstance(v, bool) or not isinstance(v, numbers.Real) or not math.isfinite(v):
            raise HosidInputError(f"values: {k} must be a finite number, got {v!r}")
    return tuple((k, float(values[k])) for k in names if k in values)


def check_measured(measured: Any, dofs: Sequence[str]) -> tuple[str | None, ...]:
    """What each channel measures as declared: one kind for all, a mapping by dof, or a
    tuple; ``None`` for a dof the declaration does not name (undeclared: a record's file
    then says what it holds, and a simulation writes a displacement).
    """
    if isinstance(measured, str):
        measured = dict.fromkeys(dofs, measured)
    if isinstance(measured, Mapping):
        for d in measured:
            if d not in dofs:
                raise HosidInputError(f"measured: unknown degree of freedom {d!r}")
        measured = tuple(measured.get(d) for d in dofs)
    measured = tuple(measured) or (None,) * len(dofs)
    bad = [m for m in measured if m is not None and m not in MEASURED_KINDS]
    if bad or len(measured) != len(dofs):
        raise HosidInputError(
            f"measured must be {' or '.join(MEASURED_KINDS)} (for all dofs or by dof), "
            f"got {bad[0] if bad else measured!r}"
        )
    return measured


def system_from_dict(data: Mapping[str, Any], source: str = "") -> System:
    """A :class:`hosid.model.system.System` from a parsed system file (module docstring).

    Raises
    ------
    HosidInputError
        One line, prefixed by ``source``, on any mistake.
    """
    from .system import System

    prefix = f"{source}: " if source else ""
    try:
        if not isinstance(data, Mapping):
            raise HosidInputError("a system file is a TOML table")
        unknown = [k for k in data if k not in KEYS]
        if unknown:
            raise HosidInputError(f"unknown key {unknown[0]!r}; valid keys: {', '.join(KEYS)}")
        if "dofs" not in data:
            raise HosidInputError("dofs missing, e.g. dofs = ['x1', 'x2']")
        check_dofs(data["dofs"])
        elements = data.get("element", [])
        if isinstance(elements, Mapping) or not isinstance(elements, list) or not elements:
            raise HosidInputError("give the elements as [[element]] tables (one or more)")
        items = []
        for k, el in enumerate(elements):
            if not isinstance(el, Mapping):
                raise HosidInputError(f"element {k + 1}: not a table")
            bad = [key for key in el if key not in ELEMENT_KEYS]
            missing = [key for key in ELEMENT_KEYS if key not in el]
            if bad or missing:
                what = f"unknown key {bad[0]!r}" if bad else f"{missing[0]} missing"
                raise HosidInputError(f"element {k + 1}: {what}; keys: between, terms")
            items.append((el["between"], el["terms"]))
        for key in ("masses", "values"):
            if key in data and not isinstance(data[key], Mapping):
                raise HosidInputError(f"{key} must be a table ([{key}])")
        return System(
            data["dofs"],
            tuple(items),
            masses=data.get("masses", {}),
            driven=data.get("driven", ()),
            measured=data.get("measured", ()),
            sensor_noise=data.get("sensor_noise"),
            excitation=data.get("excitation"),
            values=data.get("values", {}),
        )
    except HosidInputError as exc:
        raise HosidInputError(f"{prefix}{exc}") from None


def read_system(path: str | Path) -> System:
    """Read and check a system file (module docstring).

    Raises
    ------
    HosidInputError
        If the file is missing, not UTF-8 TOML, or describes no valid system (one line).
    """
    path = Path(path)
    if not path.is_file():
        raise HosidInputError(
            f"{path}: no such file" if not path.exists() else f"{path}: not a file"
        )
    try:
        with path.open("rb") as fh:
            data = tomllib.load(fh)
    except tomllib.TOMLDecodeError as exc:
        raise HosidInputError(f"{path}: not a valid TOML file: {exc}") from None
    except UnicodeDecodeError:
        raise HosidInputError(f"{path}: not UTF-8 text") from None
    except OSError as exc:
        raise HosidInputError(f"{path}: cannot read: {exc.strerror or exc}") from None
    return system_from_dict(data, str(path))
