r"""emcee on a quasi-posterior: moves, walkers, stop rule, backend.

The target is :math:`\log\pi(\theta) + \ell(\theta)` (priors of
:class:`hosid.model.priors.PriorSet`, quasi-likelihood of :mod:`hosid.inference.gmm`),
sampled in coordinates :math:`u` where parameters of log-uniform or log-normal priors
(:math:`S_0`, :math:`\omega_c`, a system's unknown masses) are logarithms (the Jacobian
is included).  Walkers start in a small ball around the mode(s), inside every
constraint.  Moves: differential evolution (0.7),
its :math:`\gamma = 1` mode-jumping variant (0.1) and, where the posterior may be curved,
long or multimodal (``kde=True``: the paper's costs, custom components, no eq-65
constraint), emcee's KDE move (0.2), which proposes from a kernel density estimate of
the other half of the ensemble (otherwise its share goes to differential evolution).  On
a short record whose J4A posterior spans the whole prior of :math:`a_1` along the J2
valley, the snooker update in its place left R-hat at 1.015 after 20 000 steps; the KDE
move converged in 13 500 (autocorrelation time 110 steps); without
the eq-65 constraint a mirror move :math:`\theta_d \to -\theta_d` of the damping
coefficients (an involution with unit Jacobian, so the Metropolis ratio is the posterior
ratio) carries walkers between the twin modes of J2 and J4.

The run continues in chunks until, after a burn-in of three autocorrelation times, the
rank-normalized R-hat over walkers is below :data:`RHAT_STOP` and bulk and tail ESS
reach :data:`ESS_STOP` for every parameter (margins over the summary's 1.01 and 400),
or ``max_steps`` (:data:`MAX_STEPS`) is reached.  Every log-probability call returns the
per-component log-likelihoods and the log prior as blobs.
"""

from __future__ import annotations

import math
import signal
import threading
import warnings
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass

import emcee
import numpy as np

from ..errors import HosidInputError
from ..progress import Stages
from ..progress import bar as progress_bar

__all__ = ["ESS_STOP", "RHAT_STOP", "Chain", "diagnostics", "run"]

RHAT_STOP = 1.007
ESS_STOP = 500.0
CHUNK = 500
#: The stop rule's default limit (steps).  The five-storey building of
#: ``analyses/building.py`` (22 parameters, autocorrelation times 290-390 steps) still had
#: R-hat 1.02-1.03 after 35 000 steps: a larger limit would buy time, not convergence.
MAX_STEPS = 20000


@dataclass
class Chain:
    """Kept draws ``(walker, draw, p)`` in natural coordinates, blobs, diagnostics."""

    theta: np.ndarray
    lp: np.ndarray
    blobs: np.ndarray
    steps: int
    burn: int
    autocorr: np.ndarray
    acceptance: float
    diagnostics: dict  # worst R-hat, bulk and tail ESS of the kept draws


def diagnostics(u: np.ndarray) -> dict[str, float]:
    """The worst rank-normalized R-hat and bulk and tail ESS over the coordinates of
    ``u`` ``(walker, draw, p)`` (arviz).
    """
    import arviz_stats as az  # arviz's rhat and ess, without its plotting (pyplot)
    import xarray as xr

    if u.shape[1] < 4:
        return {"r_hat_max": math.inf, "ess_bulk_min": 0.0, "ess_tail_min": 0.0}
    post = xr.Dataset({f"u{i}": (("chain", "draw"), u[:, :, i]) for i in range(u.shape[2])})
    with warnings.catch_warnings(), np.errstate(invalid="ignore", divide="ignore"):
        warnings.simplefilter("ignore")
        rhat = az.rhat(post)
        bulk = az.ess(post, method="bulk")
        tail = az.ess(post, method="tail")
    r = [float(rhat[k]) for k in post.data_vars]
    b = [float(bulk[k]) for k in post.data_vars]
    t = [float(tail[k]) for k in post.data_vars]
    return {  # NaN (a constant coordinate) counts as failing
        "r_hat_max": max(v if math.isfinite(v) else math.inf for v in r),
        "ess_bulk_min": min(v if math.isfinite(v) else 0.0 for v in b),
        "ess_tail_min": min(v if math.isfinite(v) else 0.0 for v in t),
    }


