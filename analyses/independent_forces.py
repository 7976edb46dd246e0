r"""The non-white forces of the independent simulator (``independent_sim.py``).

Each force is exogenous (it does not depend on the oscillator), so it hands the
splitting kernel its exact impulse over every sub-step of length ``h``, a chunk at a
time, drawn only from the ``numpy.random.Generator`` passed in:

* :class:`NarrowBand` (keys ``wf, zf``): white noise ``w`` (``R_w = 2 pi S0 delta``)
  through ``g'' + 2 zf wf g' + wf^2 g = wf^2 w``, spectrum
  ``S0 wf^4 / ((wf^2 - omega^2)^2 + (2 zf wf omega)^2)``.  The state
  ``Z = (g, g', I)``, with ``I`` the integral of ``g`` since the start of the sub-step,
  obeys ``dZ = A Z dt + B dW``; one sub-step is ``Z -> expm(A h) Z + L xi`` with ``I``
  reset to 0 first, ``xi`` three standard normals and ``L L^T`` the exact noise
  covariance (Van Loan's block exponential, on the state rescaled by
  ``diag(1/h, 1, 1/h^2)`` so that every entry is of order one; Cholesky, or a
  symmetric eigen-factor should rounding make it indefinite).  The covariance is
  positive definite for ``h > 0``: ``(A, B)`` is controllable.  ``(g, g')`` starts from
  its stationary law (the Lyapunov equation), so the force needs no burn-in.
* :class:`PoissonImpulses` (key ``rate``): impulses at the times of a Poisson process
  of rate ``rate``, areas ``N(0, 2 pi S0 / rate)``: the white spectrum ``S0`` of the
  Gaussian force, but not Gaussian.  The impulse over a sub-step is the sum of
  ``Poisson(rate h)`` areas, drawn exactly as ``sqrt(count) N(0, 2 pi S0 / rate)``
  (normals only for the sub-steps with a count).
"""

from __future__ import annotations

import math

import numba
import numpy as np
import scipy.linalg

__all__ = ["NarrowBand", "PoissonImpulses", "narrowband_matrices"]


def _drift(wf: float, zf: float) -> np.ndarray:
    """``A`` of ``Z = (g, g', I)``."""
    return np.array([[0.0, 1.0, 0.0], [-(wf**2), -2.0 * zf * wf, 0.0], [1.0, 0.0, 0.0]])


def narrowband_matrices(
    wf: float, zf: float, S0: float, h: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Exact one-sub-step matrices of the narrow-band force.

    Returns
    -------
    phi : numpy.ndarray
        ``expm(A h)`` (3 x 3), acting on ``(g, g', 0)``.
    cov : numpy.ndarray
        The noise covariance ``int_0^h expm(A s) B B^T expm(A s)^T ds`` (3 x 3).
    stationary : numpy.ndarray
        The stationary covariance of ``(g, g')`` (2 x 2), from the Lyapunov equation.
    """
    a = _drift(wf, zf)
    q = 2.0 * math.pi * S0 * wf**4  # B B^T = q e2 e2^T
    d = np.array([1.0 / h, 1.0, 1.0 / h**2])  # rescaled state D Z, of one order
    a_s = a * d[:, None] / d[None, :]
    m = np.zeros((6, 6))
    m[:3, :3] = -a_s * h
    m[1, 4] = h  # (B B^T / q) h, in the rescaled state (D B = B)
    m[3:, 3:] = a_s.T * h
    e = scipy.linalg.expm(m)
    phi_s = e[3:, 3:].T
    cov_s = phi_s @ e[:3, 3:]
    cov_s = 0.5 * (cov_s + cov_s.T)
    phi = phi_s * d[None, :] / d[:, None]
    cov = q * cov_s / np.outer(d, d)
    stationary = scipy.linalg.solve_continuous_lyapunov(a[:2, :2], -np.diag([0.0, q]))
    return phi, cov, 0.5 * (stationary + stationary.T)


def _factor(cov: np.ndarray) -> np.ndarray:
    """``L`` with ``L L^T = cov``: Cholesky on the rescaled matrix, else an eigen-factor."""
    s = np.sqrt(np.diag(cov))
    try:
        return np.linalg.cholesky(cov / np.outer(s, s)) * s[:, None]
    except np.linalg.LinAlgError:
        w, u = np.linalg.eigh(cov)
        return u * np.sqrt(np.clip(w, 0.0, None))


@numba.njit(cache=True)
def _narrowband_impulses(xi, phi, low, state, out):  # pragma: no cover - compiled
    """``out[k]``: the force's impulse over sub-step ``k``; ``state = [g, g']`` advanced."""
    g = state[0]
    gd = state[1]
    for k in range(out.size):
        a, b, c = xi[0, k], xi[1, k], xi[2, k]
        out[k] = phi[2, 0] * g + phi[2, 1] * gd + low[2, 0] * a + low[2, 1] * b + low[2, 2] * c
        gn = phi[0, 0] * g + phi[0, 1] * gd + low[0, 0] * a + low[0, 1] * b + low[0, 2] * c
        gd = phi[1, 0] * g + phi[1, 1] * gd + low[1, 0] * a + low[1, 1] * b + low[1, 2] * c
        g = gn
    state[0] = g
    state[1] = gd


class NarrowBand:
    """The narrow-band force; its stationary start is drawn from ``rng`` on creation."""

    def __init__(self, wf: float, zf: float, S0: float, h: float, rng: np.random.Generator):
        self.phi, cov, stationary = narrowband_matrices(wf, zf, S0, h)
        self.low = _factor(cov)
        self.state = _factor(stationary) @ rng.standard_normal(2)

    def impulses(self, rng: np.random.Generator, n: int) -> np.ndarray:
        """The impulses over the next ``n`` sub-steps, shape ``(1, n)``."""
        out = np.empty((1, n))
        _narrowband_impulses(rng.standard_normal((3, n)), self.phi, self.low, self.state, out[0])
        return out


class PoissonImpulses:
    """Poisson impulses of rate ``rate`` and Gaussian areas of variance ``2 pi S0 / rate``."""

    def __init__(self, rate: float, S0: float, h: float):
        self.mean = rate * h
        self.area_var = 2.0 * math.pi * S0 / rate

    def impulses(self, rng: np.random.Generator, n: int) -> np.ndarray:
        """The summed areas over the next ``n`` sub-steps, shape ``(1, n)``."""
        counts = rng.poisson(self.mean, n)
        out = np.zeros((1, n))
        hit = np.flatnonzero(counts)
        out[0, hit] = np.sqrt(counts[hit] * self.area_var) * rng.standard_normal(hit.size)
        return out
