r"""A model: an ordered tuple of terms, and the one place parameter names and order live.

A model's parameter vector ``theta`` has a fixed layout: the drift coefficients first
(``a1, n1, a2, n2`` for the paper model, as in eq 45), then ``S0``, then the other
excitation and observation parameters (:data:`hosid.model.terms.TERMS` order).
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from ..errors import HosidInputError
from .excitation import Spectrum
from .priors import PriorSet
from .system_params import named
from .terms import CANDIDATES, TERMS, DriftTerm, Scales, Term

__all__ = ["ALIASES", "Model", "get_term"]

#: Model names accepted by :meth:`Model.from_spec`.
ALIASES: dict[str, tuple[str, ...]] = {
    "linear": ("linear_damping", "linear_stiffness"),
    "paper": ("linear_damping", "quadratic_damping", "linear_stiffness", "cubic_stiffness"),
}

_ORDER = {name: i for i, name in enumerate(TERMS)}


def _valid_names() -> str:
    return ", ".join((*ALIASES, *TERMS))


def get_term(name: str) -> Term:
    """The term called ``name``.

    Raises
    ------
    HosidInputError
        If there is no such term (the message lists the valid names).
    """
    try:
        return TERMS[name]
    except (KeyError, TypeError):
        raise HosidInputError(
            f"unknown model term {name!r}; valid terms: {', '.join(TERMS)}"
        ) from None


@dataclass(frozen=True)
class Model:
    """An equation of motion: terms in canonical order, ``excitation_level`` always in.

    Examples
    --------
    >>> Model.from_spec("paper").param_names
    ('a1', 'n1', 'a2', 'n2', 'S0')
    >>> Model.from_spec("linear").with_term("excitation_mean").param_names
    ('a1', 'a2', 'm', 'S0')
    """

    terms: tuple[Term, ...]

    def __post_init__(self) -> None:
        found: dict[str, Term] = {}
        for t in (*self.terms, TERMS["excitation_level"]):
            term = get_term(t) if isinstance(t, str) else t
            if not isinstance(term, Term):
                raise HosidInputError(f"not a model term: {t!r}")
            if getattr(term, "system_only", False):
                raise HosidInputError(
                    f"{term.name} is a system's force shape (a system file's excitation, "
                    "accelerations with sensor noise): a single oscillator's identities need "
                    "an all-pole shape such as narrowband_excitation"
                )
            found.setdefault(term.name, term)
        ordered = tuple(sorted(found.values(), key=lambda t: _ORDER.get(t.name, len(_ORDER))))
        object.__setattr__(self, "terms", ordered)
        if not any(t.variable == "x" for t in self.drift_terms):
            raise HosidInputError("the model needs a restoring term (e.g. linear_stiffness)")
        if not any(t.variable == "v" for t in self.drift_terms):
            raise HosidInputError("the model needs a damping term (e.g. linear_damping)")
        try:
            Spectrum(self)
        except ValueError as exc:
            raise HosidInputError(str(exc)) from None

    @classmethod
    def from_spec(cls, spec: str | Iterable[str | Term] | Model) -> Model:
        """A model from ``"linear"``, ``"paper"`` or term names (a list, or comma-separated;
        a list may hold terms built from data, e.g. :func:`hosid.model.measured.read_shape`).

        Raises
        ------
        HosidInputError
            On an unknown name or an empty spec (the message lists the valid names).
        """
        if isinstance(spec, Model):
            return spec
        items = spec.split(",") if isinstance(spec, str) else list(spec)
        names: list[str | Term] = []
        for item in items:
            if isinstance(item, Term):  # a term built from data (a measured shape)
                names.append(item)
                continue
            key = str(item).strip()
            if not key:
                continue
            if key in ALIASES:
                names.extend(ALIASES[key])
            elif key in TERMS:
                names.append(key)
            elif key == "measured_excitation":
                raise HosidInputError(
                    "measured_excitation is made from its table: give --excitation-shape "
                    "FILE.csv (library: hosid.model.measured.read_shape)"
                )
            else:
                raise HosidInputError(f"unknown model term {key!r}; valid names: {_valid_names()}")
        if not names:
            raise HosidInputError(f"empty model spec {spec!r}; valid names: {_valid_names()}")
        return cls(tuple(TERMS[n] if isinstance(n, str) else n for n in names))

    def with_term(self, name: str) -> Model:
        """A copy with the term ``name`` added.

        Raises
        ------
        HosidInputError
            If ``name`` is unknown or already in the model.
        """
        term = get_term(name)
        if term.name in self.names:
            raise HosidInputError(f"model already has {term.name}: {', '.join(self.names)}")
        return Model((*self.terms, term))

    def extended(self, effect: str) -> Model:
        """The model with the candidate ``effect`` (one of :attr:`candidates`): the term
        added, except that a shaping filter replaces a band-limited excitation.  The
        record's band edge (:mod:`hosid.spectra.response`) may be the end of a nonlinear
        response's harmonic under a narrow-band force (a hardening oscillator's third
        harmonic), and the filter's roll-off is its own.

        Raises
        ------
        HosidInputError
            If ``effect`` is not a candidate of the model.
        """
        name = get_term(effect).name
        if name not in self.candidates:
            raise HosidInputError(f"{name} is not a candidate of {', '.join(self.names)}")
        base = self
        if name == "narrowband_excitation" and self.has("band_limited_excitation"):
            base = self.without_term("band_limited_excitation")
        return base.with_term(name)

    def without_term(self, name: str) -> Model:
        """A copy without the term ``name``.

        Raises
        ------
        HosidInputError
            If the model has no term ``name``.
        """
        name = get_term(name).name
        if name not in self.names:
            raise HosidInputError(f"model has no {name}: {', '.join(self.names)}")
        return Model(tuple(t for t in self.terms if t.name != name))

    # ------------------------------------------------------------- structure
    @property
    def names(self) -> tuple[str, ...]:
        """Term names in order."""
        return tuple(t.name for t in self.terms)

    @property
    def param_names(self) -> tuple[str, ...]:
        """Parameter names in order: the layout of ``theta``."""
        return tuple(p for t in self.terms for p in t.params)

    @property
    def drift_terms(self) -> tuple[DriftTerm, ...]:
        """The drift terms, in order (their coefficients lead ``theta``)."""
        return tuple(t for t in self.terms if isinstance(t, DriftTerm))

    @property
    def n_drift(self) -> int:
        """Number of drift coefficients (``theta[:n_drift]``)."""
        return len(self.drift_terms)

    def index(self, name: str) -> int:
        """Position of parameter ``name`` in ``theta``."""
        return self.param_names.index(name)

    def has(self, name: str) -> bool:
        """Whether the model holds the term (or parameter) ``name``."""
        return name in self.names or name in self.param_names

    @property
    def candidates(self) -> tuple[str, ...]:
        """Candidate effects not yet in the model (a band-limited excitation's roll-off
        and a shaping filter already hold a coloured excitation's low-pass; a whitening
        filter is not combined with another shape, but replaces a band's edge:
        :meth:`extended`).
        """
        taken = set(self.names)
        if self.has("wb") or self.has("wf"):  # a band's roll-off, a filter: a low-pass
            taken.add("coloured_excitation")
        if self.has("wc"):  # one whitening shape alone (a filter replaces a band: extended)
            taken.add("narrowband_excitation")
        if self.has("measured_excitation"):  # the shape is known
            taken.update(("coloured_excitation", "narrowband_excitation"))
        if any(self.has(p) for p in ("wb", "wc", "wf", "measured_excitation")):  # impulses: white
            taken.add("impulsive_excitation")
        if self.has("rate"):
            taken.update(("coloured_excitation", "narrowband_excitation"))
        return tuple(c for c in CANDIDATES if c not in taken)

    def latex(self) -> str:
        r"""The equation of motion in LaTeX."""
        lhs = r"\ddot x + " + " + ".join(t.latex for t in self.drift_terms)
        return f"{lhs} = g(t)".replace("+ -", "- ")

    # ------------------------------------------------------------ parameters
    def params(self, theta: Mapping[str, float] | Sequence[float] | np.ndarray) -> dict:
        """``theta`` (a mapping or a vector in :attr:`param_names` order) as a dict.

        Raises
        ------
        HosidInputError
            If a parameter is missing or unknown, or the vector has the wrong length.
        """
        return named(self.param_names, theta, "model")

    def vector(self, values: Mapping[str, float]) -> np.ndarray:
        """A parameter dict as a vector in :attr:`param_names` order."""
        return np.array([self.params(values)[n] for n in self.param_names])

    def equivalent_damping(self, theta, sigma_v: float) -> np.ndarray:
        r"""Eq (65) for every damping term: :math:`\sum_k\theta_k c_k(\sigma_{\dot x})`,
        e.g. :math:`a_1 + n_1\sqrt{8/\pi}\sigma_{\dot x}`; ``theta`` is ``(..., p)``.
        """
        th = np.asarray(theta, dtype=float)
        out = np.zeros(th.shape[:-1])
        for i, t in enumerate(self.drift_terms):
            c = t.damping_factor(sigma_v)
            if c:
                out = out + c * th[..., i]
        return out

    def default_priors(self, scales: Scales, *, constrained: bool = True) -> PriorSet:
        """Every term's default prior; with ``constrained`` the eq-65 constraint."""
        priors = {}
        for t in self.terms:
            priors.update(t.default_priors(scales))
        constraints = {}
        if constrained:
            sv = scales.sigma_v
            constraints["a1eq"] = lambda th: self.equivalent_damping(th, sv)
        return PriorSet(priors, constraints)

    # --------------------------------------------------------------- actions
    def simulate(self, theta, *, duration: float, dt: float, rng: np.random.Generator, **kw):
        """Simulate a record of this model (:func:`hosid.model.simulate.simulate`); a
        measured excitation shape through its second-order form
        (:meth:`hosid.model.measured.MeasuredExcitation.simulated`).
        """
        from .simulate import simulate

        params = self.params(theta)
        for t in self.terms:
            params = t.simulated(params)
        return simulate(params, duration=duration, dt=dt, rng=rng, **kw)

    def __repr__(self) -> str:
        return f"Model({' + '.join(self.names)})"
