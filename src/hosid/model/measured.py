r"""A measured excitation shape: the force spectrum :math:`S_0\,\ell(\omega)` with
:math:`\ell` a table the user knows (a measured wave-elevation spectrum times a moment
transfer function) and the level :math:`S_0` estimated.

The spectral components use the table itself, interpolated linearly in
:math:`\omega` (``--excitation-shape FILE.csv``, columns ``omega`` in rad/s and
``level``; the table's scale is the user's: :math:`S_0` multiplies it).  The generator
identities need a Markov state, so the shape enters them through the second-order
shaping filter that approximates it best, the rational form ship-roll practice uses for
wave spectra:

.. math:: \ell(\omega) \approx \frac{G\,\omega_f^4}{(\omega_f^2-\omega^2)^2 +
    (2\zeta_f\omega_f\omega)^2},

fitted once to the table by least squares in :math:`\log\ell` over the table's range
(:func:`rational_fit`), its gain absorbed in the whitening operator
:math:`P(s) = (1 + 2\zeta_fs/\omega_f + s^2/\omega_f^2)/\sqrt G`, so that :math:`Pg` is
white at the level :math:`S_0`.  Where the table and its rational form part, the
identities carry the difference; the fit states the approximation's misfit on the
record's band (:meth:`MeasuredExcitation.misfit`).  Outside the table the shape is the
rational form.  No shape parameter is estimated.
"""

from __future__ import annotations

import csv
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import ClassVar

import numpy as np
from scipy.optimize import least_squares

from ..errors import HosidInputError
from .excitation import ShapeTerm
from .priors import LogUniform
from .simulate import narrowband_shape

__all__ = ["MeasuredExcitation", "rational_fit", "read_shape", "shape_attrs", "with_shape"]


def rational_fit(omega: np.ndarray, level: np.ndarray) -> tuple[float, float, float]:
    r"""``(G, wf, zf)`` of the second-order form (module docstring) closest to the
    positive ``level`` in :math:`\log`, over 400 log-spaced points of the table's range:
    a grid over :math:`(\omega_f, \zeta_f)` with :math:`G` in closed form, refined by
    :func:`scipy.optimize.least_squares`.
    """
    pos = level > 0
    lo = max(float(omega[pos].min()), 1e-3 * float(omega[pos].max()))
    w = np.geomspace(lo, float(omega[pos].max()), 400)
    y = np.log(np.interp(w, omega[pos], level[pos]))

    def resid(q):  # q = log wf, log zf, log G
        return y - q[2] - np.log(narrowband_shape(np.exp(q[0]), np.exp(q[1]))(w))

    best = None
    for wf in np.geomspace(w[0] / 3.0, 3.0 * w[-1], 60):
        for zf in np.geomspace(0.01, 4.0, 40):
            r = resid([math.log(wf), math.log(zf), 0.0])
            q = np.array([math.log(wf), math.log(zf), float(r.mean())])
            cost = float(np.sum((r - r.mean()) ** 2))
            if best is None or cost < best[0]:
                best = (cost, q)
    q = least_squares(resid, best[1]).x
    return float(np.exp(q[2])), float(np.exp(q[0])), float(np.exp(q[1]))


