r"""Discrepancy measures between a record and posterior-predictive replicates.

Each measure is a statistic that some missing effect leaves its mark on.  All are
computed by :func:`measures` with one fixed layout (a :class:`MeasureSpec` taken
from the observed record), so that the record's vector lines up with those of
replicate records simulated from the fitted model:

- ``psd``: :math:`\log \bar S_x` in bands from the first bin to :math:`2\omega_n`
  (Hann blocks, mean removed); moved by the stiffness, the damping law and a
  coloured excitation.
- ``psd_tail``: the shape of the spectral tail, the steps
  :math:`\log \bar S_x(B_{j+1}) - \log \bar S_x(B_j)` between log-spaced bands from
  :math:`2.5\omega_n` to :math:`0.8\,\omega_N` (about :math:`-4\log r` for bands
  in the ratio :math:`r` and the :math:`S_0/\omega^4` tail of a white-noise-driven
  oscillator); measurement noise (a
  floor) and coloured excitation (a steeper fall).  Its level, set by :math:`S_0`
  and measured to a fraction of a percent, is left out: a point estimate of
  :math:`S_0` would dominate it.
- ``pdf_x``: quantiles of :math:`(x - \bar x)/s_x` (levels :data:`X_LEVELS`);
  cubic and quadratic stiffness.
- ``pdf_v``: quantiles of :math:`|\dot x|/s_{\dot x}` (levels :data:`V_LEVELS`); the
  damping law (quadratic damping thins the tails, Coulomb friction sharpens the
  centre), measurement noise.
- ``pdf_energy``: quantiles of :math:`\log(E/\bar E)` (levels :data:`ENERGY_LEVELS`);
  the damping law, friction, a stiffness the fit lacks.
- ``skewness``: skewness of :math:`x` and of :math:`\dot x`; quadratic stiffness, a
  mean force on a nonlinear spring.
- ``kurtosis``: excess kurtosis of :math:`x` and of :math:`\dot x`; cubic stiffness,
  the damping law, friction, measurement noise (on :math:`\dot x`).
- ``mean``: :math:`\bar x`; excitation mean, quadratic stiffness.
- ``bispectrum``: third-order moments of frequency bands (integrals of the bispectrum
  over regions, :func:`_bispectrum`); quadratic stiffness, mean force.
- ``force_psd`` (with a drift): the shape of :math:`\log \bar S_f` of the inferred
  force in log-spaced bands from :math:`0.25\omega_n` to :math:`4\omega_n` (mean over
  bands removed: whiteness, not level); coloured excitation, missing drift terms.
- ``force_moments`` (with a drift): skewness and excess kurtosis of the inferred force
  low-passed below :math:`3\omega_n` (Gaussianity); missing drift terms.

Here :math:`\omega_n = \sigma_{\dot x}/\sigma_x` is the record's equivalent natural
frequency, :math:`\omega_N = \pi/\Delta t`, and the velocity and acceleration are
spectral derivatives of the whole record (:func:`hosid.spectra.derivatives`).
The response energy is :math:`E = \dot x^2/2 + V(x) - \min V` with
:math:`V(x) = \int_0^x (k(s) - m)\,ds`, :math:`k(s)` the fitted restoring force
(the drift at :math:`\dot x = 0`) and :math:`m` the fitted mean force; with no drift
it is model-free, :math:`V = \hat\omega_n^2 (x - \bar x)^2/2` with
:math:`\hat\omega_n^2 = s_{\dot x}^2/s_x^2` of the record itself.  The inferred force
is :math:`f = \ddot x + \mathrm{drift}(x, \dot x)`.

The gap (:func:`gaps`) standardizes each component by the replicates:

.. math::

    z_j = \frac{T_j(y) - \bar T_j^{\rm rep}}{s_j^{\rm rep}\sqrt{1 + 1/R}}, \qquad
    G_m = \Big(\frac{1}{K_m}\sum_{j \in m} z_j^2\Big)^{1/2}, \qquad
    G = \Big(\frac{1}{M}\sum_m G_m^2\Big)^{1/2},

with :math:`R` replicates, :math:`\bar T^{\rm rep}` and :math:`s^{\rm rep}` their
mean and standard deviation (``ddof=1``), :math:`K_m` the components of measure
:math:`m` and :math:`M` the number of measures.  :math:`\sqrt{1 + 1/R}` makes
:math:`z_j` the standardized distance of a new draw from the replicate mean, so a
record from the fitted model has :math:`E[z_j^2] = (R-1)/(R-3)` (Gaussian
statistics) and :math:`G_m, G \approx 1`; a gap is a number of standard deviations.
The null distribution of :math:`G` is also measured directly, leaving each
replicate out in turn and scoring it against the others.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from .errors import HosidInputError
from .records import Record
from .spectra import block_fft, derivatives
from .terms import drift_from_params
from .windows import get_window

__all__ = [
    "ENERGY_LEVELS",
    "V_LEVELS",
    "X_LEVELS",
    "MeasureSpec",
    "compare",
    "gaps",
    "measures",
]

#: Probability levels of the quantiles of the standardized displacement.
X_LEVELS: tuple[float, ...] = (0.005, 0.025, 0.1, 0.25, 0.5, 0.75, 0.9, 0.975, 0.995)
#: Probability levels of the quantiles of the standardized speed.
V_LEVELS: tuple[float, ...] = (0.05, 0.1, 0.25, 0.5, 0.75, 0.9, 0.99)
#: Probability levels of the quantiles of log(E / mean E).
ENERGY_LEVELS: tuple[float, ...] = (0.05, 0.25, 0.5, 0.75, 0.9, 0.99)

_HANN = get_window("hann")

DriftLike = Callable[[np.ndarray, np.ndarray], np.ndarray] | Mapping[str, float] | None


@dataclass(frozen=True)
class MeasureSpec:
    r"""The fixed layout of the measures, taken from the observed record.

    Build it with :meth:`from_record` and pass the same spec for the record and
    every replicate.

    Attributes
    ----------
    dt : float
        Sampling interval (s); replicates must share it.
    omega_n : float
        Equivalent natural frequency :math:`\sigma_{\dot x}/\sigma_x` of the record (rad/s).
    block : int
        Samples per Hann-windowed block of the spectral measures.
    psd_edges, tail_edges, force_edges : tuple of float
        Band edges (rad/s) of ``psd``, ``psd_tail`` and ``force_psd``.
    force_cutoff : float
        Low-pass corner (rad/s) of the force for ``force_moments``.
    bispec_edges : tuple of float
        Edges (rad/s) of the bands L, R, H of the bispectral moments:
        :math:`(0, 0.5, 1.5, 3)\,\omega_n`.
    trim : int
        Samples left out at each end of the time-domain statistics (the
        spectral derivative's end errors).
    """

    dt: float
    omega_n: float
    block: int
    psd_edges: tuple[float, ...]
    tail_edges: tuple[float, ...]
    force_edges: tuple[float, ...]
    force_cutoff: float
    bispec_edges: tuple[float, float, float, float]
    trim: int

    @property
    def d_omega(self) -> float:
        """Bin spacing of the blocks (rad/s)."""
        return 2.0 * math.pi / (self.block * self.dt)

    @classmethod
    def from_record(
        cls,
        record: Record,
        *,
        block_seconds: float = 20.48,
        omega_n: float | None = None,
        min_blocks: int = 8,
    ) -> MeasureSpec:
        r"""The layout for ``record``.

        Parameters
        ----------
        record : Record
            The observed record.
        block_seconds : float
            Block length of the spectral measures (paper: 20.48 s).
        omega_n : float, optional
            Natural frequency (rad/s); default :math:`s_{\dot x}/s_x` of the record.
        min_blocks : int
            Fewest blocks accepted.

        Raises
        ------
        HosidInputError
            If the record holds fewer than ``min_blocks`` blocks, or if the bands
            do not fit below the Nyquist frequency or hold no frequency bin.
        """
        dt = record.dt
        M = round(block_seconds / dt)
        if M < 32 or record.n // M < min_blocks:
            raise HosidInputError(
                f"record of {record.duration:g} s is too short for {min_blocks} blocks of "
                f"{block_seconds:g} s ({M} samples of {dt:g} s)"
            )
        if omega_n is None:
            x = record.x - record.x.mean()
            v, _ = derivatives(x, dt)
            if not np.std(x) > 0:
                raise HosidInputError("record is constant")
            omega_n = float(np.std(v) / np.std(x))
        wn, wN, dw = float(omega_n), math.pi / dt, 2.0 * math.pi / (M * dt)
        if not (math.isfinite(wn) and 4.0 * dw <= wn <= 0.2 * wN):
            raise HosidInputError(
                f"natural frequency {wn:.3g} rad/s is outside [{4 * dw:.3g}, {0.2 * wN:.3g}] "
                f"rad/s: use longer blocks or a finer sampling"
            )
        psd_edges = (0.5 * dw, *np.linspace(0.25 * wn, 2.0 * wn, 8))
        tail_edges = tuple(np.geomspace(2.5 * wn, 0.8 * wN, 5))
        force_hi = min(4.0 * wn, 0.8 * wN)
        force_edges = tuple(np.geomspace(0.25 * wn, force_hi, 7))
        spec = cls(
            dt=dt,
            omega_n=wn,
            block=M,
            psd_edges=tuple(float(e) for e in psd_edges),
            tail_edges=tuple(float(e) for e in tail_edges),
            force_edges=tuple(float(e) for e in force_edges),
            force_cutoff=float(min(3.0 * wn, 0.8 * wN)),
            bispec_edges=(0.0, 0.5 * wn, 1.5 * wn, 3.0 * wn),
            trim=max(1, round(1.0 / dt)),
        )
        for edges in (spec.psd_edges, spec.tail_edges, spec.force_edges):
            counts = np.histogram(spec._omega, bins=np.asarray(edges))[0]
            if np.any(counts == 0):
                raise HosidInputError(
                    f"a band of {np.round(edges, 3).tolist()} rad/s holds no frequency bin "
                    f"of {block_seconds:g} s blocks: use longer blocks"
                )
        return spec

    @property
    def _omega(self) -> np.ndarray:
        return 2.0 * math.pi * np.fft.rfftfreq(self.block, self.dt)


# --------------------------------------------------------------------- helpers
def _block_fft(y: np.ndarray, spec: MeasureSpec) -> np.ndarray:
    """Hann-windowed block transforms, shape (N, M // 2 + 1)."""
    return block_fft(y, spec.block, spec.dt, _HANN)


def _psd(Y: np.ndarray, spec: MeasureSpec) -> np.ndarray:
    r"""Two-sided PSD estimate :math:`\overline{|Y|^2}/(2\pi T k_2)` per bin."""
    T = spec.block * spec.dt
    return np.mean(np.abs(Y) ** 2, axis=0) / (2.0 * math.pi * T * _HANN.k2)


def _band_log(P: np.ndarray, edges: Sequence[float], spec: MeasureSpec) -> np.ndarray:
    """Log of the mean of P over each band [lo, hi)."""
    idx = np.digitize(spec._omega, np.asarray(edges)) - 1
    out = np.empty(len(edges) - 1)
    for b in range(out.size):
        out[b] = np.log(np.mean(P[idx == b]))
    return out


def _std_moments(y: np.ndarray) -> np.ndarray:
    """Skewness and excess kurtosis of ``y``."""
    y = y - y.mean()
    s2 = np.mean(y**2)
    return np.array([np.mean(y**3) / s2**1.5, np.mean(y**4) / s2**2 - 3.0])


def _as_drift(drift: DriftLike) -> tuple[Callable | None, float]:
    """The drift callable and the mean force ``m`` (from a parameter mapping)."""
    if drift is None:
        return None, 0.0
    if isinstance(drift, Mapping):
        return drift_from_params(drift), float(drift.get("m", 0.0))
    if callable(drift):
        return drift, 0.0
    raise HosidInputError(
        f"drift must be None, a callable (x, v) -> force or a parameter mapping, got {drift!r}"
    )


def _potential(x: np.ndarray, drift: Callable, m: float) -> np.ndarray:
    r""":math:`V(x) - \min V` with :math:`V = \int_0^x (k(s) - m)\,ds`, :math:`k(s)` the
    drift at zero velocity, by the trapezoidal rule on 2049 points spanning the record.
    """
    lo, hi = min(float(x.min()), 0.0), max(float(x.max()), 0.0)
    grid = np.linspace(lo, hi, 2049)
    k = np.asarray(drift(grid, np.zeros_like(grid)), dtype=float) - m
    V = np.concatenate([[0.0], np.cumsum(0.5 * (k[1:] + k[:-1]) * np.diff(grid))])
    V -= np.interp(0.0, grid, V)
    Vx = np.interp(x, grid, V)
    return Vx - min(float(V.min()), float(Vx.min()))


def _band_split(y: np.ndarray, dt: float, edges: Sequence[float]) -> list[np.ndarray]:
    """``y`` split into frequency bands ``[edges[i], edges[i+1])`` by FFT masking."""
    F = np.fft.rfft(y)
    w = 2.0 * math.pi * np.fft.rfftfreq(y.size, dt)
    return [
        np.fft.irfft(np.where((w >= lo) & (w < hi), F, 0.0), y.size)
        for lo, hi in itertools.pairwise(edges)
    ]


def _bispectrum(xc: np.ndarray, body: slice, spec: MeasureSpec) -> np.ndarray:
    r"""Normalized third-order cross moments of frequency bands: integrals of the
    bispectrum over regions.

    With :math:`x = x_L + x_R + x_H + \dots` split into the bands ``bispec_edges``
    (below the resonance, around it, above it),

    .. math::

        c_{ABC} = \frac{E[x_A x_B x_C]}{\sigma_A\sigma_B\sigma_C}, \qquad
        E[x_A x_B x_C] = \iint_{\omega_1\in A,\ \omega_2\in B,\
        -\omega_1-\omega_2\in C} B_x(\omega_1, \omega_2)\,d\omega_1 d\omega_2,

    for :math:`(A, B, C)` = ``LRR`` (difference interaction: the slow part of
    :math:`x` following the resonant amplitude, as a quadratic stiffness drives
    it), ``LLR``, ``HRR`` (sum interaction: the second harmonic) and ``HHR``.  All
    are 0 for a system symmetric under :math:`x \to -x`.
    """
    L, R, H = (b[body] for b in _band_split(xc, spec.dt, spec.bispec_edges))
    sL, sR, sH = L.std(), R.std(), H.std()
    return np.array(
        [
            np.mean(L * R * R) / (sL * sR * sR),
            np.mean(L * L * R) / (sL * sL * sR),
            np.mean(H * R * R) / (sH * sR * sR),
            np.mean(H * H * R) / (sH * sH * sR),
        ]
    )


# -------------------------------------------------------------------- measures
def measures(
    record: Record,
    *,
    spec: MeasureSpec | None = None,
    drift: DriftLike = None,
) -> dict[str, np.ndarray]:
    r"""The discrepancy measures of one record (see the module docstring).

    Parameters
    ----------
    record : Record
        The observed record or a replicate.
    spec : MeasureSpec, optional
        The layout; default :meth:`MeasureSpec.from_record` of ``record``.  Use the
        observed record's spec for all replicates.
    drift : callable or mapping, optional
        The fitted drift, ``drift(x, v) -> force`` (e.g. :meth:`hosid.terms.Model.drift`)
        or a :func:`hosid.simulate.simulate` parameter dict (its ``m`` then also
        enters the potential).  It defines the inferred force
        :math:`f = \ddot x + \mathrm{drift}(x, \dot x)` (measures ``force_psd`` and
        ``force_moments``, present only with a drift) and the potential of the
        energy :math:`V(x) = \int_0^x (\mathrm{drift}(s, 0) - m)\,ds`.

    Returns
    -------
    dict of str to ndarray
        One 1-D vector per measure, with a layout fixed by ``spec``.

    Raises
    ------
    HosidInputError
        If the record's sampling interval differs from the spec's or the record is
        too short for eight blocks.
    """
    spec = MeasureSpec.from_record(record) if spec is None else spec
    if not math.isclose(record.dt, spec.dt, rel_tol=1e-9):
        raise HosidInputError(f"record dt {record.dt:g} differs from the spec's {spec.dt:g}")
    if record.n // spec.block < 8:
        raise HosidInputError(
            f"record of {record.n} samples is too short for 8 blocks of {spec.block}"
        )
    fn, m = _as_drift(drift)
    x = record.x
    mean_x = float(x.mean())
    xc = x - mean_x
    v, a = derivatives(xc, record.dt)
    body = slice(spec.trim, x.size - spec.trim)
    xs, vs = xc[body], v[body]

    X = _block_fft(xc, spec)
    P = _psd(X, spec)
    out: dict[str, np.ndarray] = {
        "psd": _band_log(P, spec.psd_edges, spec),
        "psd_tail": np.diff(_band_log(P, spec.tail_edges, spec)),
        "pdf_x": np.quantile(xs / xs.std(), X_LEVELS),
        "pdf_v": np.quantile(np.abs(vs) / vs.std(), V_LEVELS),
    }
    if fn is None:
        w2 = vs.var() / xs.var()
        energy = 0.5 * vs**2 + 0.5 * w2 * xs**2
    else:
        energy = 0.5 * vs**2 + _potential(x[body], fn, m)
    energy = np.maximum(energy / energy.mean(), np.finfo(float).tiny)
    out["pdf_energy"] = np.log(np.quantile(energy, ENERGY_LEVELS))
    mx, mv = _std_moments(xs), _std_moments(vs)
    out["skewness"] = np.array([mx[0], mv[0]])
    out["kurtosis"] = np.array([mx[1], mv[1]])
    out["mean"] = np.array([mean_x])
    out["bispectrum"] = _bispectrum(xc, body, spec)
    if fn is not None:
        f = a + np.asarray(fn(x, v), dtype=float)
        f = f - f.mean()
        Pf = _psd(_block_fft(f, spec), spec)
        logs = _band_log(Pf, spec.force_edges, spec)
        out["force_psd"] = logs - logs.mean()
        (low,) = _band_split(f, record.dt, (0.0, spec.force_cutoff))
        out["force_moments"] = _std_moments(low[body])
    return out


def _standardize(obs: np.ndarray, reps: np.ndarray) -> np.ndarray:
    r""":math:`z = (T - \bar T^{rep}) / (s^{rep}\sqrt{1 + 1/R})`."""
    R = reps.shape[0]
    mu = reps.mean(axis=0)
    sd = reps.std(axis=0, ddof=1)
    floor = 1e-12 * np.maximum(1.0, np.abs(mu))
    return (obs - mu) / (np.maximum(sd, floor) * math.sqrt(1.0 + 1.0 / R))


def _gap_values(
    obs: Mapping[str, np.ndarray], reps: Mapping[str, np.ndarray]
) -> tuple[dict[str, np.ndarray], dict[str, float], float]:
    z = {k: _standardize(obs[k], reps[k]) for k in obs}
    per = {k: float(np.sqrt(np.mean(zk**2))) for k, zk in z.items()}
    total = float(np.sqrt(np.mean(np.square(list(per.values())))))
    return z, per, total


def gaps(
    record_measures: Mapping[str, np.ndarray],
    replicate_measures: Sequence[Mapping[str, np.ndarray]],
) -> dict:
    r"""The record's standardized distance from the replicates, per measure and in total.

    .. math::

        z_j = \frac{T_j(y) - \bar T_j^{\rm rep}}{s_j^{\rm rep}\sqrt{1 + 1/R}}, \quad
        G_m = \Big(\frac{1}{K_m}\sum_{j\in m} z_j^2\Big)^{1/2}, \quad
        G = \Big(\frac{1}{M}\sum_m G_m^2\Big)^{1/2}.

    Parameters
    ----------
    record_measures : mapping
        :func:`measures` of the observed record.
    replicate_measures : sequence of mappings
        :func:`measures` of each replicate (same spec, same drift convention);
        at least 4, 20 or more recommended.

    Returns
    -------
    dict
        ``"total"`` (:math:`G`), ``"measures"`` (:math:`G_m` by name), ``"z"``
        (the component vectors), ``"worst"`` (the measure with the largest
        :math:`G_m`), ``"null"`` (the leave-one-out totals: each replicate scored
        against the other :math:`R - 1`, the null distribution of :math:`G`),
        ``"p_value"`` (:math:`(1 + \#\{G^{null} \ge G\})/(R + 1)`) and
        ``"n_replicates"``.

    Raises
    ------
    HosidInputError
        If fewer than 4 replicates are given or the measures do not line up.
    """
    R = len(replicate_measures)
    if R < 4:
        raise HosidInputError(f"need at least 4 replicates for a gap, got {R}")
    names = list(record_measures)
    stacked: dict[str, np.ndarray] = {}
    for k in names:
        obs = np.asarray(record_measures[k], dtype=float)
        try:
            reps = np.stack([np.asarray(r[k], dtype=float) for r in replicate_measures])
        except KeyError:
            raise HosidInputError(f"a replicate lacks the measure {k!r}") from None
        except ValueError:
            raise HosidInputError(f"replicates disagree on the layout of {k!r}") from None
        if reps.shape[1:] != obs.shape:
            raise HosidInputError(
                f"measure {k!r}: record has shape {obs.shape}, replicates {reps.shape[1:]}"
            )
        if not (np.all(np.isfinite(obs)) and np.all(np.isfinite(reps))):
            raise HosidInputError(f"measure {k!r} is not finite")
        stacked[k] = reps
    extra = set().union(*(set(r) for r in replicate_measures)) - set(names)
    if extra:
        raise HosidInputError(f"replicates hold measures the record lacks: {sorted(extra)}")
    obs = {k: np.asarray(record_measures[k], dtype=float) for k in names}
    z, per, total = _gap_values(obs, stacked)
    keep = np.ones(R, dtype=bool)
    null = np.empty(R)
    for j in range(R):
        keep[j] = False
        null[j] = _gap_values(
            {k: stacked[k][j] for k in names}, {k: stacked[k][keep] for k in names}
        )[2]
        keep[j] = True
    return {
        "total": total,
        "measures": per,
        "z": z,
        "worst": max(per, key=per.__getitem__),
        "null": null,
        "p_value": float((1 + np.sum(null >= total)) / (R + 1)),
        "n_replicates": R,
    }


def compare(
    record: Record,
    replicates: Sequence[Record],
    *,
    drift: DriftLike = None,
    spec: MeasureSpec | None = None,
) -> dict:
    """Measure a record and its replicates with one layout and return :func:`gaps`.

    The replicates must have the record's sampling interval and length.  The
    result also holds the ``"spec"`` used.

    Raises
    ------
    HosidInputError
        If a replicate's length or sampling interval differs from the record's.
    """
    spec = MeasureSpec.from_record(record) if spec is None else spec
    for i, rep in enumerate(replicates):
        if rep.n != record.n or not math.isclose(rep.dt, record.dt, rel_tol=1e-9):
            raise HosidInputError(
                f"replicate {i} has {rep.n} samples at dt {rep.dt:g}; the record has "
                f"{record.n} at dt {record.dt:g}"
            )
    obs = measures(record, spec=spec, drift=drift)
    reps = [measures(r, spec=spec, drift=drift) for r in replicates]
    out = gaps(obs, reps)
    out["spec"] = spec
    return out
