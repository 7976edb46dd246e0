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

A change of the parameters during the record (:class:`ParameterChange`; keys
``change_at``, ``ramp``, ``<p>_after`` of ``independent_sim.simulate``) is not a force
but changes the force's level too: from ``change_at`` seconds after the record's first
sample the parameters move linearly over ``ramp`` seconds (0: a step) to their values
after, ``p(t) = (1 - phi) p + phi p_after``, ``phi = clip((t - change_at) / ramp, 0,
1)``.  The splitting kernel then runs piecewise: a piece of samples with the same
``phi`` (taken at each sample's midpoint: a step falls on the sample boundary nearest
``change_at``, a ramp is a staircase of one stair a sample) runs with that piece's
coefficients, and its kicks (white, low-pass, narrow-band or impulses) are scaled by
``sqrt(S0(t) / S0)``.
"""

from __future__ import annotations

import itertools
import math

import numba
import numpy as np
import scipy.linalg

__all__ = [
    "CHANGE_KEYS",
    "NarrowBand",
    "ParameterChange",
    "PoissonImpulses",
    "narrowband_matrices",
]

#: The parameters that may change, in the order of the splitting kernel's coefficients.
_CHANGING = ("a1", "n1", "a2", "n2", "b2", "mu", "m")
#: A change's keys in ``independent_sim.simulate``'s params.
CHANGE_KEYS = ("change_at", "ramp", *(f"{p}_after" for p in (*_CHANGING, "S0")))


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


class ParameterChange:
    """The pieces of a record with a step or ramp of the parameters (module docstring).

    ``params`` holds the parameters before (``a1 .. m``, ``S0``; absent = 0) and the
    change's keys (:data:`CHANGE_KEYS`, none: no change); ``coefficients`` the kernel's
    coefficients before, whose first seven are ``a1, n1, a2, n2, b2, mu, m``; the record
    is kept after ``n_burn`` samples of burn-in.

    Raises
    ------
    ValueError
        On a change without ``change_at`` or values after it, outside the record, with
        non-finite values, or to parameters out of range (``a1, n1, n2, mu >= 0``,
        ``a1 + n1 > 0``, ``a2 > 0``, ``S0 > 0``, ``b2`` only with ``n2 > 0``).
    """

    def __init__(self, params, coefficients, duration: float, dt: float, n_burn: int):
        given = {k: float(params[k]) for k in CHANGE_KEYS if k in params}
        after = {k[:-6]: v for k, v in given.items() if k.endswith("_after")}
        self.coefficients, self.dt, self.n_burn = tuple(coefficients), float(dt), int(n_burn)
        self.at, self.ramp = given.get("change_at"), given.get("ramp", 0.0)
        if self.at is None:
            if given:
                raise ValueError(f"{', '.join(given)} without change_at: {dict(params)}")
            return
        if not after or not all(math.isfinite(v) for v in given.values()):
            raise ValueError(f"change_at needs finite values after it (<p>_after): {params}")
        if not (0 < self.at < duration and self.ramp >= 0 and self.at + self.ramp <= duration):
            raise ValueError(
                f"the change must lie in the record: 0 < change_at < change_at + ramp <= "
                f"duration = {duration:g} s; got change_at {self.at:g} s, ramp {self.ramp:g} s"
            )
        before = {k: float(params.get(k, 0.0)) for k in (*_CHANGING, "S0")}
        self.before, self.after = before, {**before, **after}
        p = self.after
        ok = min(p["a1"], p["n1"], p["n2"], p["mu"]) >= 0 and p["a1"] + p["n1"] > 0
        if not (ok and p["a2"] > 0 and p["S0"] > 0 and (p["b2"] == 0 or p["n2"] > 0)):
            raise ValueError(f"parameters after the change out of range: {p}")

    def _phi(self, samples: np.ndarray) -> np.ndarray:
        """``phi`` at the midpoints of the (0-based, burn-in included) samples' steps."""
        t = (samples - self.n_burn - 0.5) * self.dt - self.at  # sample i ends at i - n_burn
        if self.ramp > 0:
            return np.clip(t / self.ramp, 0.0, 1.0)
        return (t >= 0).astype(float)

    def pieces(self, xi: np.ndarray, start: int, count: int, sub: int):
        """``(offset, length, coefficients, kicks)`` of the pieces of the ``count``
        samples from sample ``start`` (burn-in included), ``kicks`` the piece's part of
        ``xi`` (``sub`` columns a sample) scaled by ``sqrt(S0(t) / S0)``; one piece,
        ``xi`` itself, without a change.
        """
        if self.at is None:
            return [(0, count, self.coefficients, xi)]
        phi = self._phi(np.arange(start, start + count))
        cuts = [0, *(np.flatnonzero(np.diff(phi)) + 1), count]
        out = []
        for lo, hi in itertools.pairwise(cuts):
            f = float(phi[lo])
            p = {k: (1.0 - f) * v + f * self.after[k] for k, v in self.before.items()}
            co = (*(p[k] for k in _CHANGING), *self.coefficients[len(_CHANGING) :])
            kicks = xi[:, lo * sub : hi * sub]
            if p["S0"] != self.before["S0"]:
                kicks = kicks * math.sqrt(p["S0"] / self.before["S0"])
            out.append((lo, hi - lo, co, np.ascontiguousarray(kicks)))
        return out
