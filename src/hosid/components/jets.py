r"""The generator identities of the augmented state: a force through a whitening filter.

When the force is white noise through a rational filter, :math:`g = Hw` with
:math:`1/H(s) = P(s) = \sum_{m=0}^Mp_ms^m` (:class:`hosid.model.excitation.Spectrum`),
the state :math:`(x, \dot x, g, \dots, g^{(M-1)})` is Markov and the exact
log-likelihood of the displacement path is the Gaussian one of the inferred force
:math:`g_\theta = \ddot x + \sum_l\theta_l\phi_l`, whitened by :math:`P`.  Its score in
a drift coefficient is the Itô integral :math:`-\frac{1}{2\pi S_0}\int(P\phi_j)(Pg)\,dt`
(:math:`Pg = w`), a martingale; with a test function :math:`\psi_j` in place of
:math:`\phi_j` it stays one, and in Stratonovich form (what a sampled record gives)

.. math:: \frac1{T_b}\int_b (P\psi_j)\circ(Pg)\,dt - \pi S_0\,\overline{\partial_{\dot x}
    \psi_j} = \sum_{m,n}p_mp_n\Big[C^{mn}_j + \sum_lQ^{mn}_{jl}\theta_l\Big]
    - \pi S_0\,e_j

has mean zero in every block :math:`b` and is uncorrelated between blocks, with
:math:`Q^{mn}_{jl} = \overline{\psi_j^{(m)}\phi_l^{(n)}}`, :math:`C^{mn}_j =
\overline{\psi_j^{(m)}\ddot x^{(n)}}` and :math:`e_j = \overline{\partial_{\dot x}\psi_j}`
(time derivatives :math:`^{(m)}` by the chain rule on the jet :math:`(x, \dot x, \ddot x,
\dddot x)`; the Itô correction :math:`\pi S_0e_j` comes from the top order, where
:math:`\psi^{(M)}` holds :math:`\partial_{\dot x}\psi\,y`, :math:`y = x^{(M+1)}`, whose
increments carry :math:`w/p_M`).  White noise is :math:`M = 0` (the identities of
:mod:`hosid.components.identities`).  :math:`\ddot x^{(M)}` is white-like: every term
that holds it is integrated by parts once (boundary terms at the block's ends), so the
block means hold the jet up to :math:`y` only; for a velocity test function the top term
is :math:`\int\psi^{(M)}\ddot x^{(M)} = [\psi^{(M)}y - \tfrac12\psi'y^2] - \int Ry +
\tfrac12\int\psi''\ddot x\,y^2` with :math:`R = \psi^{(M+1)} - \psi'\ddot x^{(M)}`.

Velocity test functions are smooth (:meth:`hosid.model.base.DriftTerm.smooth_test`):
their third derivative enters.  **Sampling.**  The block means are restored for what the
sampled jet lacks above the Nyquist frequency (:func:`hosid.state.jet_deficit`, the
model's shape at the pilot): each is evaluated on the jet shifted by
:math:`\pm\sqrt{3\lambda_i}u_i` along the eigenvectors of that covariance and combined
as :math:`\bar F + \tfrac12\sum_i\lambda_i\,\Delta_i^2\bar F/(3\lambda_i)`, the Gaussian
blur :math:`E[F(\cdot + z)]` exactly for a quartic along each direction.  Measured on
the paper oscillator (S0 = 100) and a ship-roll-like one under second-order filters
peaked below, at and above their resonance (8 records each, the drift known up to the
filter): the identities' estimates of the four drift coefficients had sd within 10-30 %
of the information limit of the augmented state and no bias beyond 2.4 standard errors.
"""

from __future__ import annotations

import math

import numpy as np

from ..model.model import Model
from ..state import RecordState

__all__ = ["EXTRA", "row_kinds", "time_derivatives", "whitened_statistics"]


