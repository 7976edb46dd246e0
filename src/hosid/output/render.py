"""A report's figures drawn in two other processes while the command fits.

A fit keeps one core busy (emcee moves one ensemble at a time) and its figures cost a
third of it, half of that in the corner plot alone.  :class:`FigureProcesses` forks a
process when a command starts (``hosid fit``, ``demo``, ``report``): it imports
matplotlib and corner and draws small throwaway figures (fonts, mathtext, tickers) on the
other core while the command fits the record, then waits for the fit.  Handed the
fit (:meth:`~FigureProcesses.send`), it forks a second process that inherits it, and the
two draw their shares (:data:`SHARES`: the corner plot; the other figures) while the
command writes ``posterior.nc`` and the summary; :meth:`~FigureProcesses.images`
collects the PNG bytes.  The figures are those :func:`hosid.output.report.draw` makes in
the command's own process, by the same code; the processes write no file: the command
writes every file into its staging folder as before (:mod:`hosid.output.files`).

The processes pay off when a core is idle: on a machine that other jobs keep busy they
only compete with the fit.  So the figures are drawn beside the fit when the 1-minute
load average is below the number of cores, after it (in the command's process)
otherwise; ``HOSID_FIGURE_PROCESSES=1`` always forks, ``=0`` never.  Outside Linux, where
``os.fork`` is not safe to use, nothing is forked.

Failures: an exception in a figure process comes back as itself when it is a
:class:`~hosid.errors.HosidInputError`, otherwise as a :class:`FigureError` naming it
(the command line prints one line and exits 1); a process that ends without an answer,
or does not answer within :data:`TIMEOUT` seconds, is a :class:`FigureError` too.  The
processes run in a process group of their own (Ctrl-C reaches the command alone) and
are killed when the command leaves the ``with`` block on an error or Ctrl-C.
"""

from __future__ import annotations

import gc
import os
import pickle
import selectors
import signal
import sys
import time
import warnings
from collections.abc import Callable, Mapping
from typing import Any

from ..errors import HosidInputError

__all__ = ["SHARES", "TIMEOUT", "FigureError", "FigureProcesses", "corner_size", "enabled"]

#: The figures of each process, by stem: the corner plot takes about as long as the rest.
SHARES = (
    ("corner",),
    ("likelihood_map", "restoring_force", "trace", "spectrum", "force_spectrum", "mode_shapes"),
)
#: Seconds the command waits for the figures once it has handed over the fit.
TIMEOUT = 300.0

_CHUNK = 1 << 20


class FigureError(Exception):
    """A figure process failed, ended without an answer, or did not answer in time."""


def enabled() -> bool:
    """Whether figures are drawn in forked processes (module docstring): on Linux, when
    ``HOSID_FIGURE_PROCESSES`` is ``1``, or unset and a core is free (the 1-minute load
    average below the number of cores); never when it is ``0``.
    """
    setting = os.environ.get("HOSID_FIGURE_PROCESSES", "")
    if setting == "0" or not (sys.platform.startswith("linux") and hasattr(os, "fork")):
        return False
    cores = os.cpu_count() or 1
    return setting == "1" or (cores > 1 and os.getloadavg()[0] < cores)


def corner_size(structure: Any) -> int:
    """The number of variables in the corner plot of a fit of ``structure`` (a model or
    a system, :func:`hosid.inference.structure.resolve`) when the fit adds no excitation
    terms: its parameters, and ``a1eq`` for a single oscillator with more damping than
    ``a1`` (:func:`hosid.output.plots.corner_plot`).
    """
    from ..model.model import Model

    names = list(structure.param_names)
    if isinstance(structure, Model):
        from ..inference.structure import derived_names

        names += derived_names(structure)
    return len(names)


def _fork() -> int:
    """``os.fork()``; the child's garbage collector leaves the parent's objects alone.

    Without :func:`gc.freeze` the child's first collections would touch every object it
    inherited and copy the pages holding them (a third of a second of page faults in each
    figure process); the parent's objects are unfrozen again as soon as it has forked.
    """
    gc.freeze()
    try:
        # Python 3.12 warns about fork() in a process with threads: here BLAS's idle
        # workers and a progress bar's monitor, which the child does not use
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", DeprecationWarning)
            pid = os.fork()
    except BaseException:
        gc.unfreeze()
        raise
    if pid != 0:
        gc.unfreeze()
    return pid