def _diagnostics_pass(u: np.ndarray) -> bool:
    """R-hat and bulk/tail ESS of every coordinate within the margins."""
    if u.shape[1] < 50:
        return False
    d = diagnostics(u)
    return d["r_hat_max"] < RHAT_STOP and min(d["ess_bulk_min"], d["ess_tail_min"]) >= ESS_STOP


def _mirror(damping: Sequence[int]):
    idx = list(damping)

    def propose(coords: np.ndarray, random) -> tuple[np.ndarray, np.ndarray]:
        q = coords.copy()
        flip = random.rand(q.shape[0]) < 0.5
        for i in idx:
            q[flip, i] *= -1.0
        return q, np.zeros(q.shape[0])

    return propose


#: What a sampler whose walkers span fewer dimensions than the parameters says (emcee's
#: check of the start, or the KDE move's singular covariance).
COLLAPSED = (
    "sampling failed: the walkers span fewer dimensions than the parameters (a degenerate "
    "posterior: the record does not inform every parameter, or the estimate sits at a "
    "prior's edge); simplify the model or fix the uninformed parameters"
)


def run(
    log_prob: Callable[[np.ndarray], np.ndarray],
    *,
    modes: Sequence[np.ndarray],
    cov: np.ndarray,
    log_params: Sequence[int],
    n_blobs: int,
    rng: np.random.Generator,
    n_walkers: int = 32,
    n_steps: int | None = None,
    max_steps: int = MAX_STEPS,
    mirror: Sequence[int] = (),
    kde: bool = True,
    backend: emcee.backends.Backend | None = None,
    progress: bool | str = False,
) -> Chain:
    """Sample ``log_prob`` (natural coordinates, vectorized, returns ``(n, 1 + n_blobs)``:
    log posterior then blobs).

    Parameters
    ----------
    modes : sequence of arrays
        Where the walkers start (split evenly).
    cov : array
        Covariance of the start ball in natural coordinates (0.1 of it is used).
    log_params : sequence of int
        Parameters sampled in their logarithm.
    mirror : sequence of int
        Parameters the mirror move flips (empty: no mirror move).
    kde : bool
        Use the KDE move (curved, long or multimodal posteriors).
    backend : emcee backend, optional
        A chain to continue (``backend.iteration > 0``) or to fill; a
        :class:`hosid.inference.chains.ChainFile` is saved after every chunk of
        :data:`CHUNK` steps and when the run is interrupted (Ctrl-C).
    progress : bool, str or Stages
        tqdm progress bar (a string is its label; a command's
        :class:`~hosid.progress.Stages` shows the sampling as one of its stages).
    """
    p = len(modes[0])
    logs = np.zeros(p, dtype=bool)
    logs[list(log_params)] = True
    target = _Unconstrained(log_prob, logs)
    sampler = emcee.EnsembleSampler(
        n_walkers, p, target, moves=_moves(kde, mirror), vectorize=True, backend=backend
    )
    seed = np.random.MT19937(int(rng.integers(2**32)))
    sampler.random_state = np.random.RandomState(seed).get_state()
    state = None
    if sampler.iteration == 0:
        state = _start(target, modes, cov, logs, rng, n_walkers)
    total = int(n_steps) if n_steps is not None else None
    bar, own = _progress(progress, total, sampler.iteration)
    try:
        _chunks(sampler, state, n_steps, max_steps, backend, bar)
    except KeyboardInterrupt:
        if hasattr(backend, "save") and sampler.iteration > 0:
            backend.save()  # what was sampled is kept for the resume
        raise
    finally:
        if own:
            bar.close()
    return _chain(sampler, target.theta, n_walkers, n_blobs)


