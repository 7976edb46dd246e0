r"""The modal view of a fitted system: natural frequencies, damping ratios and mode shapes
of its linearisation, as derived posterior quantities.

Each element's force :math:`\sum_c\theta_c\varphi_c` is replaced by an equivalent linear
one, :math:`c_e\dot r_e + k_e r_e`, with :math:`c_e = \sum_{c\in e}\theta_c\gamma_c` over
its velocity terms and :math:`k_e = \sum_{c\in e}\theta_c\gamma_c` over its displacement
terms; the slopes :math:`\gamma_c` are

- **at the record's response level** (:func:`response_slopes`): the least-squares
  equivalent linearisation over the record, :math:`\gamma_c = \overline{u\varphi_c(u)}
  /\overline{u^2}` with :math:`u` the element's relative displacement (displacement
  terms) or velocity (velocity terms) over the record (:math:`\overline{r^4}/
  \overline{r^2}` for :math:`r^3`, :math:`\overline{|\dot r|^3}/\overline{\dot r^2}` for
  :math:`\dot r|\dot r|`).  This is what a linear identification of the same record
  sees: on the nonlinear chain of ``analyses/oma_comparison.py`` the covariance-driven
  SSI's first frequency agreed with it to 0.2 %, while the Gaussian linearisation (the
  mean slope, :math:`3\overline{r^2}` for :math:`r^3`; eq (65)'s factors) was 6 % high
  at four times the force level: the response of a hardening spring is platykurtic;
- **at small amplitude** (:func:`small_slopes`): 1 for ``linear_damping`` and
  ``linear_stiffness``, 0 for the others, whose slope at rest is zero (Coulomb friction
  sticks and is left out), as in :mod:`hosid.model.linear_chain`.

For a linear system both are the system itself.  With :math:`M`, :math:`C = B^{\mathsf T}
\mathrm{diag}(c)B`, :math:`K = B^{\mathsf T}\mathrm{diag}(k)B` the modes are those of
:func:`hosid.model.linear_chain.modes` (eigenvalues :math:`\lambda = -\zeta\omega \pm
i\omega\sqrt{1-\zeta^2}` of the state matrix), computed for every retained posterior draw
(:func:`modal_draws`) and summarised like the parameters (:func:`summarize_modes`): the
frequency :math:`\omega/2\pi` (Hz) and the damping ratio :math:`\zeta` with their mean,
sd and 5/25/50/75/95 % quantiles, and the mean shape (the real part of each draw's shape,
scaled so that its largest entry is 1, averaged and scaled again).  Modes are matched
across draws by the order of their frequencies.

Without posterior draws (an estimate and its Laplace covariance, where no fit ran), the
modes of the estimate carry the delta method's sds and normal intervals
(:func:`estimate_modes`).
"""

from __future__ import annotations

import numpy as np

from .linear_chain import eigenmodes, state_matrix
from .system import System

__all__ = [
    "MAX_DRAWS",
    "estimate_modes",
    "modal_draws",
    "response_slopes",
    "small_slopes",
    "summarize_modes",
]

#: At most this many posterior draws (evenly spaced) enter the modal summary.
MAX_DRAWS = 4000
QUANTILES = (0.05, 0.25, 0.5, 0.75, 0.95)
LINEARISATION = {
    "response": "equivalent linear at the record's response level: each term's "
    "least-squares slope mean(u phi(u)) / mean(u^2) over the record",
    "small": "small amplitude: the linear terms alone",
}


def small_slopes(system: System) -> np.ndarray:
    r""":math:`\gamma_c` at rest, one per drift coefficient (module docstring)."""
    return np.array(
        [float(t.name in ("linear_damping", "linear_stiffness")) for _, t in system.columns]
    )


def response_slopes(system: System, r: np.ndarray, rd: np.ndarray) -> np.ndarray:
    r""":math:`\gamma_c` at the response level (module docstring) from every element's
    relative displacement ``r`` and velocity ``rd``, each ``(E, N)``, over the record.
    """
    out = np.zeros(len(system.columns))
    for c, (e, t) in enumerate(system.columns):
        if t.variable in ("x", "v"):
            u = r[e] if t.variable == "x" else rd[e]
            out[c] = float(np.mean(u * t.phi(u)) / np.mean(u * u))
    return out


def _thin(theta: np.ndarray) -> np.ndarray:
    flat = np.asarray(theta, dtype=float).reshape(-1, np.shape(theta)[-1])
    if flat.shape[0] > MAX_DRAWS:
        flat = flat[np.linspace(0, flat.shape[0] - 1, MAX_DRAWS).round().astype(int)]
    return flat


def _linear_modes(system: System, th: np.ndarray, slopes: np.ndarray):
    """:func:`hosid.model.linear_chain.eigenmodes` of draw ``th``'s equivalent linear system."""
    B = system.incidence
    elem = np.array([e for e, _ in system.columns], dtype=int)
    is_v = np.array([t.variable == "v" for _, t in system.columns])
    is_x = np.array([t.variable == "x" for _, t in system.columns])
    coef = th[: len(system.columns)] * slopes
    c = np.bincount(elem, weights=coef * is_v, minlength=len(system.elements))
    k = np.bincount(elem, weights=coef * is_x, minlength=len(system.elements))
    minv = 1.0 / system.mass_vector(th)
    return eigenmodes(state_matrix(minv, B.T @ (c[:, None] * B), B.T @ (k[:, None] * B)))