def time_derivatives(f: list, kind: str, jet: dict, upto: int) -> list:
    r"""Time derivatives :math:`D_0..D_{upto}` (``upto`` at most 3) of :math:`f(u(t))` by
    the chain rule.

    ``f`` holds :math:`f` and its first three derivatives in the function's variable,
    ``kind`` is ``"v"`` (a function of the velocity), ``"x"`` or ``"1"`` (a constant),
    ``jet`` the arrays ``x, v, a, j``.  The third derivative of a velocity function
    leaves out :math:`f'\ddot x''`, which the jet does not hold (module docstring).
    """
    v, a, j = jet["v"], jet["a"], jet.get("j")
    if kind == "1":
        return [f[0]] + [np.zeros_like(jet["x"])] * upto
    if kind == "v":
        steps = (
            lambda: f[1] * a,
            lambda: (f[2] * a + 0.0) * a + f[1] * j,
            lambda: f[3] * a**3 + 3.0 * f[2] * a * j,
        )
    else:
        steps = (
            lambda: f[1] * v,
            lambda: f[2] * v * v + f[1] * a,
            lambda: f[3] * v**3 + 3.0 * f[2] * v * a + f[1] * j,
        )
    return [f[0]] + [steps[k]() for k in range(upto)]


#: Test functions beyond the drift terms' own: a displacement and a velocity moment of
#: higher order, as (kind, derivatives 0-3), in units of the variable's sd.  Without
#: them a second-order filter at twice the resonance of the paper oscillator had a
#: second solution, the filter and the oscillator swapped (a2 = 166 for 25, Hansen's J
#: 4-6 on 4 df against 1-2 at the truth, 3 records).
EXTRA = {
    "x^5": ("x", lambda u: (u**5, 5 * u**4, 20 * u**3, 60 * u**2)),
    "v^3": ("v", lambda u: (u**3, 3 * u**2, 6 * u, 6 + 0 * u)),
}


def row_kinds(model: Model, rows: list) -> list[str]:
    """The variable of each row: a drift term's index or a name of :data:`EXTRA`."""
    terms = model.drift_terms
    return [EXTRA[r][0] if isinstance(r, str) else terms[r].variable for r in rows]


def _functions(state: RecordState, model: Model, rows: list, eps: float):
    """Two functions of a jet: the rows' test-function derivatives (a drift term's index,
    or a name of :data:`EXTRA`) and every term's feature derivatives (orders 0-3).
    """
    sv, sx = state.scales.sigma_v, state.scales.sigma_x
    terms = model.drift_terms

    def arg(kind, jet):
        return jet["v"] if kind == "v" else jet["x"]

    def tests(jet):
        out = []
        for r in rows:
            if isinstance(r, str):
                kind, fn = EXTRA[r]
                sd = sv if kind == "v" else sx
                u = arg(kind, jet) / sd
                out.append([d * sd**-k for k, d in enumerate(fn(u))])
            elif terms[r].variable == "v":
                out.append([terms[r].smooth_test(jet["v"], k, sv) for k in range(4)])
            else:
                out.append([terms[r].phi(arg(terms[r].variable, jet), k, eps) for k in range(4)])
        return out

    def features(jet):
        return [[t.phi(arg(t.variable, jet), k, eps) for k in range(4)] for t in terms]

    return tests, features


def _block_means(M: int, kinds, rk, tests, features, jet: dict) -> dict:
    """The integrands' block means on one jet (module docstring): ``Q[(m, n)]``
    ``(B, J, p)``, ``C[(m, n)]`` ``(B, J)`` without the boundary terms, ``e`` ``(B, J)``.
    """
    psi, phi = tests(jet), features(jet)
    Dpsi = [time_derivatives(f, k, jet, M + 1) for f, k in zip(psi, rk, strict=True)]
    Dphi = [time_derivatives(f, k, jet, M) for f, k in zip(phi, kinds, strict=True)]
    acc = [jet["a"], jet["j"]]
    y = acc[M - 1]
    Mb = jet["x"].shape[1]
    # (order, B, rows, samples) @ (order, B, samples, columns): batched products
    P = np.stack([np.stack([dp[m] for dp in Dpsi], 1) for m in range(M + 1)])
    F = np.stack([np.stack([df[n] for df in Dphi], 2) for n in range(M + 1)])
    Q, C = {}, {}
    for m in range(M + 1):
        for n in range(M + 1):
            Q[m, n] = np.matmul(P[m], F[n]) / Mb
            cols = []
            for dp, f, kind in zip(Dpsi, psi, rk, strict=True):
                if n < M:
                    cols.append((dp[m] * acc[n]).mean(axis=1))
                elif m < M or kind != "v":
                    cols.append(-(dp[m + 1] * y).mean(axis=1))
                else:  # the top velocity term: R y and the y^2 term (module docstring)
                    R = dp[M + 1] - (f[1] * jet["j"] if M == 1 else 0.0)
                    cols.append((-R * y + 0.5 * f[2] * jet["a"] * y * y).mean(axis=1))
            C[m, n] = np.stack(cols, -1)
    zero = np.zeros(jet["x"].shape[0])
    e = np.stack(
        [f[1].mean(axis=1) if k == "v" else zero for f, k in zip(psi, rk, strict=True)], -1
    )
    return {"Q": Q, "C": C, "e": e}


