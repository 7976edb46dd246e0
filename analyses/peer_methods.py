r"""The methods a user would pick instead of hosid, each on the displacement record alone.

All return ``{a1, n1, a2, n2, S0, a1eq}`` (NaN where a method does not estimate a
parameter), and ``sd_<name>`` where the method gives a standard error.  ``a1eq`` is
eq (65), :math:`a_1 + n_1\sqrt{8/\pi}\,\sigma_v`, at the ``sigma_v`` the caller passes
(the same for every method).

- :func:`km_drift`: the Kramers-Moyal / Langevin route.  The velocity is reconstructed
  (hosid's spectral derivative: the package needs the full state), the drift and
  diffusion of :math:`(x, v)` are estimated on a grid by ``kramersmoyal.km`` (kernel
  estimator, Lamouroux & Lehnertz 2009), and the model's drift
  :math:`-(a_1v + n_1v|v| + a_2x + n_2x^3)` is fitted to it by least squares weighted
  by the kernel density; the diffusion :math:`D^{(2)} = \pi S_0` gives the level.
- :func:`iv_drift`: an instrumental-variable drift regression (no package does this; ten
  lines of numpy).  With :math:`a_t = (x_{t+1} - 2x_t + x_{t-1})/\Delta^2` and
  :math:`v_t = (x_{t+1} - x_{t-1})/2\Delta`,

  .. math:: a_t = -\theta^{\mathsf T}z_t + e_t, \quad z_t = (v_t, v_t|v_t|, x_t, x_t^3),

  instrumented by the state two samples earlier,
  :math:`w_t = z_{t-2}`, which the force over :math:`(t_{t-1}, t_{t+1})` in
  :math:`e_t` does not reach: :math:`\hat\theta = -(W^{\mathsf T}Z)^{-1}W^{\mathsf T}a`.
  The standard errors are the sandwich with a Newey-West long-run covariance (2 lags:
  consecutive :math:`e_t` share the force over one sample).  The central difference of
  integrated white noise has variance :math:`4\pi S_0/3\Delta`, so
  :math:`\hat S_0 = 3\Delta\,\widehat{\mathrm{var}}(e)/4\pi`.
- :func:`ssi_cov`: linear operational modal analysis, covariance-driven stochastic
  subspace identification (Peeters & De Roeck 1999), written by hand because pyOMA2 is
  not on this machine's package index and koma-python, whose ``covssi`` needs only
  numpy, installs pyvista, vtk and jupyter with it.  The output correlations
  :math:`R_k` fill a block Hankel matrix :math:`H_{ij} = R_{i+j+1}`; its rank-``order``
  SVD gives the observability matrix :math:`O`, the shift :math:`O_{\downarrow}A =
  O_{\uparrow}` the state matrix, whose eigenvalues :math:`\mu` give the poles
  :math:`s = \ln\mu/\Delta`, :math:`\omega_n = |s|` and the damping ratio
  :math:`\zeta = -\mathrm{Re}\,s/|s|`.  A user would read :math:`a_{1eq} =
  2\zeta\omega_n` and :math:`a_2 = \omega_n^2` as the structure's damping and stiffness.
"""

from __future__ import annotations

import math

import kramersmoyal
import numpy as np

SQRT_8_PI = math.sqrt(8.0 / math.pi)
NAN = math.nan


def _a1eq(a1: float, n1: float, sigma_v: float) -> float:
    return a1 + n1 * SQRT_8_PI * sigma_v


