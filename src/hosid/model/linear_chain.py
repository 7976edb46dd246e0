r"""The linear part of a system: its matrices, modes and stationary covariance.

At small amplitude only the linear terms of the elements act (``linear_damping``
:math:`a_1\dot r`, ``linear_stiffness`` :math:`a_2r`; the other features of the library,
:math:`\dot r|\dot r|`, :math:`r^2`, :math:`r^3`, have zero slope at :math:`r = 0`), and
the system of :mod:`hosid.model.system` is

.. math:: M\ddot q + C\dot q + Kq = F, \qquad
    C = B^{\mathsf T}\mathrm{diag}(a_{1,e})B, \quad K = B^{\mathsf T}\mathrm{diag}(a_{2,e})B,
    \quad M = \mathrm{diag}(m),

with :math:`B` the incidence of the elements (:attr:`System.incidence`).  Coulomb
friction has no small-amplitude slope (it sticks) and is left out, as is the shift of the
equilibrium by a constant force (``excitation_mean``) or a quadratic stiffness: this is
the linearisation at :math:`q = 0`.  In the state :math:`s = (q, \dot q)`,

.. math:: ds = As\,dt + dW, \quad A = \begin{pmatrix}0 & I\\ -M^{-1}K & -M^{-1}C
    \end{pmatrix}, \quad E[dW\,dW^{\mathsf T}] = Q\,dt, \quad
    Q = \begin{pmatrix}0 & 0\\ 0 & M^{-1}\mathrm{diag}(2\pi S_{0,d})M^{-1}\end{pmatrix},

(:math:`S_{0,d} = 0` off the driven dofs).  The eigenvalues of :math:`A` come in pairs
:math:`\lambda = -\zeta\omega \pm i\omega\sqrt{1 - \zeta^2}` for every underdamped mode:
natural frequency :math:`\omega = |\lambda|` (rad/s), damping ratio :math:`\zeta =
-\mathrm{Re}\,\lambda/|\lambda|`, mode shape the displacement half of the eigenvector
(:func:`modes`).  The stationary covariance :math:`P = E[ss^{\mathsf T}]` solves the
Lyapunov equation :math:`AP + PA^{\mathsf T} + Q = 0` (:func:`stationary_covariance`);
for the single oscillator :math:`P = \mathrm{diag}(\pi S_0/(a_1a_2), \pi S_0/a_1)`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import linalg

from ..errors import HosidInputError
from .system import System

__all__ = [
    "Modes",
    "eigenmodes",
    "linearize",
    "modes",
    "state_matrices",
    "state_matrix",
    "stationary_covariance",
]


def linearize(system: System, theta=None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    r"""The mass, damping and stiffness matrices :math:`M, C, K`, each ``(n, n)``, of the
    linear terms at ``theta`` (a vector ``(p,)`` or a mapping; default the system's
    values) (module docstring).
    """
    th = system.vector(theta)
    if th.ndim != 1:
        raise HosidInputError("linearize takes one parameter vector")
    c = np.zeros(len(system.elements))
    k = np.zeros(len(system.elements))
    for col, (e, term) in enumerate(system.columns):
        if term.name == "linear_damping":
            c[e] += th[col]
        elif term.name == "linear_stiffness":
            k[e] += th[col]
    B = system.incidence
    return np.diag(system.mass_vector(th)), B.T @ (c[:, None] * B), B.T @ (k[:, None] * B)


def state_matrix(minv: np.ndarray, C: np.ndarray, K: np.ndarray) -> np.ndarray:
    r"""The state matrix :math:`A`, ``(2n, 2n)``, of :math:`M^{-1}` (its diagonal
    ``minv``), :math:`C` and :math:`K` (module docstring).
    """
    n = minv.size
    A = np.zeros((2 * n, 2 * n))
    A[:n, n:] = np.eye(n)
    A[n:, :n] = -minv[:, None] * K
    A[n:, n:] = -minv[:, None] * C
    return A


def state_matrices(system: System, theta=None) -> tuple[np.ndarray, np.ndarray]:
    r"""The linearised state matrix :math:`A` and the noise's covariance per unit time
    :math:`Q`, each ``(2n, 2n)``, state :math:`(q, \dot q)` (module docstring).
    """
    M, C, K = linearize(system, theta)
    minv = 1.0 / np.diag(M)
    A = state_matrix(minv, C, K)
    n = system.n
    Q = np.zeros_like(A)
    Q[n:, n:] = np.diag(2.0 * np.pi * system.levels(system.vector(theta)) * minv**2)
    return A, Q


def stationary_covariance(system: System, theta=None) -> np.ndarray:
    r""":math:`P = E[ss^{\mathsf T}]`, ``(2n, 2n)``, of the linearised system's stationary
    response, :math:`s = (q, \dot q)`: :math:`AP + PA^{\mathsf T} + Q = 0`.

    Raises
    ------
    HosidInputError
        If the linear part is not asymptotically stable (no stationary state).
    """
    A, Q = state_matrices(system, theta)
    if not np.all(np.linalg.eigvals(A).real < 0):
        raise HosidInputError(
            "the linear part has no stationary state (a mode without linear damping or stiffness)"
        )
    P = linalg.solve_continuous_lyapunov(A, -Q)
    return 0.5 * (P + P.T)


@dataclass(frozen=True)
class Modes:
    """The underdamped modes, by increasing natural frequency: ``omega`` (rad/s),
    ``zeta``, ``shapes`` (``(n, n_modes)`` complex, the largest component of each 1),
    and every eigenvalue of the state matrix (``eigenvalues``, by modulus).
    """

    omega: np.ndarray
    zeta: np.ndarray
    shapes: np.ndarray
    eigenvalues: np.ndarray

    @property
    def frequency_hz(self) -> np.ndarray:
        r"""Natural frequencies :math:`\omega/2\pi` (Hz)."""
        return self.omega / (2.0 * np.pi)


def modes(system: System, theta=None) -> Modes:
    r"""Natural frequencies, damping ratios and mode shapes of the linear part
    (``scipy.linalg.eig`` of :math:`A`; module docstring).  An overdamped mode (two real
    eigenvalues) has no frequency and is left out of ``omega`` (its eigenvalues stay in
    ``eigenvalues``).
    """
    return eigenmodes(state_matrices(system, theta)[0])


def eigenmodes(A: np.ndarray) -> Modes:
    r"""The underdamped modes of the state matrix ``A`` (``(2n, 2n)``, state :math:`(q,
    \dot q)`): :class:`Modes` by increasing frequency (:func:`modes`).
    """
    n = A.shape[0] // 2
    lam, vec = linalg.eig(A)
    order = np.argsort(np.abs(lam), kind="stable")
    lam, vec = lam[order], vec[:, order]
    keep = lam.imag > 1e-12 * np.maximum(np.abs(lam), 1e-300)
    shapes = vec[:n, keep]
    big = shapes[np.argmax(np.abs(shapes), axis=0), np.arange(shapes.shape[1])]
    omega = np.abs(lam[keep])
    return Modes(omega, -lam[keep].real / omega, shapes / big, lam)