@dataclass(frozen=True, repr=False)
class MeasuredExcitation(ShapeTerm):
    """The measured shape (module docstring): build it with :func:`read_shape` or
    :meth:`from_table`.
    """

    name: ClassVar[str] = "measured_excitation"
    params: ClassVar[tuple[str, ...]] = ()
    whitening: ClassVar[bool] = True
    latex: ClassVar[str] = r"S_0\,\ell(\omega)"
    omega: tuple[float, ...] = ()
    level: tuple[float, ...] = ()
    rational: tuple[float, float, float] = field(default=(1.0, 1.0, 1.0))  # G, wf, zf

    @classmethod
    def from_table(cls, omega, level, source: str = "the shape") -> MeasuredExcitation:
        """The term of the table ``(omega, level)`` (sorted by ``omega``).

        Raises
        ------
        HosidInputError
            On fewer than 4 rows, a non-finite or negative value, a repeated frequency or
            a shape that is zero everywhere.
        """
        w = np.asarray(omega, dtype=float).ravel()
        s = np.asarray(level, dtype=float).ravel()
        if w.size < 4 or w.size != s.size:
            raise HosidInputError(f"{source}: needs at least 4 rows of omega and level")
        if not (np.all(np.isfinite(w)) and np.all(np.isfinite(s))):
            raise HosidInputError(f"{source}: omega and level must be finite numbers")
        if np.any(w < 0) or np.any(s < 0):
            raise HosidInputError(f"{source}: omega and level must be >= 0")
        order = np.argsort(w)
        w, s = w[order], s[order]
        if np.any(np.diff(w) == 0):
            raise HosidInputError(f"{source}: a frequency is repeated")
        if np.count_nonzero(s) < 4:
            raise HosidInputError(f"{source}: the level must be positive at 4 frequencies")
        return cls(tuple(w.tolist()), tuple(s.tolist()), rational_fit(w, s))

    def simulated(self, params: dict) -> dict:
        r"""The simulator's parameters of a force with this shape: its second-order
        form, :math:`S_0G` at :math:`\omega = 0`, ``wf`` and ``zf`` (the table itself has
        no Markov simulator).
        """
        G, wf, zf = self.rational
        return {**params, "S0": params["S0"] * G, "wf": wf, "zf": zf}

    def to_dict(self) -> dict:
        """The table, for a result's attributes (:meth:`from_table` reads it back)."""
        return {"omega": list(self.omega), "level": list(self.level)}

    def operator(self) -> list:
        r"""The rational form's whitening operator, gain included:
        :math:`(1, 2\zeta_f/\omega_f, 1/\omega_f^2)/\sqrt G`.
        """
        G, wf, zf = self.rational
        g = 1.0 / math.sqrt(G)
        return [g, 2.0 * zf / wf * g, g / wf**2]

    @property
    def order(self) -> int:
        """The whitening order (2)."""
        return 2

    def inverse_poly(self) -> list:
        """No free coefficient: the table enters as it is (:meth:`table`)."""
        return [1.0]

    def table(self, omega) -> np.ndarray:
        r""":math:`\ell(|\omega|)`: the table inside its range, the rational form outside."""
        a = np.abs(np.asarray(omega, dtype=float))
        inside = (a >= self.omega[0]) & (a <= self.omega[-1])
        return np.where(inside, np.interp(a, self.omega, self.level), self.second_order(a))

    def second_order(self, omega) -> np.ndarray:
        r"""The table's second-order form :math:`G\,L_f(\omega)` (module docstring)."""
        G, wf, zf = self.rational
        return G * narrowband_shape(wf, zf)(np.asarray(omega, dtype=float))

    def check_band(self, lo: float, hi: float) -> None:
        """Raise unless the table covers ``[lo, hi]`` (rad/s) with a positive level.

        Raises
        ------
        HosidInputError
            With both ranges, when it does not.
        """
        w0, w1 = self.omega[0], self.omega[-1]
        if w0 > lo * (1 + 1e-9) or w1 < hi * (1 - 1e-9):
            raise HosidInputError(
                f"the excitation shape covers {w0:.4g}-{w1:.4g} rad/s; the record's band is "
                f"{lo:.4g}-{hi:.4g} rad/s: give the shape over the whole band"
            )
        grid = np.linspace(lo, hi, 512)
        if np.any(self.table(grid) <= 0):
            raise HosidInputError(
                f"the excitation shape is zero within the record's band {lo:.4g}-{hi:.4g} "
                "rad/s, where the record has power: the shape cannot be the force's"
            )

    def misfit(self, omega) -> float:
        """The rms of the log-ratio between the table and its rational form over
        ``omega`` (0 for a table that is a second-order filter).
        """
        a = np.abs(np.asarray(omega, dtype=float))
        return float(np.sqrt(np.mean(np.log(self.table(a) / self.second_order(a)) ** 2)))

    def default_priors(self, scales):
        r"""No parameter of its own; the level's prior is moved by the table's scale:
        :math:`S_0 \sim \log U(\hat S_0/100\ell_n, 100\hat S_0/\ell_n)` with
        :math:`\ell_n = \ell(\omega_n)` (the white guess :math:`\hat S_0` is the force's
        level near the resonance).
        """
        ln = float(self.table(scales.omega_n))
        return {"S0": LogUniform(scales.S0 / (100.0 * ln), 100.0 * scales.S0 / ln)}


def read_shape(path: str | Path) -> MeasuredExcitation:
    """The measured shape in the CSV ``path`` (columns ``omega`` and ``level``).

    Raises
    ------
    HosidInputError
        If the file is missing or unreadable, lacks a column, or holds a bad table.
    """
    path = Path(path)
    if not path.is_file():
        raise HosidInputError(f"excitation shape {str(path)!r}: no such file")
    try:
        with path.open(newline="") as fh:
            rows = list(csv.DictReader(fh))
    except (OSError, UnicodeDecodeError, csv.Error) as exc:
        raise HosidInputError(f"excitation shape {str(path)!r}: cannot read it ({exc})") from None
    cols = {k.strip().lower(): k for k in (rows[0] if rows else {}) if k}
    missing = [c for c in ("omega", "level") if c not in cols]
    if missing:
        raise HosidInputError(
            f"excitation shape {str(path)!r}: needs the columns omega (rad/s) and level; "
            f"missing {', '.join(missing)}"
        )
    try:
        w = [float(r[cols["omega"]]) for r in rows]
        s = [float(r[cols["level"]]) for r in rows]
    except (TypeError, ValueError):
        raise HosidInputError(
            f"excitation shape {str(path)!r}: omega and level must be numbers"
        ) from None
    return MeasuredExcitation.from_table(w, s, source=f"excitation shape {str(path)!r}")


def with_shape(spec: str, path: str | Path):
    """The model of the spec ``spec`` with the measured shape in the CSV ``path``."""
    from .model import Model

    return Model.from_spec([*str(spec).split(","), read_shape(path)])


def shape_attrs(model) -> dict:
    """``{"excitation_shape": table}`` for a result's attributes when ``model`` holds a
    measured shape (:func:`hosid.output.results.stored_model` reads it back), else ``{}``.
    """
    for t in model.terms:
        if isinstance(t, MeasuredExcitation):
            return {"excitation_shape": t.to_dict()}
    return {}
