r"""A system's default priors, from its record's scales, and eq (65) per element.

Each element's terms take the single oscillator's default priors
(:mod:`hosid.model.terms`) at the scales of the element's relative motion,
:math:`\sigma_{r_e}` and :math:`\sigma_{\dot r_e}` (:class:`SystemScales`), widened
:math:`n`-fold for a system of :math:`n` dofs: an element carries the inertia of the dofs
on one side of it, so its coefficients (per unit mass of the first dof) exceed what its
own relative motion shows (in a uniform five-storey shear chain the ground spring is 6.7
times :math:`\omega_{n,e}^2 = \sigma_{\dot r_e}^2/\sigma_{r_e}^2`, above the single
oscillator's :math:`4\omega_n^2`), and :data:`MASS_WIDENING` times more when a mass is
unknown: the coefficients are per unit mass of the first dof, and a heavy dof carries a
stiff element (on the building of ``analyses/building.py`` the top storey's damper sat at
the edge of the narrower range; the search starts within it,
:func:`hosid.inference.spectral_pilot.search_box`).  For the one-element chain they are
the single oscillator's priors.  An unknown mass is
log-normal about the first dof's (which is 1), with 95 % of it within a decade either side
(:data:`MASS_SPREAD`), truncated to :math:`[10^{-2}, 10^2]`: a structure's storeys or
bays weigh alike within a decade.  With a flat prior over the four decades the building of
``analyses/building.py`` put a near-massless fourth floor between two stiff storeys (its
maximum at :math:`10^{-2}`, the posterior's 5-95 % 0.012-0.32); with this one 0.15-0.96,
its natural frequencies within 0.5 % of the flat prior's, its first damping ratio 2.84 %
against 2.54 %.  A driven dof's
level :math:`S_{0,d}` log-uniform over four decades each side of its acceleration's
rough level times the square of its known mass (two decades, as the single oscillator's,
when the mass is known; a factor :math:`10^2` more each side when it is not, which the
mass's range needs).  The forces' shared shape (:attr:`~hosid.model.system.System.excitation`)
takes its term's priors at the scales of the element whose relative motion is slowest.  A
channel's sensor noise level :math:`N_d` is log-uniform from
:math:`10^{-8}` to :math:`10^2` times its acceleration's rough level (a noise may hide
all of a dof's motion, or hardly any).

A chain's elements' relative displacements are independent coordinates, so its potential
energy is bounded below, and its response can be stationary, only if every element's is:
an element whose only restoring term is a linear spring has a positive stiffness
(``stiffness[<element>]``, with ``constrained``).  Whittle's likelihood does not see it (a
pole and its mirror image across the imaginary axis give one :math:`|H|`): on the
building of ``analyses/building.py`` the top storey's stiffness wandered over -112 to 158
(5-95 %), where its fit did not converge.

Eq (65) holds per element: with the restored sd :math:`\sigma_{\dot r_e}` of its relative
velocity, :math:`a_{1eq,e} = a_{1,e} + n_{1,e}\sqrt{8/\pi}\,\sigma_{\dot r_e} + \mu_e
\sqrt{2/\pi}/\sigma_{\dot r_e} > 0` for every element with a damping term (one
constraint each, ``a1eq[ground-x1]``; ``a1eq`` for the one-element chain).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from .priors import LogNormal, LogUniform, PriorSet, Uniform
from .terms import Scales

if TYPE_CHECKING:  # pragma: no cover
    from .system import System

__all__ = ["MASS_RANGE", "NOISE_RANGE", "SystemScales", "equivalent_damping", "system_priors"]

#: The support of an unknown mass (the first dof's mass is 1).
MASS_RANGE = (1e-2, 1e2)
#: The log-sd of an unknown mass's prior about the first dof's mass (module docstring):
#: a decade either side holds 95 % of it.
MASS_SPREAD = math.log(10.0) / 1.96
#: How much wider an element's coefficients range when a mass is unknown (module
#: docstring).
MASS_WIDENING = 10.0
#: The support of a sensor noise level, in units of its channel's rough level.
NOISE_RANGE = (1e-8, 1e2)


@dataclass(frozen=True)
class SystemScales:
    """The scales of a system's record: one :class:`Scales` per element (its relative
    displacement and velocity sds, the ``S0`` of its second end's acceleration, ``dt``)
    and the rough acceleration level of every dof.
    """

    elements: tuple[Scales, ...]
    levels: tuple[float, ...]

    @property
    def sigma_v(self) -> np.ndarray:
        """The elements' relative velocity sds (restored where the state says so)."""
        return np.array([s.sigma_v for s in self.elements])