def modal_draws(system: System, theta, slopes) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    r"""``omega`` (rad/s) and ``zeta`` ``(D, n)`` and real shapes ``(D, n, n)`` (dof, mode)
    of the equivalent linear system of every draw of ``theta`` ``(..., p)`` (at most
    :data:`MAX_DRAWS`), with the slopes ``slopes`` (module docstring): the ``r``
    underdamped modes of the draws that have the most common number of them, the larger
    on a tie (an overdamped mode has no frequency; on the building of
    ``analyses/building.py`` one of five is, in every draw); the other draws are left out.
    """
    gamma = np.asarray(slopes, dtype=float)
    n = system.n
    got = [_linear_modes(system, th, gamma) for th in _thin(theta)]
    counts = np.bincount([m.omega.size for m in got], minlength=n + 1)
    r = int(np.flatnonzero(counts[1:] == counts[1:].max())[-1]) + 1 if counts[1:].any() else 0
    kept = [m for m in got if r and m.omega.size == r]
    if not kept:
        return np.zeros((0, n)), np.zeros((0, n)), np.zeros((0, n, n))
    return (np.array([m.omega for m in kept]), np.array([m.zeta for m in kept]),
            np.array([m.shapes.real for m in kept]))  # fmt: skip


def _stats(v: np.ndarray) -> dict[str, float]:
    q = np.quantile(v, QUANTILES)
    out = {"mean": float(np.mean(v)), "sd": float(np.std(v, ddof=1)) if v.size > 1 else 0.0}
    out.update({f"q{round(100 * p):02d}": float(x) for p, x in zip(QUANTILES, q, strict=True)})
    return out


def summarize_modes(system: System, theta, slopes) -> list[dict]:
    """The modes by increasing frequency (module docstring): ``frequency_hz`` and
    ``damping_ratio`` (each ``mean``, ``sd``, ``q05`` ... ``q95``), ``shape`` (one number
    per dof in the system's order, largest entry 1) and ``draws`` (how many draws entered:
    :func:`modal_draws`).
    """
    omega, zeta, shapes = modal_draws(system, theta, slopes)
    if omega.shape[0] == 0:
        return []
    out = []
    for j in range(omega.shape[1]):
        s = shapes[:, :, j].mean(axis=0)
        s = s / s[np.argmax(np.abs(s))]
        out.append({
            "frequency_hz": _stats(omega[:, j] / (2.0 * np.pi)),
            "damping_ratio": _stats(zeta[:, j]),
            "shape": s.round(12).tolist(),
            "draws": int(omega.shape[0]),
        })  # fmt: skip
    return out


#: The normal quantiles of :data:`QUANTILES` (the delta method's intervals).
_Z = {0.05: -1.6448536269514729, 0.25: -0.6744897501960817, 0.5: 0.0,
      0.75: 0.6744897501960817, 0.95: 1.6448536269514729}  # fmt: skip


def estimate_modes(system: System, theta, cov, slopes, *, step: float = 1e-6) -> list[dict]:
    r"""The underdamped modes of one estimate ``theta`` with its covariance ``cov`` (module
    docstring), as :func:`summarize_modes` gives them: each frequency and damping ratio
    with the delta method's sd, :math:`\sqrt{J\Sigma J^{\mathsf T}}` (:math:`J` by central
    differences on ``step`` of each parameter, or of a thousandth of the largest drift
    coefficient for one near zero), and normal quantiles; ``draws`` is 0.  An sd is NaN
    where a step changes the number of underdamped modes.
    """
    th = np.asarray(theta, dtype=float)
    gamma = np.asarray(slopes, dtype=float)
    m = _linear_modes(system, th, gamma)
    r = m.omega.size

    def values(t):
        got = _linear_modes(system, t, gamma)
        return np.r_[got.omega, got.zeta] if got.omega.size == r else np.full(2 * r, np.nan)

    mid = np.r_[m.omega / (2.0 * np.pi), m.zeta]
    floor = 1e-3 * np.max(np.abs(th[: system.n_drift]))
    h = step * np.maximum(np.abs(th), floor)
    J = np.stack([(values(th + e) - values(th - e)) / (2.0 * e.sum()) for e in np.diag(h)], 1)
    J[:r] /= 2.0 * np.pi
    sd = np.sqrt(np.einsum("ij,jk,ik->i", J, np.asarray(cov, dtype=float), J))
    out = []
    for j in range(r):
        s = m.shapes.real[:, j] / m.shapes.real[np.argmax(np.abs(m.shapes.real[:, j])), j]
        out.append({
            key: {"mean": float(mid[j + k * r]), "sd": float(sd[j + k * r]),
                  **{f"q{round(100 * p):02d}": float(mid[j + k * r] + z * sd[j + k * r])
                     for p, z in _Z.items()}}
            for k, key in enumerate(("frequency_hz", "damping_ratio"))
        } | {"shape": s.round(12).tolist(), "draws": 0})  # fmt: skip
    return out