def km_drift(
    x: np.ndarray, v: np.ndarray, dt: float, sigma_v: float, *, bins: int = 41, bw: float = 0.15
) -> dict[str, float]:
    """Kramers-Moyal drift and diffusion of ``(x, v)`` (module docstring); the state is
    standardized, the grid spans +-4 standard deviations with one kernel bandwidth
    ``bw`` (in standard deviations) for both axes.
    """
    sx, sv = float(np.std(x)), float(np.std(v))
    z = np.column_stack([x / sx, v / sv])
    edges = [np.linspace(-4.0, 4.0, bins + 1)] * 2
    powers = np.array([[0, 0], [0, 1], [0, 2]])
    kmc, centres = kramersmoyal.km(z, bins=edges, powers=powers, bw=bw)
    X, V = np.meshgrid(centres[0] * sx, centres[1] * sv, indexing="ij")
    w = kmc[0]
    ok = w > 1e-3 * w.max()
    drift = kmc[1][ok] * sv / dt  # E[dv | x, v] / dt
    diffusion = kmc[2][ok] * sv**2 / dt  # E[dv^2 | x, v] / (2 dt) = pi S0
    Xo, Vo = X[ok], V[ok]
    phi = np.column_stack([Vo, Vo * np.abs(Vo), Xo, Xo**3])
    sw = np.sqrt(w[ok])
    coef, *_ = np.linalg.lstsq(phi * sw[:, None], -drift * sw, rcond=None)
    a1, n1, a2, n2 = map(float, coef)
    S0 = float(np.sum(w[ok] * diffusion) / np.sum(w[ok]) / math.pi)
    return {"a1": a1, "n1": n1, "a2": a2, "n2": n2, "S0": S0, "a1eq": _a1eq(a1, n1, sigma_v)}


def _features(x: np.ndarray, v: np.ndarray) -> np.ndarray:
    return np.column_stack([v, v * np.abs(v), x, x**3])


def iv_drift(x: np.ndarray, dt: float, sigma_v: float, *, lags: int = 2) -> dict[str, float]:
    """The instrumental-variable drift regression (module docstring), with standard errors
    of every parameter (``sd_a1eq`` by the delta method at ``sigma_v``).
    """
    x = np.asarray(x, dtype=float) - np.mean(x)
    a = (x[2:] - 2.0 * x[1:-1] + x[:-2]) / dt**2  # at samples 1 .. n - 2
    v = (x[2:] - x[:-2]) / (2.0 * dt)
    Z = _features(x[1:-1], v)
    W, Z, a = Z[:-2], Z[2:], a[2:]  # the instrument of sample t is the state at t - 2
    G = W.T @ Z / len(a)
    theta = -np.linalg.solve(G, W.T @ a / len(a))
    e = a + Z @ theta
    g = W * e[:, None]
    S = g.T @ g / len(a)
    for lag in range(1, lags + 1):  # Newey-West
        c = g[lag:].T @ g[:-lag] / len(a)
        S += (1.0 - lag / (lags + 1)) * (c + c.T)
    Gi = np.linalg.inv(G)
    cov = Gi @ S @ Gi.T / len(a)
    a1, n1, a2, n2 = map(float, theta)
    grad = np.array([1.0, SQRT_8_PI * sigma_v, 0.0, 0.0])
    out = {
        "a1": a1,
        "n1": n1,
        "a2": a2,
        "n2": n2,
        "S0": float(3.0 * dt * np.var(e) / (4.0 * math.pi)),
        "a1eq": _a1eq(a1, n1, sigma_v),
        "sd_a1eq": float(math.sqrt(grad @ cov @ grad)),
    }
    out.update(
        {f"sd_{p}": float(math.sqrt(cov[i, i])) for i, p in enumerate(("a1", "n1", "a2", "n2"))}
    )
    return out


def ssi_cov(
    x: np.ndarray, dt: float, *, order: int = 2, rows: int | None = None
) -> dict[str, float]:
    r"""Covariance-driven SSI of the displacement (module docstring): of the
    ``order / 2`` modes (one by default), the one nearest the record's own frequency
    :math:`\sigma_v/\sigma_x`; ``rows`` block rows (default two of its periods).
    """
    y = np.asarray(x, dtype=float) - np.mean(x)
    omega_r = float(np.std(np.diff(y) / dt) / np.std(y))
    if rows is None:
        rows = max(order + 2, round(2 * 2 * math.pi / omega_r / dt))
    n = y.size
    R = np.array([y[k:] @ y[: n - k] / (n - k) for k in range(1, 2 * rows + 1)])
    H = np.array([[R[i + j] for j in range(rows)] for i in range(rows)])
    U, s, _ = np.linalg.svd(H)
    obs = U[:, :order] * np.sqrt(s[:order])
    A = np.linalg.lstsq(obs[:-1], obs[1:], rcond=None)[0]
    mu = np.linalg.eigvals(A)
    poles = np.log(mu[np.imag(mu) > 0].astype(complex)) / dt
    if poles.size == 0:
        return {"a1eq": NAN, "a2": NAN, "omega_n": NAN, "zeta": NAN}
    pole = poles[np.argmin(np.abs(np.abs(poles) - omega_r))]
    omega, zeta = float(abs(pole)), float(-pole.real / abs(pole))
    return {"a1eq": 2 * zeta * omega, "a2": omega**2, "omega_n": omega, "zeta": zeta}


