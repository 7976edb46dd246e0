r"""Record -> state -> components -> calibrated quasi-likelihood and its mode.

:func:`estimate` turns a record into its calibrated quasi-likelihood and mode:

1. :class:`hosid.state.RecordState` (derivatives, blocks, scales) once;
2. a closed-form pilot (:mod:`hosid.inference.pilot`);
3. two rounds of efficient GMM (:mod:`hosid.inference.gmm`): the components are
   prepared at the current estimate (weights, velocity restoration), stacked,
   weighted with their influence covariance and solved; under a shaping filter solved
   once more with the covariance of the same equations on records simulated at the
   estimate (:func:`hosid.inference.simulated.refined`).

:func:`fit` adds the priors (eq-65 constraint by default), the calibration of
:mod:`hosid.inference.calibrate` and emcee (:mod:`hosid.inference.sampler`), and
returns an arviz ``DataTree`` (:mod:`hosid.output.results`).

The excitation is settled against the record, unless ``settle=False``; the estimate's
``notes`` say what was found and done:

- when the record's acceleration spectrum shows that the excitation stops below the
  Nyquist frequency (:mod:`hosid.spectra.response`), the model gets
  ``band_limited_excitation`` (the edge :math:`\omega_b` and a roll-off :math:`\beta` of
  the force within its band; :func:`excitation_for`);
- a shaping filter or impulses asked for (``narrowband_excitation``,
  ``impulsive_excitation``) are kept only when the record rejects the white Gaussian
  force they nest; otherwise the white model is estimated (:mod:`hosid.inference.settle`).

Component sets (``cost``; the restoring identities are the paper's moment method, J4
gives equations along the damping and :math:`S_0` only):

=========  =====================================================  ======================
``cost``   components                                             what it is
=========  =====================================================  ======================
``None``   identities (all drift terms) + J2 + level + kurtosis   the default: efficient
``"J2"``   identities (restoring terms) + J2                      paper's second order
``"J4A"``  identities (restoring terms) + J2 + J4A                paper's protocol, eq 59
``"J4B"``  identities (restoring terms) + J2 + J4B                eq 62-63
=========  =====================================================  ======================
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from ..components.base import Component, restoration
from ..components.cumulant import ForceKurtosis
from ..components.identities import Identities
from ..components.level import Level
from ..components.one_element import one_element
from ..components.spectral import J2, default_band
from ..components.tail import TAIL_PARAMS, Tail
from ..errors import HosidInputError
from ..model.excitation import Spectrum
from ..model.measured import MeasuredExcitation
from ..model.model import Model
from ..model.priors import PriorSet
from ..model.system import System
from ..progress import Stages
from ..record import Record
from ..screen import check_record, reject_failures
from ..state import RecordState
from ..verdicts import Check
from .correction import DEFAULT_SIMULATIONS
from .gmm import QuasiLikelihood, hansen
from .maps import likelihood_map
from .search import kept, search
from .settle import settled_note, settled_term, white_limit
from .simulated import refined
from .solutions import alternatives, bounds, capped, typical_scale

__all__ = [
    "COSTS",
    "Estimate",
    "components_for",
    "estimate",
    "excitation_for",
    "likelihood_map",
    "log_params",
    "prepare_state",
]

COSTS = ("J2", "J4A", "J4B")


def components_for(
    cost: str | None = None,
    *,
    band: tuple[float, float] | None = None,
    form: str = "scaled",
    domain: str = "principal",
) -> list[Component]:
    """The component set of ``cost`` (module table).

    Raises
    ------
    HosidInputError
        For an unknown cost or form.
    """
    if form not in ("scaled", "printed"):
        raise HosidInputError(f"unknown form {form!r}: 'scaled' or 'printed'")
    if cost is None:
        return [Identities(), J2(band=band, form=form, with_level=True), Level(), ForceKurtosis()]
    if cost not in COSTS:
        raise HosidInputError(f"unknown cost {cost!r}: choose from {', '.join(COSTS)}")
    comps: list[Component] = [Identities("restoring"), J2(band=band, form=form)]
    if cost in ("J4A", "J4B"):
        from ..components.polyspectral import J4

        comps.append(J4(kind=cost[-1], form=form, domain=domain))
    return comps


def prepare_state(
    record: Record,
    model: Model,
    *,
    block_seconds: float | None = None,
    window: str = "hann",
) -> RecordState:
    """The record's state for ``model``: the displacement keeps its offset when the
    model has an asymmetric term (``b2`` or ``m``), which the offset informs, and is
    Wiener-filtered when the model has measurement noise; its derivatives run to the
    jerk when the force goes through a shaping filter (the identities of
    :mod:`hosid.components.jets`).
    """
    centred = not (model.has("b2") or model.has("m"))
    return RecordState.from_record(
        record,
        block_seconds=block_seconds,
        window=window,
        centred=centred,
        denoise=model.has("noise_sd"),
        smooth=Spectrum(model).whitening,
    )


def excitation_for(
    state: RecordState, model: Model, *, band_limit: bool = True
) -> tuple[Model, list[str]]:
    """The model with the excitation terms the record's spectrum calls for (module
    docstring), and the sentences that say what was found and done.
    """
    notes = [state.spectrum.summary()]
    if state.repeat_note():
        notes.append(state.repeat_note())
    whitening = Spectrum(model).whitening
    for t in model.terms:
        if isinstance(t, MeasuredExcitation):
            lo, hi = default_band(state)
            omega = state.layout.bins(lo, hi, k_min=2) * state.layout.d_omega
            t.check_band(float(omega[0]), float(omega[-1]))
            _, wf, zf = t.rational
            notes.append(
                f"the measured excitation shape enters the identities through its "
                f"second-order form (wf {wf:.4g} rad/s, zf {zf:.3g}), {100 * t.misfit(omega):.0f} "
                "% rms from the table on the record's band"
            )
    if whitening and state.spectrum.band_limited:
        notes.append(
            "the acceleration spectrum falls off above the shaping filter's band: no "
            "band-limited excitation added (the filter's shape is the model's)"
        )
    if band_limit and state.spectrum.band_limited and not model.has("wb") and not whitening:
        model = model.with_term("band_limited_excitation")
        notes.append(
            "the excitation stops below the Nyquist frequency: band_limited_excitation added "
            "to the model (its edge wb and its roll-off within the band)"
        )
    return model, notes


@dataclass
class Estimate:
    """The mode of a quasi-likelihood and what it was built from (a system's: its
    :class:`~hosid.chain_state.ChainState`, and ``sigma_v`` one an element).
    """

    model: Model | System
    state: RecordState
    theta: np.ndarray
    ql: QuasiLikelihood
    cov: np.ndarray
    sigma_v: float  # velocity sd with the restoration (eq 65)
    test: dict
    pilot: np.ndarray
    checks: list[Check] = field(default_factory=list)  # hosid.screen
    notes: list[str] = field(default_factory=list)
    #: other solutions of the equations from other starts that the best one's
    #: quasi-likelihood does not rule out (a filter and its oscillator swapped): the
    #: sampler starts walkers there too
    alternatives: list[np.ndarray] = field(default_factory=list)
    #: the test of the white force nested in a shaping filter asked for
    #: (:func:`hosid.inference.settle.white_limit`), or ``None``
    excitation_test: dict | None = None

    @property
    def values(self) -> dict[str, float]:
        """The estimate by name."""
        return self.model.params(self.theta)

    @property
    def sd(self) -> dict[str, float]:
        """Standard deviations from the calibrated curvature."""
        return dict(zip(self.model.param_names, np.sqrt(np.diag(self.cov)).tolist(), strict=True))

    def scales(self):
        """The state's scales with the restored velocity sd (a system's: its elements')."""
        if isinstance(self.model, System):
            from ..components.chain_features import system_scales

            return system_scales(self.state, self.model, np.atleast_1d(self.sigma_v))
        return dataclasses.replace(self.state.scales, sigma_v=self.sigma_v)


