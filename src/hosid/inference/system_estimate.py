r"""Record -> state -> a system's components -> the calibrated quasi-likelihood and its mode.

The same steps as a single oscillator's estimate (:mod:`hosid.inference.estimate`), for a
:class:`hosid.model.system.System`:

1. the record's channels are selected in the system's dof order (what the system file
   declares they measure is checked against the record's file) and checked
   (:func:`hosid.screen.check_record`); their state is prepared once
   (:class:`hosid.chain_state.ChainState`: acceleration channels integrated in their band);
2. a closed-form pilot (:mod:`hosid.inference.chain_pilot`);
3. the same rounds of efficient GMM (:func:`hosid.inference.solutions.solve_rounds`,
   :mod:`hosid.inference.gmm`) on the system's components, prepared at the current
   estimate, within the default priors' supports; the same Laplace covariance, cap and
   Hansen test.

The default components (``cost=None``) generalize the single oscillator's default one by
one: the generator identities of every element's terms
(:class:`~hosid.components.chain_identities.ChainIdentities`), J2's in-band level of every
driven dof and the inferred forces' cross-spectra
(:class:`~hosid.components.chain_spectral.ChainJ2`), each driven dof's level above the
band (:class:`~hosid.components.chain_spectral.ChainLevel`) and its force's fourth
cumulant (:class:`~hosid.components.chain_cumulant.ChainKurtosis`).  For the one-element
chain they give the single oscillator's equations to the last digit, and the estimate is
the single oscillator's default estimate (``tests/test_system_fit.py``).

**Sensor noise.**  A linear system whose channels are accelerations with their own white
noise (``sensor_noise = true``, or not given and the ``sensor_noise`` check warning:
:func:`with_sensor_noise`) has the channels' spectral matrix as its one component
(:class:`~hosid.components.chain_spectral_matrix.ChainSpectralMatrix`, Whittle's score):
the identities, moments of the twice-integrated channels, are biased by the noise, and for
a linear Gaussian system the spectral matrix holds all the information.  Its pilot is
Whittle's maximum (:func:`~hosid.inference.spectral_pilot.spectral_pilot`); under a
shaped force its dampers' coefficients at least 0
(:func:`~hosid.inference.spectral_pilot.damping_floor`).

**Blocks.**  A system of several dofs has many equations for its blocks: :math:`k = 28`
for the three-dof chain of ``analyses/chain_study.py``, whose 2000 s records the single
oscillator's rule (16 periods of the slowest resonance) cut into 48 blocks.  The
weight's noise then costs the feasible efficient estimator a variance factor
:math:`(\nu-1)/(\nu-q-1)` (:mod:`hosid.inference.gmm`; :math:`\nu = B - 1`, :math:`q`
over-identifying equations), 1.39 there, and the quasi-posterior a margin over it.  A
system's blocks are therefore shortened (by halves, never below 4 periods) until there
are :data:`BLOCKS_PER_EQUATION` times its equations (:func:`equation_count`).  On 30
records of that chain (Laplace intervals of the estimate, seeds apart from the study's)
48, 97 and 195 blocks gave efficiency 0.69, 0.77 and 0.80 over the element coefficients
and 90 % coverage 0.94, 0.88 and 0.91; on 30 of the two-dof chain's acceleration records
92 and 184 blocks gave 0.50 and 0.56, coverage 0.84 and 0.85.  The single oscillator
(7 equations) keeps its layout.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence

import numpy as np

from ..chain_state import ChainState
from ..components.chain_cumulant import ChainKurtosis
from ..components.chain_features import noise_shares, restoration, system_scales
from ..components.chain_identities import ChainIdentities, rows
from ..components.chain_spectral import ChainJ2, ChainLevel
from ..components.chain_spectral_matrix import ChainSpectralMatrix, check_noise_model
from ..errors import HosidInputError
from ..model.system import System
from ..record import Record
from ..screen import check_record, reject_failures
from ..verdicts import Check
from .chain_pilot import chain_pilot
from .estimate import Estimate
from .gmm import hansen
from .solutions import alternatives, bounds, capped, solve_rounds, typical_scale
from .spectral_pilot import damping_floor, settled_shape, spectral_pilot

__all__ = [
    "BLOCKS_PER_EQUATION",
    "centred",
    "equation_count",
    "estimate_system",
    "routed",
    "system_components",
]

#: A system's record is cut into at least this many blocks per estimating equation where
#: the blocks can be shortened (module docstring).
BLOCKS_PER_EQUATION = 6


def system_components(cost: str | None = None, system: System | None = None) -> list:
    """The components of a system's fit (module docstring); for a system with sensor
    noise, the channels' spectral matrix alone
    (:mod:`hosid.components.chain_spectral_matrix`).

    Raises
    ------
    HosidInputError
        For a cost other than the default (the paper's J2/J4 sets are the single
        oscillator's).
    """
    if cost is not None:
        raise HosidInputError(
            f"a system is fitted with the default components; cost {cost!r} is the single "
            "oscillator's (give --model with term names for it)"
        )
    if system is not None and (system.sensor_noise or system.excitation):
        return [ChainSpectralMatrix()]
    return [ChainIdentities(), ChainJ2(), ChainLevel(), ChainKurtosis()]


def routed(record, model, components, **settings) -> Estimate:
    """:func:`hosid.inference.estimate.estimate` of a system, or of a single oscillator's
    acceleration record (its one-element chain, the channel named ``x``); the single
    oscillator's default components stand for the system's.
    """
    if not isinstance(model, System):
        record = Record(record.x, record.dt, record.name, record.segments, ("x",), record.measured)
        model = System.single(model)
    from .estimate import components_for

    default = components is None or list(components) == components_for()
    return estimate_system(record, model, None if default else components, **settings)


def equation_count(system: System) -> int:
    """The default components' equations for ``system`` (module docstring): an identity
    per row (:func:`hosid.components.chain_identities.rows`), and per driven dof its
    in-band level, its level above the band and its fourth cumulant, and two
    cross-spectral equations per pair of driven dofs.
    """
    nd = len(system.driven)
    return len(rows(system)) + 3 * nd + nd * (nd - 1)


def system_state(record: Record, system: System, *, block_seconds=None) -> ChainState:
    """The state of ``record``'s channels named by the system's dofs (module docstring);
    the displacements keep their offsets when an element has an asymmetric term; a system
    of several dofs gets :data:`BLOCKS_PER_EQUATION` blocks per equation where it can.
    """
    record = record.select(system.dofs, measured=system.declared)
    target = BLOCKS_PER_EQUATION * equation_count(system) if system.n > 1 else None
    return ChainState.from_record(
        record, block_seconds=block_seconds, centred=centred(system), target_blocks=target
    )


def centred(system: System) -> bool:
    """Whether the system's state is centred: no element has an asymmetric term."""
    return not any(t.params[0] in ("b2", "m") for _, t in system.columns)


#: An element's relative motion with at least this share of sensor noise gets a warning.
NOISE_SHARE = 0.05


def noise_check(state: ChainState, system: System) -> list[Check]:
    """``sensor_noise``: ``warn`` when an element's relative displacement or velocity is
    at least :data:`NOISE_SHARE` its acceleration channels' noise
    (:func:`hosid.components.chain_features.noise_shares`); none without acceleration
    channels.  The identities are moments of the integrated channels, and noise in an
    element's relative motion biases its coefficients towards zero (errors in
    variables): on a five-storey twin of the building in ``analyses/building.py`` with
    the building's sensor floors, shares of 2-33 % took the storeys' stiffnesses from
    136 to 48-1.6.
    """
    if all(c.band is None for c in state.channels):
        return []
    share = noise_shares(state, system)
    e, k = np.unravel_index(int(np.argmax(share)), share.shape)
    worst, what = float(share[e, k]), ("displacement", "velocity")[k]
    where = f"element {system.elements[e].label}'s relative {what}"
    if system.sensor_noise:
        return [Check("sensor_noise", "pass", worst, f"modelled (N per channel): the floors "
                      f"make at least {100 * worst:.2g} % of {where} variance")]  # fmt: skip
    if worst < NOISE_SHARE:
        return [Check("sensor_noise", "pass", worst, f"the acceleration channels' floors make "
                      f"at most {100 * worst:.2g} % of {where} variance")]  # fmt: skip
    many = int(np.sum(share.max(axis=1) >= NOISE_SHARE))
    return [Check("sensor_noise", "warn", worst, f"the acceleration channels' floors make at "
                  f"least {100 * worst:.2g} % of {where} variance (sensor noise; {many} of "
                  f"{share.shape[0]} elements at 5 % or more; a linear system can model it: "
                  "sensor_noise = true): its coefficients are biased "
                  "towards zero")]  # fmt: skip


def with_sensor_noise(state: ChainState, system: System, checks: list) -> tuple[System, list]:
    """``system`` with every channel's sensor noise modelled (``sensor_noise = true``) when
    its file leaves that to the record (not given), the ``sensor_noise`` check warns or the
    forces have a shape (whose one component is the spectral matrix), and the channels'
    spectral matrix holds for it (a linear system of accelerations:
    :func:`hosid.components.chain_spectral_matrix.check_noise_model`); else as given.
    """
    warned = any(c.name == "sensor_noise" and c.status == "warn" for c in checks)
    if system.sensor_noise is not None or not (warned or system.excitation):
        return system, checks
    noisy = dataclasses.replace(system, sensor_noise=True)
    try:
        check_noise_model(noisy, state)
    except HosidInputError:
        return system, checks
    return noisy, [c for c in checks if c.name != "sensor_noise"] + noise_check(state, noisy)


def estimate_system(
    record: Record | ChainState,
    system: System,
    components: Sequence | None = None,
    *,
    start: np.ndarray | None = None,
    rounds: int = 2,
    block_seconds: float | None = None,
    force: bool = False,
    unit: str = "m",
    checks: Sequence | None = None,
    support=None,
    floor: bool | None = None,
) -> Estimate:
    """The calibrated quasi-likelihood of ``record`` under ``system`` and its mode
    (module docstring); the arguments are :func:`hosid.inference.estimate.estimate`'s.
    ``floor``: whether the spectral matrix's search keeps every damper's coefficient at
    least 0 (:func:`~hosid.inference.spectral_pilot.damping_floor`; default: under a
    shaped force only).

    Raises
    ------
    RecordRejected
        If the record fails a check and ``force`` is false.
    HosidInputError
        If a channel is missing, the record is too short, or the equations have no
        solution.
    """
    checks = list(checks or [])
    if isinstance(record, ChainState):
        state = record
    else:
        picked = record.select(system.dofs, measured=system.declared)
        checks = checks or check_record(picked, unit=unit)
        reject_failures(checks, force=force)
        state = system_state(record, system, block_seconds=block_seconds)
    if state.n > 1 and not any(c.name == "sensor_noise" for c in checks):
        checks = [*checks, *noise_check(state, system)]
    if components is None:
        system, checks = with_sensor_noise(state, system, checks)

    def bounds_of(s):
        return bounds(s, support, lambda: s.default_priors(system_scales(state, s),
                                                           constrained=False))  # fmt: skip

    theta0, settled = None, []
    if system.excitation is None:  # the file leaves the forces' shape to the record
        system = dataclasses.replace(system, excitation=())
        if components is None and system.sensor_noise and start is None:
            try:
                check_noise_model(system, state)
            except HosidInputError:
                pass
            else:
                system, theta0, note = settled_shape(state, system, _identities_pilot(
                    state, system), bounds_of)  # fmt: skip
                settled = [note]
    components = list(components or system_components(system=system))
    lower, upper = bounds_of(system)
    if (bool(system.excitation) if floor is None else floor) and any(
        isinstance(c, ChainSpectralMatrix) for c in components
    ):
        lower = damping_floor(system, lower)
    if start is not None:
        theta0 = np.array(start, dtype=float)
    elif theta0 is not None:  # the shape's settlement searched it
        pass
    elif system.sensor_noise or system.excitation:  # from the identities' pilot if any
        theta0 = spectral_pilot(state, system, _identities_pilot(state, system), lower, upper)
    else:
        theta0 = chain_pilot(state, system)
    logs = system.log_params
    theta, ql = solve_rounds(state, system, components, theta0, rounds, logs, lower, upper)
    J_best = float(-2.0 * ql(theta))
    cov = capped(ql.laplace(theta, typical_scale(system, state, theta)), upper - lower)
    sigma_v = restoration(state, system, theta).velocity_sd
    sigma_v = float(sigma_v[0]) if system.single_names else sigma_v
    others = alternatives(ql, theta, [theta], cov, J_best)
    notes = (
        [
            (f"channel {c.name}: " if state.n > 1 else "") + c.spectrum.summary()
            for c in state.channels
        ]
        + state.band_notes()
        + settled
    )
    if not np.all(np.isfinite(theta)):
        raise HosidInputError("the estimating equations have no finite solution")
    return Estimate(system, state, theta, ql, cov, sigma_v, hansen(ql, theta), theta0, checks,
                    notes, others, None)  # fmt: skip


def _identities_pilot(state: ChainState, system: System) -> np.ndarray | None:
    """The identities' closed-form pilot (:func:`~hosid.inference.chain_pilot.chain_pilot`),
    or ``None`` where they have none (a start of the spectral matrix's search).
    """
    try:
        return chain_pilot(state, system)
    except HosidInputError:
        return None