class _Unconstrained:
    r"""``log_prob`` in the sampler's coordinates :math:`u`: the parameters ``logs`` in
    their logarithm (:math:`\theta = e^u`, the Jacobian :math:`\sum u` added), a
    non-finite log posterior as :math:`-\infty`.
    """

    def __init__(self, log_prob: Callable[[np.ndarray], np.ndarray], logs: np.ndarray):
        self.log_prob, self.logs = log_prob, logs

    def theta(self, u) -> np.ndarray:
        """The natural coordinates of ``u``."""
        th = np.array(u, dtype=float, copy=True)
        th[..., self.logs] = np.exp(th[..., self.logs])
        return th

    def __call__(self, u) -> np.ndarray:
        u = np.atleast_2d(u)
        out = self.log_prob(self.theta(u))
        out[:, 0] = out[:, 0] + np.sum(u[:, self.logs], axis=1)  # Jacobian of exp
        out[:, 0] = np.where(np.isfinite(out[:, 0]), out[:, 0], -np.inf)
        return out


def _chain(sampler, to_theta, n_walkers: int, n_blobs: int) -> Chain:
    """The sampled chain after its burn-in, in natural coordinates (``to_theta``)."""
    done = sampler.iteration
    burn = _burn(sampler, done)
    u = np.swapaxes(sampler.get_chain(discard=burn), 0, 1)
    blobs = np.asarray(sampler.get_blobs(discard=burn), dtype=float).reshape(
        u.shape[1], n_walkers, n_blobs
    )
    return Chain(
        theta=to_theta(u),
        lp=np.swapaxes(sampler.get_log_prob(discard=burn), 0, 1),
        blobs=np.swapaxes(blobs, 0, 1),
        steps=done,
        burn=burn,
        autocorr=_taus(sampler, done),
        acceptance=float(np.mean(sampler.acceptance_fraction)),
        diagnostics=diagnostics(u),
    )


def _moves(kde: bool, mirror: Sequence[int]) -> list:
    """The ensemble's moves: differential evolution (and its mode-hopping ``gamma0 = 1``),
    the KDE move where ``kde``, the mirror move of the damping's sign where ``mirror``.
    """
    moves = [
        (emcee.moves.DEMove(), 0.7 if kde else 0.9),
        (emcee.moves.DEMove(gamma0=1.0), 0.1),
    ]
    if kde:
        moves.append((emcee.moves.KDEMove(), 0.2))
    if mirror:
        moves = [(m, 0.9 * w) for m, w in moves] + [(emcee.moves.MHMove(_mirror(mirror)), 0.1)]
    return moves


def _progress(progress, total: int | None, initial: int):
    """The sampling's bar and whether :func:`run` owns it (a command's stage is not)."""
    if isinstance(progress, Stages):
        return progress.stage("sampling", total=total, initial=initial, unit="step"), False
    if progress:
        label = progress if isinstance(progress, str) else "sampling"
        return progress_bar(label, total=total, initial=initial, unit="step"), True
    return None, False


def _chunks(sampler, state, n_steps, max_steps: int, backend, bar) -> None:
    """Advance ``sampler`` by chunks of :data:`CHUNK` steps from ``state`` (or where it
    stopped): ``n_steps`` in all, or until the chain passes its checks (50
    autocorrelation times after the burn-in and the diagnostics) or reaches
    ``max_steps``; a checkpoint of a file backend after every chunk.
    """

    def advance(start, steps):
        with _deferred_interrupt() as interrupted, _collapsed():
            for _ in sampler.sample(start, iterations=steps, store=True):
                if bar is not None:
                    bar.update()
                if interrupted:
                    raise KeyboardInterrupt  # between steps, outside emcee's wrapper

    while True:
        done = sampler.iteration
        if n_steps is not None:
            todo = min(CHUNK, int(n_steps) - done)
        else:
            todo = CHUNK if done < max_steps else 0
        if todo <= 0:
            return
        advance(state if state is not None else sampler.get_last_sample(), todo)
        state = None
        if hasattr(backend, "save"):
            backend.save()  # a checkpoint per chunk (hosid.inference.chains)
        if n_steps is None:
            done = sampler.iteration
            burn = _burn(sampler, done)
            if done - burn >= 50 * _tau_max(sampler, done) and _diagnostics_pass(
                np.swapaxes(sampler.get_chain(discard=burn), 0, 1)
            ):
                return