def log_params(model: Model, priors: PriorSet | None = None) -> list[int]:
    """Parameters handled in their logarithm (``Prior.log_scaled``; ``S0`` and ``wc``)."""
    names = model.param_names
    if priors is not None:
        return [i for i, n in enumerate(names) if priors[n].log_scaled]
    return [i for i, n in enumerate(names) if n in ("S0", "wc", "wf", "zf")]


def estimate(
    record: Record | RecordState,
    model: Model | System | str = "paper",
    components: Sequence[Component] | None = None,
    *,
    start: np.ndarray | None = None,
    rounds: int = 2,
    block_seconds: float | None = None,
    settle: bool = True,
    force: bool = False,
    unit: str = "m",
    checks: Sequence[Check] | None = None,
    simulations: int = DEFAULT_SIMULATIONS,
    progress: bool | Stages = False,
    support: PriorSet | None = None,
) -> Estimate:
    """The calibrated quasi-likelihood of ``record`` and its mode (module docstring),
    searched within the default priors' supports; with ``settle`` the excitation is
    settled against the record (module docstring: a band's edge added, a shaping filter
    the record does not show dropped).

    A :class:`~hosid.record.Record` is checked first (:func:`hosid.screen.check_record`);
    ``force`` estimates a record that fails a check anyway, ``unit`` names the
    displacement's unit in the checks' messages, ``checks`` passes the record's checks
    when the caller already made them; an acceleration record is the one-element chain's.
    With ``impulsive_excitation`` and fewer than one impulse a sample, the estimate is
    corrected for its sampling bias by ``simulations`` records of the model a step
    (:mod:`hosid.inference.correction`; 0: not; their seed is fixed by the record's
    samples), with a progress bar when ``progress``; with ``narrowband_excitation`` the
    same number of records simulated at the estimate weigh its equations
    (:func:`hosid.inference.simulated.refined`).  ``support``: priors whose supports
    bound the search instead of the default priors' (used when it names the model's
    parameters, as the priors a fit is given do).

    Raises
    ------
    RecordRejected
        If the record fails a check (a constant, white noise, tones, a random walk, a
        clipped or too short record ...) and ``force`` is false.
    HosidInputError
        If the record is too short, constant, or not described by the model.
    """
    if isinstance(model, System) or getattr(record, "measured", ()) == ("acceleration",):
        from .system_estimate import routed  # a system's own state, pilot and components

        kw = {"block_seconds": block_seconds, "force": force, "unit": unit, "checks": checks,
              "support": support}  # fmt: skip
        return routed(record, model, components, start=start, rounds=rounds, **kw)
    model = Model.from_spec(model)
    state, checks = _checked_state(record, model, checks, force, unit, block_seconds)
    settle = settle and start is None
    model, notes = excitation_for(state, model, band_limit=settle)
    asked = components
    components, chain = _components(state, model, components)
    logs = log_params(model)
    lower, upper = bounds(
        model, support, lambda: model.default_priors(state.scales, constrained=False)
    )
    found, df = search(state, model, components, start, rounds, (logs, lower, upper), chain)
    theta, ql, theta0 = (
        kept(state, model, components, found, df, rounds, (logs, lower, upper))
        if start is None
        else found[0]
    )
    test = None
    if settle and settled_term(model):
        test = white_limit(model, ql, theta, log_params=logs,
                           scale=typical_scale(model, state, theta))  # fmt: skip
        if test["p_value"] >= test["level"]:  # the white force it nests: estimated instead
            est = estimate(
                record, model.without_term(test["effect"]), asked, block_seconds=block_seconds,
                settle=False, force=force, unit=unit, checks=checks, simulations=simulations,
                progress=progress,
            )  # fmt: skip
            est.notes.append(settled_note(test, kept=False))
            est.excitation_test = test
            return est
        notes.append(settled_note(test, kept=True))
    solutions = [t for t, _, _ in found]
    if simulations:
        theta, ql, done = refined(
            state, model, components, theta, ql, simulations, (logs, lower, upper), progress
        )
        notes += done
        if model.has("rate") and done:  # the other solutions are of the unshifted equations
            solutions = [theta]
    est = _at_mode(state, model, theta, ql, solutions, upper - lower)
    est.pilot, est.checks, est.notes, est.excitation_test = theta0, checks, notes, test
    return est