def equivalent_damping(system: System, theta, sigma_v: Sequence[float]) -> np.ndarray:
    r"""Eq (65) per element, ``(..., E)``: :math:`\sum_{c\in e}\theta_cc_c(\sigma_{\dot
    r_e})`, e.g. :math:`a_1 + n_1\sqrt{8/\pi}\sigma_{\dot r_e}` (0 for an element without
    damping); ``theta`` is ``(..., p)``.
    """
    th = np.asarray(theta, dtype=float)
    out = np.zeros((*th.shape[:-1], len(system.elements)))
    for c, (e, t) in enumerate(system.columns):
        f = t.damping_factor(float(sigma_v[e]))
        if f:
            out[..., e] = out[..., e] + f * th[..., c]
    return out


def damped(system: System) -> list[int]:
    """The elements with a damping term."""
    return sorted({e for e, t in system.columns if t.damping_factor(1.0)})


def constraint_name(system: System, e: int) -> str:
    """``a1eq[<element>]`` (``a1eq`` for the one-element chain)."""
    return "a1eq" if system.single_names else f"a1eq[{system.elements[e].label}]"


def system_priors(system: System, scales: SystemScales, *, constrained: bool = True) -> PriorSet:
    """Every parameter's default prior (module docstring); with ``constrained`` eq (65)
    per damped element and a positive stiffness per lone linear spring.
    """
    names = iter(system.param_names)
    priors = {}
    for e, t in system.columns:
        prior = t.default_priors(scales.elements[e])[t.params[0]]
        if system.n > 1 and isinstance(prior, Uniform):
            wide = system.n * (MASS_WIDENING if None in system.masses else 1.0)
            prior = Uniform(wide * prior.lower, wide * prior.upper)
        priors[next(names)] = prior
    masses = system.masses
    for m in masses:
        if m is None:
            priors[next(names)] = LogNormal(1.0, MASS_SPREAD, *MASS_RANGE)
    for d in system.driven:
        k = system.dofs.index(d)
        known = masses[k] is not None
        base = scales.levels[k] * (masses[k] ** 2 if known else 1.0)
        wide = 1e2 if known else 1e4
        priors[next(names)] = LogUniform(base / wide, wide * base)
    if system.excitation:  # at the scales of the element of the slowest relative motion
        slow = min(scales.elements, key=lambda sc: sc.omega_n)
        for t in system.excitation:
            shape = t.default_priors(slow)
            for p in t.params:
                priors[next(names)] = shape[p]
    for d in system.sensor_noise or ():
        level = scales.levels[system.dofs.index(d)]
        priors[next(names)] = LogUniform(NOISE_RANGE[0] * level, NOISE_RANGE[1] * level)
    constraints = {}
    if constrained:
        sv = scales.sigma_v
        for e in damped(system):
            constraints[constraint_name(system, e)] = lambda th, e=e: equivalent_damping(
                system, th, sv
            )[..., e]
        for e, col in linear_springs(system).items():
            constraints[f"stiffness[{system.elements[e].label}]"] = lambda th, c=col: th[..., c]
    return PriorSet(priors, constraints)


def linear_springs(system: System) -> dict[int, int]:
    """The elements whose only restoring term is a linear spring, and its column: its
    stiffness must be positive for a stationary response (module docstring).
    """
    restoring: dict[int, list[tuple[int, str]]] = {}
    for col, (e, t) in enumerate(system.columns):
        if not t.damping_factor(1.0) and t.name != "excitation_mean":
            restoring.setdefault(e, []).append((col, t.name))
    return {e: r[0][0] for e, r in restoring.items()
            if len(r) == 1 and r[0][1] == "linear_stiffness"}  # fmt: skip
