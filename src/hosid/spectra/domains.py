r"""Frequency domains of the higher-order spectra (paper eqs 39, 64; section 6).

Bins are integers :math:`k` with :math:`\omega_k = 2\pi k/T`; negative bins stand for
complex conjugates.

Trispectrum (fourth order) on triples :math:`(k_1, k_2, k_3)`,
:math:`k_4 = k_1 + k_2 + k_3`, all four in :math:`k_{min} \le |k| \le k_{max}`:

- ``"principal"``: eq (39), :math:`k_1 \ge k_2 \ge k_3`, :math:`k_4 \ge 0`,
  :math:`k_1 + k_2 + 2k_3 \ge 0`, exactly one negative frequency;
- ``"reduced"``: the principal domain within one bin of a plane
  :math:`\omega_i + \omega_j = 0` (eq 64 read as a union);
- ``"full"``: every triple.

Bispectrum (third order) on pairs :math:`k_{lo} \le k_2 \le k_1`,
:math:`k_1 + k_2 \le k_{max}`, :math:`k_{lo} = \max(k_{min}, 2)`: with the Hann window
a constant leaks only into bins :math:`0, \pm1`, so a mean force reaches no ordinate
(paper section 6).
"""

from __future__ import annotations

import numpy as np

__all__ = ["DOMAINS", "bispectral_domain", "trispectral_domain"]

#: Names of the trispectral domains.
DOMAINS = ("principal", "reduced", "full")


def trispectral_domain(k_max: int, kind: str = "principal", k_min: int = 1) -> np.ndarray:
    """Integer bins ``(n, 4)``: ``k1, k2, k3, k4 = k1 + k2 + k3`` (module docstring).

    Raises
    ------
    ValueError
        For an unknown ``kind``.
    """
    if kind not in DOMAINS:
        raise ValueError(f"unknown trispectral domain {kind!r}: {', '.join(DOMAINS)}")
    r = np.arange(-k_max, k_max + 1)
    r = r[np.abs(r) >= k_min]
    k1, k2, k3 = (a.ravel() for a in np.meshgrid(r, r, r, indexing="ij"))
    k4 = k1 + k2 + k3
    ok = (np.abs(k4) >= k_min) & (np.abs(k4) <= k_max)
    if kind != "full":
        neg = (k1 < 0).astype(int) + (k2 < 0) + (k3 < 0)
        ok &= (k1 >= k2) & (k2 >= k3) & (k4 >= 0) & (k1 + k2 + 2 * k3 >= 0) & (neg == 1)
        if kind == "reduced":  # eq (64)
            ok &= (np.abs(k1 + k2) <= 1) | (np.abs(k1 + k3) <= 1) | (np.abs(k2 + k3) <= 1)
    return np.stack([k1[ok], k2[ok], k3[ok], k4[ok]], axis=1)


def bispectral_domain(k_max: int, k_min: int = 1) -> np.ndarray:
    """Integer bins ``(n, 3)``: ``k1, k2, k3 = k1 + k2`` (module docstring)."""
    lo = max(k_min, 2)
    k1, k2 = np.meshgrid(np.arange(lo, k_max + 1), np.arange(lo, k_max + 1), indexing="ij")
    k1, k2 = k1.ravel(), k2.ravel()
    ok = (k2 <= k1) & (k1 + k2 <= k_max)
    return np.stack([k1[ok], k2[ok], k1[ok] + k2[ok]], axis=1)
