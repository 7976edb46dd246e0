r"""Model terms: the equation of motion assembled from named effects.

The general model is

.. math::

    \ddot x + \sum_{k\,\in\,\mathrm{drift}} \theta_k\,\phi_k(x, \dot x) = g(t) + m,
    \qquad y_n = x(n\Delta t) + \epsilon_n,

where every *drift* term contributes one coefficient :math:`\theta_k` times a force
feature :math:`\phi_k(x, \dot x)`, the force :math:`g` is white noise of two-sided
level :math:`S_0` (:math:`R_g(\tau) = 2\pi S_0\,\delta(\tau)`, paper eqs 42-43) or,
with ``coloured_excitation``, white noise through the first-order low-pass
:math:`\dot g = \omega_c(w - g)`, :math:`m` is a constant mean force
(``excitation_mean``) and :math:`\epsilon_n \sim N(0, \sigma_\epsilon^2)` is white
measurement noise (``measurement_noise``).  Given the drift, the force inferred from
a record is

.. math:: f = \ddot x + \sum_k \theta_k\,\phi_k(x, \dot x),

which is what the paper's costs require to be white and Gaussian (eq 45 for the
paper's four drift terms).

Each term is a small frozen dataclass (one class per named effect, its formula in
the docstring) that knows its parameter names, default priors built from the
scales of a record (:class:`RecordScales`), how its parameters enter
:func:`hosid.simulate.simulate`, and, for drift terms, its feature
:math:`\phi_k`.  A :class:`Model` is an ordered tuple of terms; adding an effect is
:meth:`Model.with_term`.  The names of the candidate effects are those of
``NOTES.md``: see :data:`CANDIDATES`.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from .errors import HosidInputError
from .priors import LogUniform, Prior, Uniform
from .records import Record
from .simulate import simulate as _simulate
from .spectra import block_periodogram, derivatives

__all__ = [
    "ALIASES",
    "BASE_TERMS",
    "CANDIDATES",
    "TERMS",
    "ColouredExcitation",
    "CoulombFriction",
    "CubicStiffness",
    "ExcitationLevel",
    "ExcitationMean",
    "LinearDamping",
    "LinearStiffness",
    "MeasurementNoise",
    "Model",
    "QuadraticDamping",
    "QuadraticStiffness",
    "RecordScales",
    "Term",
    "drift_from_params",
    "get_term",
]

#: A force as a function of displacement and velocity, ``(x, v) -> array``.
FeatureFn = Callable[[np.ndarray, np.ndarray], np.ndarray]


# ---------------------------------------------------------------------- scales
@dataclass(frozen=True)
class RecordScales:
    r"""Scales of a record that the default priors are built from.

    Attributes
    ----------
    sigma_x, sigma_v : float
        Standard deviations of the displacement and of its spectral-derivative
        velocity.
    S0 : float
        A rough estimate of the two-sided excitation level (see :meth:`from_record`).
    dt : float
        Sampling interval (s); :math:`\omega_N = \pi/\Delta t` bounds ``wc``.
    """

    sigma_x: float
    sigma_v: float
    S0: float
    dt: float

    def __post_init__(self) -> None:
        for key in ("sigma_x", "sigma_v", "S0", "dt"):
            value = float(getattr(self, key))
            if not (math.isfinite(value) and value > 0):
                raise HosidInputError(
                    f"record scale {key} must be finite and positive, got {value!r}"
                )
            object.__setattr__(self, key, value)

    @property
    def omega_n(self) -> float:
        r"""Equivalent natural frequency :math:`\omega_n = \sigma_{\dot x}/\sigma_x` (rad/s);
        exact for a linear oscillator and the linear-equivalent value otherwise.
        """
        return self.sigma_v / self.sigma_x

    @property
    def omega_nyquist(self) -> float:
        r""":math:`\pi/\Delta t` (rad/s)."""
        return math.pi / self.dt

    @classmethod
    def from_record(cls, record: Record, *, block_seconds: float = 20.48) -> RecordScales:
        r"""Measure the scales of ``record``.

        The excitation level is read off the plateau of the acceleration spectrum
        above the resonance: for :math:`\omega \gg \omega_n` the response
        acceleration follows the force, :math:`S_{\ddot x}(\omega) \to S_0`
        (for a linear oscillator :math:`S_{\ddot x}/S_0 = \omega^4/((\omega_n^2 -
        \omega^2)^2 + a_{1}^2\omega^2)`, within 10 % of 1 beyond :math:`3\omega_n` at
        the paper's damping).  The median over :math:`[3\omega_n, 5\omega_n]`
        (clipped to half the Nyquist frequency) of the Hann-windowed block
        periodogram is used; it is an order-of-magnitude scale for priors, not an
        estimator (it is low under coloured excitation).
        """
        x = record.x - record.x.mean()
        v, a = derivatives(x, record.dt)
        sigma_x, sigma_v = float(np.std(x)), float(np.std(v))
        if not (sigma_x > 0 and sigma_v > 0):
            raise HosidInputError("record is constant: its scales are zero")
        M = max(16, min(round(block_seconds / record.dt), record.n))
        P = block_periodogram(a, M, record.dt).mean(axis=0)
        omega = 2.0 * np.pi * np.fft.rfftfreq(M, record.dt)
        wn, wnyq = sigma_v / sigma_x, math.pi / record.dt
        lo, hi = min(3.0 * wn, 0.25 * wnyq), min(5.0 * wn, 0.5 * wnyq)
        band = (omega >= lo) & (omega <= hi)
        if not band.any():
            band = omega > 0
        S0 = float(np.median(P[band]))
        return cls(sigma_x=sigma_x, sigma_v=sigma_v, S0=S0, dt=record.dt)


# ----------------------------------------------------------------------- terms
@dataclass(frozen=True)
class Term:
    r"""One named effect of the equation of motion (base class).

    Attributes
    ----------
    name : str
        The term's name, e.g. ``"quadratic_damping"``.
    params : tuple of str
        Its parameter names (as in :func:`hosid.simulate.simulate`).
    kind : str
        ``"drift"`` (a force :math:`\theta\,\phi(x, \dot x)` on the left-hand side;
        one parameter), ``"excitation"`` (changes the force model) or
        ``"observation"`` (changes what is measured).
    latex : str
        The term's contribution in LaTeX.
    """

    name: ClassVar[str]
    params: ClassVar[tuple[str, ...]]
    kind: ClassVar[str]
    latex: ClassVar[str]

    def feature(self, x: np.ndarray, v: np.ndarray) -> np.ndarray:
        r"""The force feature :math:`\phi(x, \dot x)` of a drift term."""
        raise TypeError(f"{self.name} is an {self.kind} term: it has no drift feature")

    def default_priors(self, scales: RecordScales) -> dict[str, Prior]:  # pragma: no cover
        """Weakly informative priors for the term's parameters, from record scales."""
        raise NotImplementedError

    def simulator_params(self, values: Mapping[str, float]) -> dict[str, float]:
        """The term's entries of the :func:`hosid.simulate.simulate` parameter dict."""
        return {p: float(values[p]) for p in self.params}

    def __repr__(self) -> str:
        return f"<Term {self.name}: {', '.join(self.params)}>"


@dataclass(frozen=True, repr=False)
class LinearDamping(Term):
    r"""Linear (viscous) damping, paper eq (40).

    .. math:: a_1\,\dot x, \qquad a_1 \sim U(-4\omega_n, 4\omega_n)

    Negative values stay admissible so that the twin mode of J2/J4 can be seen;
    the eq-65 constraint lives in :mod:`hosid.priors`.
    """

    name: ClassVar[str] = "linear_damping"
    params: ClassVar[tuple[str, ...]] = ("a1",)
    kind: ClassVar[str] = "drift"
    latex: ClassVar[str] = r"a_1\,\dot x"

    def feature(self, x: np.ndarray, v: np.ndarray) -> np.ndarray:
        r""":math:`\phi = \dot x`."""
        return np.asarray(v, dtype=float)

    def default_priors(self, scales: RecordScales) -> dict[str, Prior]:
        """``a1 ~ U(-4 w_n, 4 w_n)``."""
        w = scales.omega_n
        return {"a1": Uniform(-4.0 * w, 4.0 * w)}


@dataclass(frozen=True, repr=False)
class QuadraticDamping(Term):
    r"""Quadratic (velocity-squared) damping, paper eq (40).

    .. math:: n_1\,\dot x|\dot x|, \qquad
        |n_1| \le \frac{4\omega_n}{\sigma_{\dot x}} \ \text{(uniform)}

    (:math:`n_1\sigma_{\dot x}` is a damping rate, compare eq 65).
    """

    name: ClassVar[str] = "quadratic_damping"
    params: ClassVar[tuple[str, ...]] = ("n1",)
    kind: ClassVar[str] = "drift"
    latex: ClassVar[str] = r"n_1\,\dot x|\dot x|"

    def feature(self, x: np.ndarray, v: np.ndarray) -> np.ndarray:
        r""":math:`\phi = \dot x|\dot x|`."""
        v = np.asarray(v, dtype=float)
        return v * np.abs(v)

    def default_priors(self, scales: RecordScales) -> dict[str, Prior]:
        """``n1 ~ U(-4 w_n / sigma_v, 4 w_n / sigma_v)``."""
        s = 4.0 * scales.omega_n / scales.sigma_v
        return {"n1": Uniform(-s, s)}


@dataclass(frozen=True, repr=False)
class LinearStiffness(Term):
    r"""Linear stiffness, paper eq (40).

    .. math:: a_2\,x, \qquad a_2 \sim U(-2\omega_n^2, 4\omega_n^2)

    (negative :math:`a_2` with a hardening :math:`n_2` is a double well).
    """

    name: ClassVar[str] = "linear_stiffness"
    params: ClassVar[tuple[str, ...]] = ("a2",)
    kind: ClassVar[str] = "drift"
    latex: ClassVar[str] = r"a_2\,x"

    def feature(self, x: np.ndarray, v: np.ndarray) -> np.ndarray:
        r""":math:`\phi = x`."""
        return np.asarray(x, dtype=float)

    def default_priors(self, scales: RecordScales) -> dict[str, Prior]:
        """``a2 ~ U(-2 w_n^2, 4 w_n^2)``."""
        w2 = scales.omega_n**2
        return {"a2": Uniform(-2.0 * w2, 4.0 * w2)}


@dataclass(frozen=True, repr=False)
class CubicStiffness(Term):
    r"""Cubic (Duffing) stiffness, paper eq (40).

    .. math:: n_2\,x^3, \qquad
        n_2 \sim U\!\left(-\frac{\omega_n^2}{\sigma_x^2}, \frac{4\omega_n^2}{\sigma_x^2}\right)

    (:math:`n_2\sigma_x^2` is a stiffness; softening beyond :math:`-\omega_n^2/\sigma_x^2`
    lets a record escape its well).
    """

    name: ClassVar[str] = "cubic_stiffness"
    params: ClassVar[tuple[str, ...]] = ("n2",)
    kind: ClassVar[str] = "drift"
    latex: ClassVar[str] = r"n_2\,x^3"

    def feature(self, x: np.ndarray, v: np.ndarray) -> np.ndarray:
        r""":math:`\phi = x^3`."""
        x = np.asarray(x, dtype=float)
        return x**3

    def default_priors(self, scales: RecordScales) -> dict[str, Prior]:
        """``n2 ~ U(-w_n^2 / sigma_x^2, 4 w_n^2 / sigma_x^2)``."""
        s = scales.omega_n**2 / scales.sigma_x**2
        return {"n2": Uniform(-s, 4.0 * s)}


@dataclass(frozen=True, repr=False)
class QuadraticStiffness(Term):
    r"""Quadratic (asymmetric) stiffness; needs odd-order statistics (paper section 6).

    .. math:: b_2\,x^2, \qquad
        b_2 \sim U\!\left(-\frac{2\omega_n^2}{\sigma_x}, \frac{2\omega_n^2}{\sigma_x}\right)

    It skews the response and shifts its mean, :math:`E[x] \approx -b_2 E[x^2]/a_2`.
    """

    name: ClassVar[str] = "quadratic_stiffness"
    params: ClassVar[tuple[str, ...]] = ("b2",)
    kind: ClassVar[str] = "drift"
    latex: ClassVar[str] = r"b_2\,x^2"

    def feature(self, x: np.ndarray, v: np.ndarray) -> np.ndarray:
        r""":math:`\phi = x^2`."""
        x = np.asarray(x, dtype=float)
        return x**2

    def default_priors(self, scales: RecordScales) -> dict[str, Prior]:
        """``b2 ~ U(-2 w_n^2 / sigma_x, 2 w_n^2 / sigma_x)``."""
        s = 2.0 * scales.omega_n**2 / scales.sigma_x
        return {"b2": Uniform(-s, s)}


@dataclass(frozen=True, repr=False)
class CoulombFriction(Term):
    r"""Coulomb (dry) friction.

    .. math:: \mu\,\mathrm{sign}(\dot x), \qquad \mu \sim U(0, 2\omega_n\sigma_{\dot x})

    Friction dissipates, so :math:`\mu \ge 0`; :math:`\mu/\sigma_{\dot x}` is a damping
    rate.
    """

    name: ClassVar[str] = "coulomb_friction"
    params: ClassVar[tuple[str, ...]] = ("mu",)
    kind: ClassVar[str] = "drift"
    latex: ClassVar[str] = r"\mu\,\mathrm{sign}(\dot x)"

    def feature(self, x: np.ndarray, v: np.ndarray) -> np.ndarray:
        r""":math:`\phi = \mathrm{sign}(\dot x)`."""
        return np.sign(np.asarray(v, dtype=float))

    def default_priors(self, scales: RecordScales) -> dict[str, Prior]:
        """``mu ~ U(0, 2 w_n sigma_v)``."""
        return {"mu": Uniform(0.0, 2.0 * scales.omega_n * scales.sigma_v)}


@dataclass(frozen=True, repr=False)
class ExcitationLevel(Term):
    r"""White-noise excitation of two-sided level :math:`S_0` (paper eqs 42-43); always
    part of a model.

    .. math:: R_g(\tau) = 2\pi S_0\,\delta(\tau), \qquad
        S_0 \sim \log U(\hat S_0/100, 100\,\hat S_0)

    with :math:`\hat S_0` from :meth:`RecordScales.from_record`.
    """

    name: ClassVar[str] = "excitation_level"
    params: ClassVar[tuple[str, ...]] = ("S0",)
    kind: ClassVar[str] = "excitation"
    latex: ClassVar[str] = r"2\pi S_0\,\delta(\tau)"

    def default_priors(self, scales: RecordScales) -> dict[str, Prior]:
        """``S0 ~ logU(S0_hat / 100, 100 S0_hat)``."""
        return {"S0": LogUniform(scales.S0 / 100.0, 100.0 * scales.S0)}


@dataclass(frozen=True, repr=False)
class ColouredExcitation(Term):
    r"""Coloured excitation: the white force through a first-order low-pass.

    .. math:: \dot g = \omega_c (w - g), \qquad
        S_g(\omega) = \frac{S_0\,\omega_c^2}{\omega_c^2 + \omega^2}, \qquad
        \omega_c \sim \log U(\omega_n/10, \omega_N)

    (:math:`\omega_N = \pi/\Delta t`; :math:`\omega_c \to \infty` is white noise).
    """

    name: ClassVar[str] = "coloured_excitation"
    params: ClassVar[tuple[str, ...]] = ("wc",)
    kind: ClassVar[str] = "excitation"
    latex: ClassVar[str] = r"\frac{S_0\,\omega_c^2}{\omega_c^2 + \omega^2}"

    @staticmethod
    def shape(omega, wc: float) -> np.ndarray:
        r"""The spectral shape :math:`L(\omega) = \omega_c^2/(\omega_c^2 + \omega^2)`."""
        omega = np.asarray(omega, dtype=float)
        return wc**2 / (wc**2 + omega**2)

    def default_priors(self, scales: RecordScales) -> dict[str, Prior]:
        """``wc ~ logU(w_n / 10, pi / dt)``."""
        return {"wc": LogUniform(scales.omega_n / 10.0, scales.omega_nyquist)}


@dataclass(frozen=True, repr=False)
class ExcitationMean(Term):
    r"""A constant mean force added to the excitation.

    .. math:: g(t) + m, \qquad m \sim U(-4\omega_n^2\sigma_x, 4\omega_n^2\sigma_x)

    (for a linear oscillator it shifts the mean response by :math:`m/a_2`).
    """

    name: ClassVar[str] = "excitation_mean"
    params: ClassVar[tuple[str, ...]] = ("m",)
    kind: ClassVar[str] = "excitation"
    latex: ClassVar[str] = r"m"

    def default_priors(self, scales: RecordScales) -> dict[str, Prior]:
        """``m ~ U(-4 w_n^2 sigma_x, 4 w_n^2 sigma_x)``."""
        s = 4.0 * scales.omega_n**2 * scales.sigma_x
        return {"m": Uniform(-s, s)}


@dataclass(frozen=True, repr=False)
class MeasurementNoise(Term):
    r"""White measurement noise on the sampled displacement.

    .. math:: y_n = x(n\Delta t) + \epsilon_n, \qquad
        \epsilon_n \sim N(0, \sigma_\epsilon^2), \qquad \sigma_\epsilon \sim U(0, \sigma_x)

    Its spectrum is the floor :math:`\sigma_\epsilon^2\Delta t/2\pi` (two-sided), which
    dominates the response's :math:`S_0/\omega^4` tail at high frequencies.
    """

    name: ClassVar[str] = "measurement_noise"
    params: ClassVar[tuple[str, ...]] = ("noise_sd",)
    kind: ClassVar[str] = "observation"
    latex: ClassVar[str] = r"\epsilon_n \sim N(0, \sigma_\epsilon^2)"

    def default_priors(self, scales: RecordScales) -> dict[str, Prior]:
        """``noise_sd ~ U(0, sigma_x)``."""
        return {"noise_sd": Uniform(0.0, scales.sigma_x)}


#: Every term by name, in the canonical order of a model's parameters (drift terms
#: first, as in eq 45, so that the paper model's parameters are ``a1, n1, a2, n2, S0``).
TERMS: dict[str, Term] = {
    t.name: t
    for t in (
        LinearDamping(),
        QuadraticDamping(),
        LinearStiffness(),
        CubicStiffness(),
        QuadraticStiffness(),
        CoulombFriction(),
        ExcitationLevel(),
        ColouredExcitation(),
        ExcitationMean(),
        MeasurementNoise(),
    )
}

#: The candidate effects of the discrepancy workflow (NOTES.md), spelled exactly so.
CANDIDATES: tuple[str, ...] = (
    "quadratic_damping",
    "cubic_stiffness",
    "quadratic_stiffness",
    "coulomb_friction",
    "coloured_excitation",
    "excitation_mean",
    "measurement_noise",
)

#: Terms every model holds besides its named effects.
BASE_TERMS: tuple[str, ...] = ("linear_damping", "linear_stiffness", "excitation_level")

#: Model names accepted by :meth:`Model.from_spec`.
ALIASES: dict[str, tuple[str, ...]] = {
    "linear": ("linear_damping", "linear_stiffness"),
    "paper": ("linear_damping", "quadratic_damping", "linear_stiffness", "cubic_stiffness"),
}

_ORDER = {name: i for i, name in enumerate(TERMS)}
_DRIFT_BY_PARAM = {t.params[0]: t for t in TERMS.values() if t.kind == "drift"}


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


def drift_from_params(params: Mapping[str, float]) -> FeatureFn:
    r"""The drift force :math:`\sum_k \theta_k\phi_k(x, \dot x)` of a simulator
    parameter dict.

    Keys of drift terms (``a1, n1, a2, n2, b2, mu``) are used; excitation and
    observation keys (``S0, wc, m, noise_sd``) are ignored; other keys raise.
    """
    unknown = set(params) - {p for t in TERMS.values() for p in t.params}
    if unknown:
        raise HosidInputError(
            f"unknown parameter(s) {', '.join(sorted(unknown))}; valid: "
            f"{', '.join(p for t in TERMS.values() for p in t.params)}"
        )
    parts = [(float(params[p]), t) for p, t in _DRIFT_BY_PARAM.items() if p in params]

    def drift(x: np.ndarray, v: np.ndarray) -> np.ndarray:
        x = np.asarray(x, dtype=float)
        out = np.zeros(np.broadcast_shapes(x.shape, np.shape(v)))
        for coef, term in parts:
            if coef != 0.0:
                out = out + coef * term.feature(x, v)
        return out

    return drift


# ----------------------------------------------------------------------- model
@dataclass(frozen=True)
class Model:
    r"""An equation of motion: an ordered tuple of terms.

    The terms are kept in the canonical order of :data:`TERMS` and
    ``excitation_level`` (:math:`S_0`) is always included, so that a model's
    parameter vector ``theta`` has a fixed layout: the drift coefficients first
    (``a1, n1, a2, n2`` for the paper model, as in eq 45), then ``S0``, then the
    excitation and observation parameters.

    Parameters
    ----------
    terms : iterable of Term or str
        The terms (names are looked up in :data:`TERMS`); duplicates are dropped.

    Examples
    --------
    >>> Model.from_spec("paper").param_names
    ('a1', 'n1', 'a2', 'n2', 'S0')
    >>> Model.from_spec("linear").with_term("excitation_mean").param_names
    ('a1', 'a2', 'S0', 'm')
    """

    terms: tuple[Term, ...]

    def __post_init__(self) -> None:
        found = {}
        for t in (*self.terms, TERMS["excitation_level"]):
            term = get_term(t) if isinstance(t, str) else t
            if not isinstance(term, Term):
                raise HosidInputError(f"not a model term: {t!r}")
            found.setdefault(term.name, term)
        ordered = tuple(sorted(found.values(), key=lambda t: _ORDER.get(t.name, len(_ORDER))))
        object.__setattr__(self, "terms", ordered)

    # ------------------------------------------------------------ construction
    @classmethod
    def from_spec(cls, spec: str | Iterable[str]) -> Model:
        """Build a model from ``"linear"``, ``"paper"``, or a list or comma-separated
        string of term names (which may include ``linear`` and ``paper``).

        ``linear`` is ``linear_damping + linear_stiffness``; ``paper`` adds
        ``quadratic_damping + cubic_stiffness``.

        Raises
        ------
        HosidInputError
            On an unknown name (the one-line message lists the valid names) or an
            empty spec.
        """
        items = spec.split(",") if isinstance(spec, str) else list(spec)
        names: list[str] = []
        for item in items:
            if not isinstance(item, str):
                raise HosidInputError(f"model terms must be names, got {item!r}")
            key = item.strip()
            if not key:
                continue
            if key in ALIASES:
                names.extend(ALIASES[key])
            elif key in TERMS:
                names.append(key)
            else:
                raise HosidInputError(f"unknown model term {key!r}; valid names: {_valid_names()}")
        if not names:
            raise HosidInputError(f"empty model spec {spec!r}; valid names: {_valid_names()}")
        return cls(tuple(TERMS[n] for n in names))

    def with_term(self, name: str) -> Model:
        """A copy of the model with the term ``name`` added.

        Raises
        ------
        HosidInputError
            If ``name`` is unknown or already in the model.
        """
        term = get_term(name)
        if term.name in self.names:
            raise HosidInputError(f"model already has {term.name}: {', '.join(self.names)}")
        return Model((*self.terms, term))

    # ------------------------------------------------------------- properties
    @property
    def names(self) -> tuple[str, ...]:
        """Term names in order."""
        return tuple(t.name for t in self.terms)

    @property
    def param_names(self) -> tuple[str, ...]:
        """Parameter names in order (the layout of ``theta``)."""
        return tuple(p for t in self.terms for p in t.params)

    @property
    def drift_terms(self) -> tuple[Term, ...]:
        """The drift terms, in order."""
        return tuple(t for t in self.terms if t.kind == "drift")

    @property
    def drift_params(self) -> tuple[str, ...]:
        """Coefficients of the drift terms, in the order of :meth:`features` rows 1..."""
        return tuple(t.params[0] for t in self.drift_terms)

    @property
    def candidates(self) -> tuple[str, ...]:
        """Candidate effects not yet in the model."""
        return tuple(c for c in CANDIDATES if c not in self.names)

    def latex(self) -> str:
        r"""The equation of motion in LaTeX (drift = force + mean; observation)."""
        lhs = r"\ddot x + " + " + ".join(t.latex for t in self.drift_terms)
        rhs = "g(t) + m" if "excitation_mean" in self.names else "g(t)"
        return f"{lhs} = {rhs}"

    # ------------------------------------------------------------- parameters
    def params(
        self, theta: Mapping[str, float] | Sequence[float] | np.ndarray
    ) -> dict[str, float]:
        """``theta`` (a mapping or a vector in :attr:`param_names` order) as a dict.

        Raises
        ------
        HosidInputError
            If a parameter is missing, unknown, or the vector has the wrong length.
        """
        names = self.param_names
        if isinstance(theta, Mapping):
            missing = [n for n in names if n not in theta]
            extra = [k for k in theta if k not in names]
            if missing or extra:
                raise HosidInputError(
                    f"parameters do not match the model ({', '.join(names)}): "
                    f"missing {missing or 'none'}, unknown {extra or 'none'}"
                )
            return {n: float(theta[n]) for n in names}
        values = np.asarray(theta, dtype=float)
        if values.shape != (len(names),):
            raise HosidInputError(
                f"theta has shape {values.shape}; expected ({len(names)},) for {', '.join(names)}"
            )
        return dict(zip(names, values.tolist(), strict=True))

    def default_priors(self, scales: RecordScales | Record) -> dict[str, Prior]:
        """Default priors of every parameter, in :attr:`param_names` order."""
        if isinstance(scales, Record):
            scales = RecordScales.from_record(scales)
        out: dict[str, Prior] = {}
        for t in self.terms:
            out.update(t.default_priors(scales))
        return out

    def simulator_params(self, theta) -> dict[str, float]:
        """The :func:`hosid.simulate.simulate` parameter dict of ``theta``."""
        values = self.params(theta)
        out: dict[str, float] = {}
        for t in self.terms:
            out.update(t.simulator_params(values))
        return out

    # ---------------------------------------------------------------- actions
    def simulate(
        self,
        theta,
        *,
        duration: float,
        dt: float,
        rng: np.random.Generator,
        **kwargs,
    ) -> Record:
        """Simulate a record of this model (:func:`hosid.simulate.simulate`).

        Extra keyword arguments (``substeps``, ``burn_in``, ``name``) are passed on.
        """
        return _simulate(self.simulator_params(theta), duration=duration, dt=dt, rng=rng, **kwargs)

    def features(self, record: Record, *, derivative: str = "spectral") -> np.ndarray:
        r"""Time-domain features, shape ``(1 + n_drift, n)``: row 0 is :math:`\ddot x`,
        row :math:`k` the feature :math:`\phi_k(x, \dot x)` of the k-th drift term.

        For the paper model these are eq (45)'s :math:`y_0 .. y_4` (as
        :func:`hosid.spectra.features`).  Velocity and acceleration are spectral
        derivatives of the whole record (:func:`hosid.spectra.derivatives`).
        """
        x = record.x
        v, a = derivatives(x, record.dt, derivative)
        return np.stack([a, *(t.feature(x, v) for t in self.drift_terms)])

    def drift(self, theta) -> FeatureFn:
        r"""The drift force :math:`(x, \dot x) \mapsto \sum_k \theta_k\phi_k(x, \dot x)`."""
        values = self.params(theta)
        return drift_from_params({p: values[p] for p in self.drift_params})

    def inferred_force(self, record: Record, theta, *, derivative: str = "spectral") -> np.ndarray:
        r"""The force inferred from the record, :math:`f = \ddot x + \sum_k \theta_k\phi_k`.

        ``theta`` may be a mapping, a vector, or an array of shape ``(..., p)``;
        the result has shape ``(..., n)``.  It includes the mean force :math:`m`.
        """
        F = self.features(record, derivative=derivative)
        idx = [self.param_names.index(p) for p in self.drift_params]
        if isinstance(theta, Mapping):
            theta = np.array(list(self.params(theta).values()))
        th = np.asarray(theta, dtype=float)
        if th.shape[-1:] != (len(self.param_names),):
            raise HosidInputError(
                f"theta has shape {th.shape}; expected (..., {len(self.param_names)})"
            )
        lam = np.concatenate([np.ones((*th.shape[:-1], 1)), th[..., idx]], axis=-1)
        return lam @ F

    def __repr__(self) -> str:
        return f"Model({' + '.join(self.names)})"
