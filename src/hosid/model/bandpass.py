r"""A band-pass force: white noise through the second-order band-pass filter.

.. math:: \ddot u + 2\zeta_f\omega_f\dot u + \omega_f^2u = w, \qquad
    g = 2\zeta_f\omega_f\dot u, \qquad
    S_g = S_0\,\frac{(2\zeta_f\omega_f\omega)^2}{(\omega_f^2 - \omega^2)^2 +
    (2\zeta_f\omega_f\omega)^2}

(:math:`H(s) = 2\zeta_f\omega_fs/(s^2 + 2\zeta_f\omega_fs + \omega_f^2)`): the level
:math:`S_0` at the peak :math:`\omega_f`, zero at :math:`\omega = 0`, falling as
:math:`\omega^2` below the peak and :math:`\omega^{-2}` above it; half-power points
:math:`\omega_f(\sqrt{1+\zeta_f^2} \pm \zeta_f)`.  White noise is the limit
:math:`\zeta_f \to \infty`.

An inertial shaker (a mass driven by an actuator, whose reaction is the force) puts no
power into a structure at zero frequency.  The building of ``analyses/building.py`` is
driven at its roof by a hybrid mass damper whose measured force spectrum (0.15-4 Hz)
this shape follows with a log-residual of 0.24 rms (:math:`\omega_f` 4.9 rad/s,
:math:`\zeta_f` 0.51), the low-pass filter of ``narrowband_excitation`` with 0.58.  From
the floors alone Whittle's maximum is nonetheless the low-pass filter's (a deviance 20
lower, both about 810-830 below the white force's), which the record then chooses
(:func:`hosid.inference.spectral_pilot.settled_shape`); the band-pass asked for ends at a
narrow peak (:math:`\omega_f` 4.7 rad/s, :math:`\zeta_f` 0.07) with the first mode 3 %
below the input-output reference.  The band-pass form (numerator :math:`s`) is also the
usual rational approximation of a wave-elevation spectrum.

The factor :math:`(2\zeta_f\omega/\omega_f)^2` has a zero at :math:`\omega = 0`, so the
filter is not all-pole: the single oscillator's generator identities (whitening or
Stein's input power, :mod:`hosid.components.excitation`) do not hold it, and the shape is
a system's only (``excitation = "bandpass_excitation"`` in a system file: its channels'
spectral matrix, :mod:`hosid.components.chain_spectral_matrix`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from .excitation import NarrowbandExcitation, ShapeTerm
from .priors import LogUniform

__all__ = ["BandpassExcitation"]

#: The prior's range of the band-pass damping ratio (at the top the force is white
#: within 1 % from a quarter to four times the peak frequency).
ZF_RANGE = (0.02, 20.0)


@dataclass(frozen=True, repr=False)
class BandpassExcitation(ShapeTerm):
    r"""The band-pass force (module docstring): :math:`S_0L(\omega)` with
    :math:`L = (2\zeta_f\omega/\omega_f)^2\,\omega_f^4/[(\omega_f^2-\omega^2)^2 +
    (2\zeta_f\omega_f\omega)^2]`; :math:`\omega_f \sim \log U(\omega_n/10, \omega_N)`,
    :math:`\zeta_f \sim \log U(0.02, 20)`.  A system's shape only.
    """

    name: ClassVar[str] = "bandpass_excitation"
    params: ClassVar[tuple[str, ...]] = ("wf", "zf")
    shape_params: ClassVar[tuple[str, ...]] = ("wf", "zf")
    system_only: ClassVar[bool] = True
    latex: ClassVar[str] = (
        r"\frac{S_0\,(2\zeta_f\omega_f\omega)^2}{(\omega_f^2 - \omega^2)^2 + "
        r"(2\zeta_f\omega_f\omega)^2}"
    )

    def inverse_poly(self, wf, zf):
        r"""The denominator: the low-pass filter's
        (:meth:`hosid.model.excitation.NarrowbandExcitation.inverse_poly`); the numerator is
        :meth:`factor`.
        """
        return NarrowbandExcitation().inverse_poly(wf, zf)

    def factor(self, omega, wf, zf):
        r"""The numerator :math:`(2\zeta_f\omega/\omega_f)^2`."""
        return (2.0 * np.asarray(zf) * np.asarray(omega, dtype=float) / np.asarray(wf)) ** 2

    def default_priors(self, scales):
        """``wf ~ logU(w_n / 10, w_N)``, ``zf ~ logU(0.02, 20)``."""
        return {
            "wf": LogUniform(scales.omega_n / 10.0, scales.omega_nyquist),
            "zf": LogUniform(*ZF_RANGE),
        }
