r"""Discrepancy measures between a record and posterior-predictive replicates.

Each measure is a statistic that some missing effect leaves its mark on.  All are
computed by :func:`measures` with one fixed layout (a :class:`MeasureSpec` taken
from the observed record), so that the record's vector lines up with those of
replicate records simulated from the fitted model:

- ``psd``: :math:`\log \bar S_x` in bands from the first bin to :math:`2\omega_n`
  (Hann blocks, mean removed); moved by the stiffness, the damping law and a
  coloured excitation.
- ``psd_tail``: the spectral tail's shape from :math:`4\omega_n` to :math:`\omega_N`,
  as the level-free scores of a corner and of a noise floor
  (:func:`hosid.spectra.tail.tail_scores`; weights fixed by the spec from the record's
  equivalent linear tail, :math:`k = s_{\dot x}^2/s_x^2`, :math:`c = \pi A/s_{\dot x}^2`,
  :math:`A` the force level of its response spectrum): coloured excitation (a steeper
  fall) and measurement noise (a floor), where both show most.
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
  over regions, :func:`hosid.check.statistics.bispectral_moments`); quadratic
  stiffness, mean force.
- ``force_psd`` (with a drift): the shape of :math:`\log \bar S_f` of the inferred
  force in log-spaced bands from :math:`0.25\omega_n` to :math:`4\omega_n` (mean over
  bands removed: whiteness, not level); coloured excitation, missing drift terms.
- ``force_moments`` (with a drift): skewness and excess kurtosis of the inferred force
  low-passed below :math:`3\omega_n` (Gaussianity); missing drift terms.

Here :math:`\omega_n = \sigma_{\dot x}/\sigma_x` is the record's equivalent natural
frequency, :math:`\omega_N = \pi/\Delta t`, and the velocity and acceleration are
spectral derivatives of the whole record (:func:`hosid.state.derivatives`).  The
response energy is :math:`E = \dot x^2/2 + V(x) - \min V` with
:math:`V(x) = \int_0^x \mathrm{drift}(s, 0)\,ds` (the restoring force, less a mean
force :math:`m`: its feature is :math:`-1`); with no drift it is model-free,
:math:`V = \hat\omega_n^2 (x - \bar x)^2/2` with :math:`\hat\omega_n = s_{\dot x}/s_x`.
The inferred force is :math:`f = \ddot x + \mathrm{drift}(x, \dot x)`.

The gap (:func:`gaps`) standardizes each component by the replicates:

.. math::

    z_j = \frac{T_j(y) - \bar T_j^{\rm rep}}{s_j^{\rm rep}\sqrt{1 + 1/R}}, \qquad
    G_m = \Big(\frac{1}{K_m}\sum_{j \in m} z_j^2\Big)^{1/2}, \qquad
    G = \Big(\frac{1}{M}\sum_m G_m^2\Big)^{1/2},

with :math:`R` replicates, :math:`\bar T^{\rm rep}` and :math:`s^{\rm rep}` their
mean and standard deviation (``ddof=1``), :math:`K_m` the components of measure
:math:`m` and :math:`M` the number of measures.  :math:`\sqrt{1 + 1/R}` makes
:math:`z_j` the standardized distance of a new draw from the replicate mean, so a
record from the fitted model has :math:`G_m, G \approx 1`; a gap is a number of
standard deviations.  The null distribution of :math:`G` is measured directly,
leaving each replicate out in turn and scoring it against the others.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from ..errors import HosidInputError
from ..record import Record
from ..spectra.blocks import block_fft, blocks_in, choose_layout
from ..spectra.response import response_spectrum
from ..spectra.tail import LOW, MIN_BINS, tail_bins, tail_scores
from ..spectra.windows import get_window
from ..state import derivatives
from .gaps import compare_layout, gaps
from .statistics import (
    Drift,
    band_split,
    bispectral_moments,
    drift_function,
    potential,
    std_moments,
)

__all__ = [
    "ENERGY_LEVELS",
    "V_LEVELS",
    "X_LEVELS",
    "MeasureSpec",
    "compare",
    "component_labels",
    "drift_function",
    "measures",
]

#: Probability levels of the quantiles of the standardized displacement.
X_LEVELS: tuple[float, ...] = (0.005, 0.025, 0.1, 0.25, 0.5, 0.75, 0.9, 0.975, 0.995)
#: Probability levels of the quantiles of the standardized speed.
V_LEVELS: tuple[float, ...] = (0.05, 0.1, 0.25, 0.5, 0.75, 0.9, 0.99)
#: Probability levels of the quantiles of log(E / mean E).
ENERGY_LEVELS: tuple[float, ...] = (0.05, 0.25, 0.5, 0.75, 0.9, 0.99)
#: Fewest blocks a record must hold for the spectral measures.
MIN_BLOCKS = 8

_HANN = get_window("hann")

DriftLike = Drift | Mapping[str, float] | None


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
    psd_edges, force_edges : tuple of float
        Band edges (rad/s) of ``psd`` and ``force_psd``.
    tail_band : tuple of float
        ``(lo, hi)`` (rad/s) of ``psd_tail``, or ``()`` when the tail holds too few bins.
    tail_shape : tuple of float
        ``(c, k)`` of the equivalent linear tail the weights of ``psd_tail`` are built on.
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
    tail_band: tuple[float, ...]
    tail_shape: tuple[float, float]
    force_edges: tuple[float, ...]
    force_cutoff: float
    bispec_edges: tuple[float, float, float, float]
    trim: int

    @property
    def d_omega(self) -> float:
        """Bin spacing of the blocks (rad/s)."""
        return 2.0 * math.pi / (self.block * self.dt)

    @property
    def omega(self) -> np.ndarray:
        """Frequencies of the block bins (rad/s)."""
        return 2.0 * math.pi * np.fft.rfftfreq(self.block, self.dt)

    @classmethod
    def from_record(
        cls,
        record: Record,
        *,
        block_seconds: float | None = None,
        omega_n: float | None = None,
        min_blocks: int = MIN_BLOCKS,
    ) -> MeasureSpec:
        r"""The layout for ``record``.

        Parameters
        ----------
        record : Record
            The observed record.
        block_seconds : float, optional
            Block length of the spectral measures; default about 16 periods of
            :math:`\omega_n` (:func:`hosid.spectra.choose_layout`; 20.48 s for the paper
            oscillator).
        omega_n : float, optional
            Natural frequency (rad/s); default :math:`s_{\dot x}/s_x` of the record.
        min_blocks : int
            Fewest blocks accepted.

        Raises
        ------
        HosidInputError
            If the record is constant or holds fewer than ``min_blocks`` blocks, or if
            the bands do not fit below the Nyquist frequency or hold no frequency bin.
        """
        dt = record.dt
        x = record.x - record.x.mean()
        if not np.std(x) > 0:
            raise HosidInputError("record is constant")
        v = np.concatenate([derivatives(p, dt)[0] for p in record.split(x)])
        if omega_n is None:
            omega_n = float(np.std(v) / np.std(x))
        wn, wN = float(omega_n), math.pi / dt
        if not (math.isfinite(wn) and wn > 0):
            raise HosidInputError(f"natural frequency {wn!r} rad/s is not positive")
        M = choose_layout(
            record.n, dt, wn, block_seconds=block_seconds, min_blocks=min_blocks,
            bounds=record.bounds,
        ).M  # fmt: skip
        dw = 2.0 * math.pi / (M * dt)
        if not 4.0 * dw <= wn <= 0.4 * wN:
            raise HosidInputError(
                f"natural frequency {wn:.3g} rad/s is outside [{4 * dw:.3g}, {0.4 * wN:.3g}] "
                f"rad/s: use longer blocks or a finer sampling"
            )
        # the tail up to the Nyquist frequency, where a corner and a noise floor show
        # most (hosid.spectra.tail), or to 0.8 of the excitation's edge when it stops
        # below it (nothing of the model's tail lies beyond); none when too few bins
        resp = response_spectrum(x, dt, sigma_v=float(np.std(v)), bounds=record.bounds)
        top, sv2 = (0.8 * resp.edge[0] if resp.edge else wN), float(np.var(v))
        _, tail_omega = tail_bins(M - 2, dt, LOW * wn, top)
        tail = (float(tail_omega[0]), float(top)) if tail_omega.size >= MIN_BINS else ()
        psd_edges = (0.5 * dw, *np.linspace(0.25 * wn, 2.0 * wn, 8))
        spec = cls(
            dt=dt,
            omega_n=wn,
            block=M,
            psd_edges=tuple(float(e) for e in psd_edges),
            tail_band=tail,
            tail_shape=(math.pi * max(resp.level, 1e-300) / sv2, sv2 / float(np.var(x))),
            force_edges=tuple(
                float(e) for e in np.geomspace(0.25 * wn, min(4.0 * wn, 0.8 * wN), 7)
            ),
            force_cutoff=float(min(3.0 * wn, 0.8 * wN)),
            bispec_edges=(0.0, 0.5 * wn, 1.5 * wn, min(3.0 * wn, wN)),
            trim=max(1, min(round(1.0 / dt), min(b - a for a, b in record.bounds) // 8)),
        )
        for edges in (spec.psd_edges, spec.force_edges):
            counts = np.histogram(spec.omega, bins=np.asarray(edges))[0]
            if np.any(counts == 0):
                raise HosidInputError(
                    f"a band of {np.round(edges, 3).tolist()} rad/s holds no frequency bin "
                    f"of {M * dt:g} s blocks: use longer blocks"
                )
        return spec


# --------------------------------------------------------------------- helpers
def _psd(y: np.ndarray, spec: MeasureSpec, bounds) -> np.ndarray:
    r"""Two-sided PSD estimate :math:`\overline{|Y|^2}/(2\pi T k_2)` per bin (Hann blocks
    inside the segments ``bounds``).
    """
    Y = block_fft(y, blocks_in(bounds, spec.block, spec.dt), _HANN)
    T = spec.block * spec.dt
    return np.mean(Y.real**2 + Y.imag**2, axis=0) / (2.0 * math.pi * T * _HANN.k2)


def _band_log(P: np.ndarray, edges: Sequence[float], spec: MeasureSpec) -> np.ndarray:
    """Log of the mean of P over each band [lo, hi)."""
    idx = np.digitize(spec.omega, np.asarray(edges)) - 1
    return np.array([np.log(np.mean(P[idx == b])) for b in range(len(edges) - 1)])


def _as_drift(drift: DriftLike) -> Drift | None:
    if drift is None:
        return None
    if isinstance(drift, Mapping):
        return drift_function(drift)
    if callable(drift):
        return drift
    raise HosidInputError(
        f"drift must be None, a callable (x, v) -> force or a parameter mapping, got {drift!r}"
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
        The fitted drift, ``drift(x, v) -> force``, or a parameter mapping of the
        model (:func:`drift_function`).  It defines the inferred force
        :math:`f = \ddot x + \mathrm{drift}(x, \dot x)` (measures ``force_psd`` and
        ``force_moments``, present only with a drift) and the potential of the energy.

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
    if blocks_in(record.bounds, spec.block, spec.dt).B < MIN_BLOCKS:
        raise HosidInputError(
            f"record of {record.n} samples is too short for {MIN_BLOCKS} blocks of {spec.block}"
        )
    fn = _as_drift(drift)
    x = record.x
    mean_x = float(x.mean())
    xc = x - mean_x
    segs = record.split(xc)
    deriv = [derivatives(p, record.dt) for p in segs]
    bodies = [slice(spec.trim, p.size - spec.trim) for p in segs]

    def pooled(parts) -> np.ndarray:  # the segments' bodies, one after the other
        return np.concatenate([p[b] for p, b in zip(parts, bodies, strict=True)])

    xs, vs = pooled(segs), pooled([d[0] for d in deriv])
    P = _psd(xc, spec, record.bounds)
    out: dict[str, np.ndarray] = {"psd": _band_log(P, spec.psd_edges, spec)}
    if spec.tail_band:
        blocks = blocks_in(record.bounds, spec.block, spec.dt).take(xc)
        out["psd_tail"] = tail_scores(blocks, spec.dt, spec.tail_band, spec.tail_shape)
    out["pdf_x"] = np.quantile(xs / xs.std(), X_LEVELS)
    out["pdf_v"] = np.quantile(np.abs(vs) / vs.std(), V_LEVELS)
    if fn is None:
        energy = 0.5 * vs**2 + 0.5 * (vs.var() / xs.var()) * xs**2
    else:
        energy = 0.5 * vs**2 + potential(xs + mean_x, fn)
    energy = np.maximum(energy / energy.mean(), np.finfo(float).tiny)
    out["pdf_energy"] = np.log(np.quantile(energy, ENERGY_LEVELS))
    mx, mv = std_moments(xs), std_moments(vs)
    out["skewness"] = np.array([mx[0], mv[0]])
    out["kurtosis"] = np.array([mx[1], mv[1]])
    out["mean"] = np.array([mean_x])
    out["bispectrum"] = bispectral_moments(
        list(zip(segs, bodies, strict=True)), spec.dt, spec.bispec_edges
    )
    if fn is not None:
        f = np.concatenate([a + fn(p + mean_x, v) for p, (v, a) in zip(segs, deriv, strict=True)])
        f = f - f.mean()
        logs = _band_log(_psd(f, spec, record.bounds), spec.force_edges, spec)
        out["force_psd"] = logs - logs.mean()
        low = [band_split(p, record.dt, (0.0, spec.force_cutoff))[0] for p in record.split(f)]
        out["force_moments"] = std_moments(pooled(low))
    return out


def component_labels(name: str, size: int) -> list[str]:
    """Short labels of the components of measure ``name`` (for plots)."""
    fixed = {
        "pdf_x": [f"q{p:g}" for p in X_LEVELS],
        "pdf_v": [f"q{p:g}" for p in V_LEVELS],
        "pdf_energy": [f"q{p:g}" for p in ENERGY_LEVELS],
        "skewness": ["x", "v"],
        "kurtosis": ["x", "v"],
        "mean": ["mean x"],
        "bispectrum": ["LRR", "LLR", "HRR", "HHR"],
        "force_moments": ["skew", "kurt"],
        "psd_tail": ["corner", "floor"],
    }.get(name)
    if fixed is not None and len(fixed) == size:
        return fixed
    return [f"band {i}" if name.endswith("psd") else str(i) for i in range(size)]


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
    compare_layout(record, replicates)
    obs = measures(record, spec=spec, drift=drift)
    reps = [measures(r, spec=spec, drift=drift) for r in replicates]
    out = gaps(obs, reps)
    out["spec"] = spec
    return out
