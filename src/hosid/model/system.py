r"""A system: degrees of freedom joined by elements of drift terms, and their forces.

The displacements :math:`q_1, \dots, q_n` (one record column each) obey

.. math::

    m_d\,\ddot q_d + \sum_e B_{ed}\,f_e(r_e, \dot r_e) = F_d(t), \qquad
    r_e = q_{j_e} - q_{i_e}, \qquad
    f_e = \sum_k \theta_{ek}\,\phi_k(r_e \text{ or } \dot r_e),

with element :math:`e` between its ends :math:`i_e` and :math:`j_e` (the ground,
:math:`q = 0`, is always the first end :math:`i_e`), its force :math:`f_e` made of
terms of the single oscillator's library (:mod:`hosid.model.terms`: ``a1`` :math:`\dot
r`, ``n1`` :math:`\dot r|\dot r|`, ``a2`` :math:`r`, ``n2`` :math:`r^3`, ``b2``
:math:`r^2`, ``mu`` :math:`\mathrm{sign}\,\dot r`, ``m`` :math:`-1`), and the incidence
:math:`B_{ed} = +1` if :math:`d = j_e`, :math:`-1` if :math:`d = i_e`, else 0.  So an
element's force acts with opposite signs on its two ends (Newton's third law): a spring
:math:`a_2` between :math:`x_1` and :math:`x_2` adds :math:`a_2(q_2 - q_1)` to the
equation of :math:`x_2` and :math:`a_2(q_1 - q_2)` to that of :math:`x_1`, restoring on
both.  An element from the ground has :math:`r = q_j`, and the one-element chain is the
single oscillator :math:`\ddot x + a_1\dot x + n_1\dot x|\dot x| + a_2x + n_2x^3 = F`.
The odd features do not care which end is first; the even ones (``b2``, ``m``) change
sign with the order of ``between``.

In matrix form, with :math:`M = \mathrm{diag}(m)` and the coefficients :math:`\theta`,

.. math:: M\ddot q + \Phi(q, \dot q)\,\theta = F, \qquad
    \Phi_{d,(e,k)} = B_{ed}\,\phi_k(r_e \text{ or } \dot r_e),

linear in :math:`\theta` (:meth:`System.features`).  The forces are independent Gaussian
noises on the driven degrees of freedom, zero on the others, of spectra
:math:`S_{0,d}L(\omega)\delta_{dd'}`: white (:math:`L = 1`, :math:`E[F_d(t)F_{d'}(t + s)]
= 2\pi S_{0,d}\delta_{dd'}\delta(s)`) or a shape :math:`L` they share
(:attr:`System.excitation`, :mod:`hosid.model.excitation`: a shaker's or a sea's force).
:math:`m_1 = 1` (the scale: masses, coefficients and :math:`\sqrt{S_0}` scaled together
give the same motion) unless the file gives it, and the other masses are parameters
unless the file fixes them.

Parameter layout (:attr:`System.param_names`, the one place): every element's
coefficients (elements in order, terms in the library's order), then the unknown
masses, then the levels of the driven degrees of freedom and the shape's parameters
(``wf``, ``zf``), then those of the channels' sensor noises (white, two-sided,
:math:`N_d`, added to what channel :math:`d` measures), each named with its place:
``a1[ground-x1]``, ``n2[x1-x2]``, ``mass[x2]``, ``S0[x1]``, ``N[x1]``.
:meth:`System.single` names the one-element chain's parameters as
:class:`hosid.model.Model` does (``a1``, ``n1``, ``a2``, ``n2``, ``S0``).  Files:
:mod:`hosid.model.system_file`; parameters by name: :mod:`hosid.model.system_params`; the
linear chain's matrices and modes: :mod:`hosid.model.linear_chain`.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from ..errors import HosidInputError
from .model import Model
from .system_file import (
    GROUND,
    MEASURED_KINDS,
    check_dofs,
    check_driven,
    check_element,
    check_excitation,
    check_masses,
    check_measured,
    check_sensor_noise,
    check_topology,
    check_values,
    read_system,
)
from .system_params import ParameterLayout
from .terms import DriftTerm

__all__ = ["GROUND", "MEASURED_KINDS", "Element", "System"]


@dataclass(frozen=True)
class Element:
    """Drift ``terms`` between two degrees of freedom, or the ground and one (``between``:
    the ground first; else in the given order, ``r = q[between[1]] - q[between[0]]``).
    """

    between: tuple[str, str]
    terms: tuple[DriftTerm, ...]

    @property
    def label(self) -> str:
        """``"ground-x1"``, ``"x1-x2"``: the bracket of its parameter names."""
        return "-".join(self.between)


@dataclass(frozen=True)
class System(ParameterLayout):
    """Degrees of freedom, elements, masses, the driven degrees of freedom, what each
    channel measures, and parameter values (module docstring for the equation).

    Parameters
    ----------
    dofs : sequence of str
        Names of the degrees of freedom (the record's columns).
    elements : sequence of Element or (between, terms)
        ``between`` two dof names or ``"ground"`` and one; ``terms`` drift term names
        (or terms) of :data:`hosid.model.terms.TERMS`, or ``"paper"``, ``"linear"``.
    masses : mapping, optional
        Known masses by dof; the first dof's is 1 unless given, the others are
        parameters ``mass[dof]`` unless given.
    driven : sequence of str, optional
        The dofs with a white force (default all).
    measured : str or mapping, optional
        ``"displacement"`` or ``"acceleration"``, for all channels or by dof; stored as
        one kind or ``None`` (undeclared: the record's file says) a dof.
    sensor_noise : bool or sequence of str, optional
        The dofs whose channels carry a white noise of unknown level ``N[dof]``; not given
        (``None``), a fit models it where a linear system's accelerations need it.
    excitation : str or sequence, optional
        The forces' shared spectral shape: ``"white"`` or a term of
        :data:`hosid.model.system_file.SHAPES`; not given (``None``), white unless a
        linear system's record rejects it
        (:func:`hosid.inference.spectral_pilot.settled_shape`).
    values : mapping, optional
        Parameter values by name (a simulation's truth); stored as ``(name, value)``
        pairs in :attr:`param_names` order (``dict(system.values)``).
    single_names : bool
        Name the one-element chain's parameters without brackets, as
        :class:`hosid.model.Model` does (:meth:`single` sets it).

    Raises
    ------
    HosidInputError
        On any inconsistency (one line naming it).

    Examples
    --------
    >>> s = System(("x1", "x2"), [(("ground", "x1"), ("linear_damping", "linear_stiffness")),
    ...                           (("x1", "x2"), ("linear_damping", "cubic_stiffness"))])
    >>> s.param_names  # doctest: +NORMALIZE_WHITESPACE
    ('a1[ground-x1]', 'a2[ground-x1]', 'a1[x1-x2]', 'n2[x1-x2]', 'mass[x2]', 'S0[x1]',
     'S0[x2]')
    """

    dofs: tuple[str, ...]
    elements: tuple[Element, ...]
    masses: Mapping[str, float] | tuple = ()
    driven: tuple[str, ...] = ()
    measured: str | Mapping[str, str] | tuple = ()
    sensor_noise: bool | tuple | None = None
    excitation: str | tuple | None = None
    values: Mapping[str, float] | tuple = ()
    single_names: bool = False

    def __post_init__(self) -> None:
        dofs = check_dofs(self.dofs)
        if isinstance(self.elements, str | Element) or not len(self.elements):
            raise HosidInputError("a system needs at least one element")
        items = [(e.between, e.terms) if isinstance(e, Element) else e for e in self.elements]
        elements = tuple(Element(*check_element(e, dofs, k)) for k, e in enumerate(items))
        check_topology(dofs, [(e.between, e.terms) for e in elements])
        known = check_masses(self.masses, dofs)
        driven = check_driven(self.driven, dofs)
        measured = check_measured(self.measured, dofs)
        set_ = object.__setattr__
        set_(self, "dofs", dofs)
        set_(self, "elements", elements)
        set_(self, "masses", known)
        set_(self, "driven", driven)
        set_(self, "measured", measured)
        set_(self, "sensor_noise", check_sensor_noise(self.sensor_noise, dofs))
        set_(self, "excitation", check_excitation(self.excitation))
        if self.single_names and (len(dofs) != 1 or len(elements) != 1):
            raise HosidInputError("plain parameter names are for the one-element chain only")
        set_(self, "values", check_values(dict(self.values), self.param_names))

    # ---------------------------------------------------------------- builders
    @classmethod
    def single(cls, model: Model | str, values=()) -> System:
        """The one-element chain of the single oscillator ``model`` (dof ``x``, white
        force, the Model's parameter names; ``values`` optional, as for the Model).

        Raises
        ------
        HosidInputError
            If the model has excitation or observation terms beyond the white level.
        """
        model = Model.from_spec(model)
        other = [t.name for t in model.terms if not isinstance(t, DriftTerm)]
        other = [n for n in other if n != "excitation_level"]
        if other:
            raise HosidInputError(
                f"a System has a white force and no observation terms yet: {', '.join(other)}"
            )
        element = Element((GROUND, "x"), model.drift_terms)
        return cls(("x",), (element,), values=values, single_names=True)

    @classmethod
    def from_toml(cls, path) -> System:
        """Read a system file (:func:`hosid.model.system_file.read_system`)."""
        return read_system(path)

    # --------------------------------------------------------------- structure
    @property
    def declared(self) -> dict[str, str]:
        """What the declared channels measure, by dof (for
        :meth:`hosid.record.Record.select`, which checks them against the record's file).
        """
        return {d: k for d, k in zip(self.dofs, self.measured, strict=True) if k is not None}

    @property
    def n(self) -> int:
        """Number of degrees of freedom."""
        return len(self.dofs)

    @cached_property
    def columns(self) -> tuple[tuple[int, DriftTerm], ...]:
        """(element index, term) of every drift coefficient, in :attr:`param_names` order."""
        return tuple((k, t) for k, e in enumerate(self.elements) for t in e.terms)

    @property
    def names(self) -> tuple[str, ...]:
        """The terms as a model names them: ``"x1-x2: linear_damping + linear_stiffness"``
        an element (the one-element chain's: its term names and ``excitation_level``).
        """
        if self.single_names:
            return (*(t.name for t in self.elements[0].terms), "excitation_level")
        return tuple(f"{e.label}: {' + '.join(t.name for t in e.terms)}" for e in self.elements)

    @property
    def n_drift(self) -> int:
        """Number of drift coefficients (``theta[:n_drift]``)."""
        return len(self.columns)

    @cached_property
    def param_names(self) -> tuple[str, ...]:
        """Parameter names in order: the layout of ``theta`` (module docstring)."""
        if self.single_names:
            return (*(t.params[0] for _, t in self.columns), "S0")
        drift = [f"{t.params[0]}[{self.elements[k].label}]" for k, t in self.columns]
        masses = [f"mass[{d}]" for d, m in zip(self.dofs, self.masses, strict=True) if m is None]
        noise = (f"N[{d}]" for d in self.sensor_noise or ())
        shape = (p for t in self.excitation or () for p in t.params)
        return (*drift, *masses, *(f"S0[{d}]" for d in self.driven), *shape, *noise)

    def default_priors(self, scales, *, constrained: bool = True):
        """Every parameter's default prior from the record's
        :class:`~hosid.model.system_priors.SystemScales`; with ``constrained`` eq (65)
        per damped element (:mod:`hosid.model.system_priors`).
        """
        from .system_priors import system_priors

        return system_priors(self, scales, constrained=constrained)

    def describe(self) -> dict:
        """The system as plain data (a fit's ``system`` attribute)."""
        elements = [{"between": list(e.between), "terms": [t.name for t in e.terms]}
                    for e in self.elements]  # fmt: skip
        masses = dict(zip(self.dofs, self.masses, strict=True))
        return {"dofs": list(self.dofs), "elements": elements, "masses": masses,
                "driven": list(self.driven), "measured": self.declared,
                "sensor_noise": None if self.sensor_noise is None
                else list(self.sensor_noise),
                "excitation": None if self.excitation is None
                else [t.name for t in self.excitation] or "white"}  # fmt: skip

    @property
    def incidence(self) -> np.ndarray:
        """:math:`B`, ``(n_elements, n)``: +1 at an element's second end, -1 at its first."""
        B = np.zeros((len(self.elements), self.n))
        for k, e in enumerate(self.elements):
            B[k, self.dofs.index(e.between[1])] = 1.0
            if e.between[0] != GROUND:
                B[k, self.dofs.index(e.between[0])] = -1.0
        return B

    # --------------------------------------------------------------- equations
    def _state(self, q, qdot) -> tuple[np.ndarray, np.ndarray]:
        q, qdot = np.asarray(q, dtype=float), np.asarray(qdot, dtype=float)
        if q.shape[-1:] != (self.n,) or qdot.shape[-1:] != (self.n,):
            raise HosidInputError(f"q and qdot need a last axis of {self.n} (the dofs)")
        B = self.incidence
        return q @ B.T, qdot @ B.T

    def element_features(self, q, qdot) -> np.ndarray:
        r""":math:`\phi_k(r_e)` or :math:`\phi_k(\dot r_e)` of every coefficient,
        ``(..., n_drift)``, for states ``q``, ``qdot`` of shape ``(..., n)``.
        """
        r, rdot = self._state(q, qdot)
        cols = [t.phi(rdot[..., k] if t.variable == "v" else r[..., k]) for k, t in self.columns]
        return np.stack(cols, axis=-1)

    def features(self, q, qdot) -> np.ndarray:
        r""":math:`\Phi(q, \dot q)`, ``(..., n, n_drift)``, with
        :math:`M\ddot q + \Phi\theta_{\mathrm{drift}} = F` (module docstring).
        """
        B = self.incidence
        S = np.stack([B[k] for k, _ in self.columns], axis=-1)  # (n, n_drift)
        return self.element_features(q, qdot)[..., None, :] * S

    def drift_force(self, q, qdot, theta) -> np.ndarray:
        r"""The elements' forces on each dof, :math:`B^{\mathsf T}f = \Phi\theta_{\mathrm{drift}}`,
        ``(..., n)``; ``theta`` is a full parameter vector ``(p,)`` (or ``(..., p)``
        broadcasting with the states) or a mapping.
        """
        th = self.vector(theta)[..., : self.n_drift]
        return np.einsum("...dp,...p->...d", self.features(q, qdot), th)

    def acceleration(self, q, qdot, theta, force=None) -> np.ndarray:
        r""":math:`\ddot q = M^{-1}(F - \Phi\theta)` (``force`` :math:`F` default 0: the
        drift acceleration), ``(..., n)``.
        """
        f = -self.drift_force(q, qdot, theta)
        if force is not None:
            f = f + np.asarray(force, dtype=float)
        return f / self.mass_vector(theta)

    def inferred_force(self, q, qdot, qddot, theta) -> np.ndarray:
        r"""The force vector a response implies, :math:`F = M\ddot q + \Phi\theta` (eq 45
        per dof), ``(..., n)``.
        """
        return self.mass_vector(theta) * np.asarray(qddot, dtype=float) + self.drift_force(
            q, qdot, theta
        )

    def __repr__(self) -> str:
        body = "; ".join(
            f"{e.label}: {' + '.join(t.name for t in e.terms)}" for e in self.elements
        )
        return f"System({', '.join(self.dofs)}; {body})"
