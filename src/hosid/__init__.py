r"""hosid: output-only identification of a nonlinear oscillator from higher-order spectra.

The oscillator (Vasta & Roberts 1998, section 7) is

.. math:: \ddot x + a_1 \dot x + n_1 \dot x |\dot x| + a_2 x + n_2 x^3 = f(t),

with :math:`f` Gaussian white noise of two-sided spectral level :math:`S_0`.
The data flow is record -> features -> block spectra -> costs -> estimators.
"""

__version__ = "0.1.0"