def _write(fd: int, data: bytes, deadline: float | None = None) -> None:
    """Write all of ``data`` to the pipe ``fd``, within ``deadline`` (monotonic) if given."""
    view = memoryview(data)
    if deadline is None:
        while view:
            view = view[os.write(fd, view[:_CHUNK]) :]
        return
    os.set_blocking(fd, False)
    with selectors.DefaultSelector() as sel:
        sel.register(fd, selectors.EVENT_WRITE)
        while view:
            if not sel.select(max(deadline - time.monotonic(), 0.0)):
                raise FigureError(f"the figures were not drawn within {TIMEOUT:g} s")
            try:
                view = view[os.write(fd, view[:_CHUNK]) :]
            except BlockingIOError:
                continue


def _read(fds: tuple[int, ...], deadline: float | None = None) -> list[bytes]:
    """Everything written to the pipes ``fds`` until each is closed, in that order."""
    data = {fd: bytearray() for fd in fds}
    with selectors.DefaultSelector() as sel:
        for fd in fds:
            sel.register(fd, selectors.EVENT_READ)
        while sel.get_map():
            wait = None if deadline is None else max(deadline - time.monotonic(), 0.0)
            ready = sel.select(wait)
            if not ready:
                raise FigureError(f"the figures were not drawn within {TIMEOUT:g} s")
            for key, _ in ready:
                chunk = os.read(key.fd, _CHUNK)
                if chunk:
                    data[key.fd] += chunk
                else:
                    sel.unregister(key.fd)
    return [bytes(data[fd]) for fd in fds]


def _answer(fd: int, work) -> None:
    """Send ``("ok", work())`` or ``("error", the exception)`` through ``fd``."""
    try:
        message: tuple = ("ok", work())
    except BaseException as exc:  # everything goes back to the command
        message = ("error", f"{type(exc).__name__}: {exc}", exc)
    try:
        data = pickle.dumps(message, protocol=pickle.HIGHEST_PROTOCOL)
    except Exception:  # an exception that does not pickle: its text only
        data = pickle.dumps(message[:2], protocol=pickle.HIGHEST_PROTOCOL)
    _write(fd, data)
    os.close(fd)


def _warm_up() -> None:
    """Import what drawing needs and draw two small figures of the same kinds (a corner
    plot; a log axis with a band and a legend) at a low resolution: fonts, mathtext,
    tickers and contours are ready when the fit arrives.
    """
    import numpy as np
    import xarray as xr
    from matplotlib.figure import Figure

    from . import plots, spectrum_plots  # noqa: F401  (matplotlib, corner)
    from .files import png

    draws = np.random.default_rng(0).standard_normal((2, 2, 250))
    post = xr.Dataset({"a1": (("chain", "draw"), draws[0]), "S0": (("chain", "draw"), draws[1])})
    tiny = xr.DataTree.from_dict({"posterior": post})
    tiny.attrs["truths_json"] = '{"a1": 0.1, "S0": -0.1}'
    png(plots.corner_plot(tiny), 20)
    fig = Figure(figsize=(2.0, 1.5), layout="constrained")
    ax = fig.add_subplot()
    ax.plot([1.0, 2.0], [1.0, 10.0], label="x")
    ax.fill_between([1.0, 2.0], [0.5, 5.0], [2.0, 20.0], alpha=0.3, linewidth=0)
    ax.set_yscale("log")
    ax.set_xlabel(r"$\omega$ (rad/s)")
    ax.legend(fontsize=7)
    png(fig, 20)


def _child(tree_fd: int, answers: tuple[int, int], dpi: int, corner: int | None) -> None:
    """The first figure process: warm up, make the corner plot's axes for ``corner``
    variables, wait for the fit, fork the second, draw.
    """
    from .report import STEMS, draw

    first, second = answers
    try:
        _warm_up()
        if corner:
            from .plots import prepare_corner

            prepare_corner(corner)
    except Exception:
        pass  # drawing fails the same way and says why
    data = _read((tree_fd,))[0]
    os.close(tree_fd)
    if not data:  # the command ended without a fit
        return
    tree = pickle.loads(data)
    del data
    try:
        pid = _fork()
    except OSError:  # no second process: this one draws every figure
        _answer(second, dict)
        _answer(first, lambda: draw(tree, STEMS, dpi=dpi))
        return
    if pid == 0:
        os.close(first)
        _answer(second, lambda: draw(tree, SHARES[1], dpi=dpi))
        os._exit(0)
    os.close(second)
    _answer(first, lambda: draw(tree, SHARES[0], dpi=dpi))
    os.waitpid(pid, 0)