def _boundary(M: int, rk, tests, state: RecordState) -> np.ndarray:
    r"""The by-parts boundary terms of :math:`C^{mM}` per block, ``(M + 1, B, J)``:
    :math:`[\psi^{(m)}y]/T_b` (less :math:`\tfrac12\psi'y^2` at the top of a velocity
    test function).
    """
    first, nxt = state.block_edges
    T = state.layout.T
    out = np.zeros((M + 1, first.size, len(rk)))
    for idx, sign in ((nxt, 1.0), (first, -1.0)):
        jet = {k: getattr(state, k)[idx][:, None] for k in ("x", "v", "a", "j")}
        y = jet["j"] if M == 2 else jet["a"]
        for a, (f, kind) in enumerate(zip(tests(jet), rk, strict=True)):
            D = time_derivatives(f, kind, jet, M)
            for m in range(M + 1):
                val = D[m] * y
                if m == M and kind == "v":
                    val = val - 0.5 * f[1] * y * y
                out[m, :, a] += sign * val[:, 0] / T
    return out


def whitened_statistics(
    state: RecordState, model: Model, rows: list[int], deficit: np.ndarray
) -> dict:
    r"""The per-block statistics of the identities of the augmented state (module
    docstring) for the test functions ``rows`` (drift terms' indices and names of
    :data:`EXTRA`): ``Q[(m, n)]`` ``(B, J, p)``, ``C[(m, n)]``
    ``(B, J)``, ``e`` ``(B, J)``, restored for the jet's ``deficit`` (the covariance of
    what the sampled ``x, v, a, j`` lack, :func:`hosid.state.jet_deficit`, of shape
    ``(M + 2, M + 2)`` for a whitening filter of order ``M``).

    Raises
    ------
    ValueError
        If the state has no jerk or the whitening order is not 1 or 2.
    """
    M = deficit.shape[0] - 2
    if M not in (1, 2):
        raise ValueError(f"whitening filters of order 1 or 2 are supported, not {M}")
    if state.j is None:
        raise ValueError("the identities of a coloured force need a smooth state (its jerk)")
    eps = max(math.sqrt(max(deficit[1, 1], 0.0)), 0.05 * state.scales.sigma_v)
    tests, features = _functions(state, model, rows, eps)
    kinds = [t.variable for t in model.drift_terms]
    rk = row_kinds(model, rows)
    base = state.blocks
    keys = ("x", "v", "a", "j")[: M + 2]

    def flat(got):
        out = {("e", None): got["e"]}
        out.update({(p, k): got[p][k] for p in ("Q", "C") for k in got[p]})
        return out

    plain = flat(_block_means(M, kinds, rk, tests, features, base))
    restored = dict(plain)
    # eigen-directions in units of each variable's sd (the entries span 15 decades when
    # the filter lies far above the Nyquist frequency)
    size = np.array([max(float(np.std(base[key])), 1e-300) for key in keys])
    lam, U = np.linalg.eigh(deficit / np.outer(size, size))
    for li, ui in zip(lam, U.T, strict=True):
        if abs(li) <= 1e-5:  # a loss below 1e-5 of the variables' variances
            continue
        h = math.sqrt(3.0 * abs(li))
        sides = []
        for sgn in (1.0, -1.0):
            jet = dict(base)
            for k, key in enumerate(keys):
                jet[key] = base[key] + sgn * h * ui[k] * size[k]
            sides.append(flat(_block_means(M, kinds, rk, tests, features, jet)))
        for key, value in plain.items():
            d2 = sides[0][key] + sides[1][key] - 2.0 * value
            restored[key] = restored[key] + 0.5 * li * d2 / h**2
    bnd = _boundary(M, rk, tests, state)
    pairs = [(m, n) for m in range(M + 1) for n in range(M + 1)]
    Q = {k: restored["Q", k] for k in pairs}
    C = {k: restored["C", k] + (bnd[k[0]] if k[1] == M else 0.0) for k in pairs}
    return {"Q": Q, "C": C, "e": restored["e", None]}