@contextmanager
def _collapsed() -> Iterator[None]:
    """Walkers on fewer dimensions than the parameters as :data:`COLLAPSED`, one line:
    emcee's check of the start (its condition number), the KDE move's singular covariance.
    """
    try:
        yield
    except (ValueError, np.linalg.LinAlgError) as exc:
        if not any(m in str(exc) for m in ("condition number", "lower-dimensional")):
            raise
        raise HosidInputError(COLLAPSED) from None


@contextmanager
def _deferred_interrupt() -> Iterator[list]:
    """Ctrl-C during sampling takes effect between two steps: emcee's wrapper of the
    log-probability prints a traceback for any exception raised inside it.  Yields a
    list that is non-empty once SIGINT arrived (main thread only; elsewhere a no-op).
    """
    flag: list = []
    if threading.current_thread() is not threading.main_thread():
        yield flag
        return
    previous = signal.signal(signal.SIGINT, lambda *_: flag.append(True))
    try:
        yield flag
    finally:
        signal.signal(signal.SIGINT, previous)


def _taus(sampler, done: int) -> np.ndarray:
    with warnings.catch_warnings(), np.errstate(invalid="ignore", divide="ignore"):
        warnings.simplefilter("ignore", RuntimeWarning)  # short runs, walkers that stuck
        tau = sampler.get_autocorr_time(tol=0, discard=done // 5)
    return np.where(np.isfinite(tau), tau, max(done / 10, 1.0))


def _tau_max(sampler, done: int) -> float:
    return float(np.max(_taus(sampler, done)))


def _burn(sampler, done: int) -> int:
    return min(math.ceil(3 * _tau_max(sampler, done)), done // 2)


def _nearest_psd(c: np.ndarray) -> np.ndarray:
    """``c`` symmetrized with its eigenvalues held at least 1e-12 of the largest (the
    Laplace covariance of a record the equations barely describe can be indefinite, and
    numpy's own check of a valid one fails when its entries span many decades: white
    noise forced through ``hosid fit --force`` raised a RuntimeWarning there).
    """
    w, V = np.linalg.eigh(0.5 * (c + c.T))
    w = np.maximum(w, 1e-12 * max(float(np.max(np.abs(w))), 1e-300))
    return (V * w) @ V.T


def _start(target, modes, cov, logs, rng, n_walkers) -> np.ndarray:
    """Walkers in a ball around the modes (split evenly), all with finite probability."""
    out = []
    for mode, idx in zip(modes, np.array_split(np.arange(n_walkers), len(modes)), strict=True):
        mode = np.asarray(mode, dtype=float)
        c = np.array(cov, dtype=float)
        # the ball in sampling coordinates: log-parameters scaled by their value
        scale = np.ones_like(mode)
        scale[logs] = 1.0 / np.abs(mode[logs])
        c = c * np.outer(scale, scale)
        c = _nearest_psd(c)
        u0 = mode.copy()
        u0[logs] = np.log(mode[logs])
        got = np.empty((0, mode.size))
        spread = 0.3
        for _ in range(60):
            draw = rng.multivariate_normal(u0, spread**2 * c, size=4 * idx.size,
                                           method="eigh", check_valid="ignore")  # fmt: skip
            ok = np.isfinite(target(draw)[:, 0])
            got = np.concatenate([got, draw[ok]])
            if got.shape[0] >= idx.size:
                break
            spread *= 0.6
        if got.shape[0] < idx.size:
            raise HosidInputError(
                "no admissible starting point near the estimate: it lies outside the priors "
                "or the constraints"
            )
        out.append(got[: idx.size])
    return np.concatenate(out)