class FigureProcesses:
    """Draw a report's figures in two forked processes (module docstring).

    ::

        with FigureProcesses() as figures:   # forks before the fit
            tree = fit(record)
            figures.send(tree)
            ...                               # posterior.nc, the summary
            images = figures.images()         # {stem: PNG bytes}

    (:meth:`handed` sends the fit and returns :meth:`images`, or ``None`` when nothing
    was forked.)

    Parameters
    ----------
    dpi : int
        Resolution of the PNG figures.
    corner : int, optional
        The number of variables the corner plot will likely show
        (:func:`corner_size`): its axes are made while the command
        fits.
    """

    def __init__(self, *, dpi: int = 100, corner: int | None = None) -> None:
        self.dpi = dpi
        self.corner = corner
        self._pid: int | None = None
        self._tree_fd: int | None = None
        self._answer_fds: tuple[int, ...] = ()
        self._sent = False
        self._done = False

    def __enter__(self) -> FigureProcesses:
        if not enabled():
            return self
        tree_r, tree_w = os.pipe()
        first_r, first_w = os.pipe()
        second_r, second_w = os.pipe()
        try:
            pid = _fork()
        except OSError:
            for fd in (tree_r, tree_w, first_r, first_w, second_r, second_w):
                os.close(fd)
            return self
        if pid == 0:  # the figure process: never returns into the command
            code = 0
            try:
                os.setpgid(0, 0)  # Ctrl-C at the terminal reaches the command alone
                for fd in (tree_w, first_r, second_r):
                    os.close(fd)
                _child(tree_r, (first_w, second_w), self.dpi, self.corner)
            except BaseException:
                code = 1
            finally:
                os._exit(code)
        for fd in (tree_r, first_w, second_w):
            os.close(fd)
        try:  # also here, so that it holds before the child gets to it
            os.setpgid(pid, pid)
        except OSError:
            pass
        self._pid, self._tree_fd, self._answer_fds = pid, tree_w, (first_r, second_r)
        return self

    @property
    def running(self) -> bool:
        """Whether figure processes were started (else the caller draws the figures)."""
        return self._pid is not None

    def handed(self, tree: Any) -> Callable[[], Mapping[str, bytes]] | None:
        """:meth:`send` the fit when the processes run; returns what
        :func:`hosid.output.report.write_report` takes as ``images``: :meth:`images`, or
        ``None`` (no process: the report draws its figures itself).
        """
        if self._pid is None:
            return None
        self.send(tree)
        return self.images

    def send(self, tree: Any) -> None:
        """Hand the fit (an arviz ``DataTree``) to the figure processes."""
        if self._pid is None or self._sent:
            raise RuntimeError("no figure process is waiting for a fit")
        self._sent = True
        fd, self._tree_fd = self._tree_fd, None
        try:
            data = pickle.dumps(tree, protocol=pickle.HIGHEST_PROTOCOL)
            _write(fd, data, time.monotonic() + TIMEOUT)
        except BrokenPipeError:
            pass  # the process is gone: images() says why
        finally:
            os.close(fd)

    def images(self) -> Mapping[str, bytes]:
        """The figures' PNG bytes by stem, once both processes have drawn them.

        Raises
        ------
        HosidInputError
            As raised by the figure code.
        FigureError
            On any other failure of a figure process, or none within :data:`TIMEOUT`.
        """
        if not self._sent:
            raise RuntimeError("send() the fit first")
        fds, self._answer_fds = self._answer_fds, ()
        try:
            answers = _read(fds, time.monotonic() + TIMEOUT)
        finally:
            for fd in fds:
                os.close(fd)
        out: dict[str, bytes] = {}
        missing = False
        for data in answers:
            try:
                message = pickle.loads(data) if data else None
            except Exception:  # cut short: the process died as it answered
                message = None
            if message is None:
                missing = True
            elif message[0] == "error":
                exc = message[2] if len(message) > 2 else None
                if isinstance(exc, HosidInputError):
                    raise exc
                raise FigureError(f"drawing the report's figures failed: {message[1]}")
            else:
                out.update(message[1])
        if missing:
            raise FigureError("a figure process ended without drawing its figures")
        self._done = True
        return out

    def __exit__(self, *exc_info) -> None:
        if self._pid is None:
            return
        pid, self._pid = self._pid, None
        for fd in (self._tree_fd, *self._answer_fds):
            if fd is not None:
                os.close(fd)
        self._tree_fd, self._answer_fds = None, ()
        if not self._done:  # an error, Ctrl-C or no fit: stop drawing
            try:
                os.killpg(pid, signal.SIGKILL)
            except OSError:
                try:
                    os.kill(pid, signal.SIGKILL)
                except OSError:
                    pass
        os.waitpid(pid, 0)
