r"""The gap: a record's standardized distance from its posterior-predictive replicates.

.. math::

    z_j = \frac{T_j(y) - \bar T_j^{\rm rep}}{s_j^{\rm rep}\sqrt{1 + 1/R}}, \qquad
    G_m = \Big(\frac{1}{K_m}\sum_{j\in m} z_j^2\Big)^{1/2}, \qquad
    G = \Big(\frac{1}{M}\sum_m G_m^2\Big)^{1/2}

(:mod:`hosid.check.measures` defines the measures :math:`T`); the leave-one-out gaps
of the replicates sample the null distribution of :math:`G`, and
:func:`robust_z` standardizes a gap by them.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

import numpy as np

from ..errors import HosidInputError
from ..record import Record

__all__ = ["compare_layout", "gaps", "robust_scale", "robust_z"]


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

    Parameters
    ----------
    record_measures : mapping
        :func:`hosid.check.measures.measures` of the observed record.
    replicate_measures : sequence of mappings
        The measures of each replicate (same spec, same drift); at least 4, 20 or
        more recommended.

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


def robust_scale(null: np.ndarray) -> tuple[float, float]:
    r"""Median and :math:`1.4826\,\operatorname{MAD}` of the finite null gaps
    (``nan`` when there are none).
    """
    null = np.asarray(null, dtype=float)
    null = null[np.isfinite(null)]
    if null.size == 0:
        return math.nan, math.nan
    med = float(np.median(null))
    return med, max(1.4826 * float(np.median(np.abs(null - med))), 1e-12)


def robust_z(total: float, null: np.ndarray) -> float:
    r"""A gap standardized robustly by its leave-one-out null gaps,
    :math:`(G - \operatorname{med} G^{null})/(1.4826\,\operatorname{MAD} G^{null})`
    (:math:`+\infty` for an infinite gap).
    """
    if not math.isfinite(total):
        return math.inf
    med, scale = robust_scale(null)
    return (total - med) / scale


def compare_layout(record: Record, replicates: Sequence[Record]) -> None:
    """Check that every replicate has the record's length and sampling interval.

    Raises
    ------
    HosidInputError
        Naming the first replicate that does not.
    """
    for i, rep in enumerate(replicates):
        if rep.n != record.n or not math.isclose(rep.dt, record.dt, rel_tol=1e-9):
            raise HosidInputError(
                f"replicate {i} has {rep.n} samples at dt {rep.dt:g}; the record has "
                f"{record.n} at dt {record.dt:g}"
            )