def km_chain_drift(system, q: np.ndarray, v: np.ndarray, dt: float, *, bins: int = 14,
                   bw: float = 0.5) -> dict[str, float]:  # fmt: skip
    r"""The Kramers-Moyal route on a chain (issue 33): the drift and diffusion of every
    dof's velocity on a grid of the full state :math:`(q, \dot q)` (``kramersmoyal.km``,
    ``2n`` dimensions, ``bins`` a dimension over +-4 sd, bandwidth ``bw`` sd), then the
    system's equations :math:`m_d\,D^{(1)}_d + \Phi_d\theta = 0` (every element's
    coefficients, the unknown masses; :math:`m_1 = 1`) fitted over the grid by least
    squares weighted by the kernel density, and :math:`S_{0,d} = m_d^2 D^{(2)}_d/\pi`.
    ``q`` and ``v`` are ``(samples, n)``; returns the system's parameters by name.
    """
    n = system.n
    sq, sv = q.std(axis=0), v.std(axis=0)
    z = np.column_stack([q / sq, v / sv])
    powers = [np.zeros(2 * n, dtype=int)]
    for d in range(n):
        for k in (1, 2):
            p = np.zeros(2 * n, dtype=int)
            p[n + d] = k
            powers.append(p)
    edges = [np.linspace(-4.0, 4.0, bins + 1)] * (2 * n)
    kmc, centres = kramersmoyal.km(z, bins=edges, powers=np.array(powers), bw=bw)
    w = kmc[0]
    ok = w > 1e-3 * w.max()
    grid = np.meshgrid(*centres, indexing="ij")
    Q = np.column_stack([grid[d][ok] * sq[d] for d in range(n)])
    V = np.column_stack([grid[n + d][ok] * sv[d] for d in range(n)])
    Phi = system.features(Q, V)  # (cells, n, n_drift)
    drift = [kmc[1 + 2 * d][ok] * sv[d] / dt for d in range(n)]
    diffusion = [kmc[2 + 2 * d][ok] * sv[d] ** 2 / dt for d in range(n)]
    unknown = [d for d in range(n) if system.masses[d] is None]
    sw = np.sqrt(w[ok])
    rows, rhs = [], []
    for d in range(n):
        cols = [np.zeros(Phi.shape[0])] * len(unknown)
        if d in unknown:
            cols[unknown.index(d)] = drift[d]
        rows.append(np.column_stack([Phi[:, d, :], *cols]) * sw[:, None])
        known = 0.0 if d in unknown else float(system.masses[d])
        rhs.append(-known * drift[d] * sw)
    coef, *_ = np.linalg.lstsq(np.concatenate(rows), np.concatenate(rhs), rcond=None)
    nd = system.n_drift
    masses = [float(system.masses[d]) if d not in unknown else float(coef[nd + unknown.index(d)])
              for d in range(n)]  # fmt: skip
    out = dict(zip(system.param_names[:nd], map(float, coef[:nd]), strict=True))
    out.update({f"mass[{system.dofs[d]}]": masses[d] for d in unknown})
    for d, dof in enumerate(system.dofs):
        if dof in system.driven:
            level = float(np.sum(w[ok] * diffusion[d]) / np.sum(w[ok]))
            out[f"S0[{dof}]"] = masses[d] ** 2 * level / math.pi
    return out