def _checked_state(record, model: Model, checks, force: bool, unit: str, block_seconds):
    """The record's state and checks (:func:`hosid.screen.check_record`, unless given;
    a failure rejects the record unless ``force``); a state is taken as it is.
    """
    checks = list(checks or [])
    if isinstance(record, RecordState):
        return record, checks
    checks = checks or check_record(record, unit=unit)
    reject_failures(checks, force=force)
    return prepare_state(record, model, block_seconds=block_seconds), checks


def _at_mode(state, model: Model, theta, ql, solutions, width) -> Estimate:
    """The estimate at the mode ``theta`` of ``ql``: its Laplace covariance capped by the
    search's ``width``, the velocity sd with the restoration, Hansen's test, and the
    other ``solutions`` the quasi-likelihood does not rule out.
    """
    J_best = float(-2.0 * ql(theta))
    cov = capped(ql.laplace(theta, typical_scale(model, state, theta)), width)
    s2, _ = restoration(state, model, theta)
    sigma_v = math.sqrt(state.scales.sigma_v**2 + s2)
    others = alternatives(ql, theta, solutions, cov, J_best)
    return Estimate(
        model, state, theta, ql, cov, sigma_v, hansen(ql, theta), theta, alternatives=others
    )


def _components(state, model: Model, components) -> tuple[list[Component], bool]:
    """The equations the estimate solves: ``components`` (default: :func:`components_for`)
    with the tail's where the model has a corner or a noise floor, the force's kurtosis
    where it has a shaping filter (its oscillator may swap with it) or impulses (their
    rate shows there), written as the one-element chain's where they are the default
    ones (:func:`hosid.components.one_element.one_element`); and whether they are.
    """
    components = list(components or components_for())
    if any(model.has(p) for p in TAIL_PARAMS) and not any(isinstance(c, Tail) for c in components):
        components.append(Tail())
    if (model.has("wf") or model.has("rate")) and not any(
        isinstance(c, ForceKurtosis) for c in components
    ):
        components.append(ForceKurtosis())
    chain = one_element(state, model, components)
    return (chain or components), bool(chain)
