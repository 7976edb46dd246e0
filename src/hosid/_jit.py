"""Compiled kernels that import numba only when one of them first runs.

The simulators and the higher-order spectral components run loops compiled by numba, but
a default fit calls none of them, and numba's import takes about 0.15 s of every command
(a tenth of what ``hosid fit`` spends before it fits).  :func:`njit` marks a kernel as
``numba.njit`` would, leaving the plain Python function behind a placeholder; the first
call of any placeholder imports numba, compiles every marked kernel (with the options
each was marked with, ``cache=True`` included) and puts the compiled dispatchers into the
namespaces of the modules that hold the placeholders, under the same names, so that
kernels calling each other, and ``prange`` loops, compile as if marked directly.  A
placeholder called, or asked for an attribute (``py_func``, ``signatures``), after that
forwards to its dispatcher.

numba offers no lazy import of its own (``numba.njit`` needs numba imported); this module
is the few lines that defer it.
"""

from __future__ import annotations

import sys
import threading
from collections.abc import Callable
from typing import Any

__all__ = ["compile_all", "njit", "prange"]

_MARKED: list[_Kernel] = []
_LOCK = threading.Lock()
_DONE = False


class _Kernel:
    """A marked kernel: the Python function and its options until compiled."""

    def __init__(self, func: Callable | None, options: dict[str, Any], target=None) -> None:
        self.func = func
        self.options = options
        self.target = target  # what the placeholder becomes (set by compile_all)
        if func is not None:
            self.__name__ = func.__name__
            self.__qualname__ = func.__qualname__
            self.__module__ = func.__module__
            self.__doc__ = func.__doc__
            self.__wrapped__ = func

    def __call__(self, *args, **kwargs):
        if self.target is None:
            compile_all()
        return self.target(*args, **kwargs)

    def __getattr__(self, name: str):
        if name.startswith("__"):
            raise AttributeError(name)
        if self.target is None:
            compile_all()
        return getattr(self.target, name)

    def __repr__(self) -> str:
        state = "compiled" if self.target is not None else "not compiled yet"
        return f"<kernel {getattr(self, '__qualname__', 'prange')} ({state})>"


#: ``numba.prange`` in a kernel's loop (``for b in prange(n)``), before numba is imported.
prange = _Kernel(None, {})


def njit(*args, **options):
    """Mark a kernel for ``numba.njit(**options)`` at the first call of any kernel.

    Used as ``@njit`` or ``@njit(cache=True, parallel=True)``; returns a placeholder that
    calls the compiled kernel (module docstring).
    """
    if args and callable(args[0]) and not options:
        return njit()(args[0])

    def mark(func: Callable):
        with _LOCK:
            if not _DONE:
                kernel = _Kernel(func, options)
                _MARKED.append(kernel)
                return kernel
        # a module imported after the first kernel ran: compile it as numba.njit would
        import numba

        _rebind(func.__module__)
        return numba.njit(**options)(func)

    return mark


def compile_all() -> None:
    """Import numba and replace every placeholder by its compiled dispatcher (idempotent)."""
    global _DONE
    with _LOCK:
        if _DONE:
            return
        import numba

        prange.target = numba.prange
        for kernel in _MARKED:
            kernel.target = numba.njit(**kernel.options)(kernel.func)
        for module in {k.func.__module__ for k in _MARKED}:
            _rebind(module)
        _DONE = True


def _rebind(module: str) -> None:
    """In the namespace where the module's kernels look names up, the placeholders
    (its own kernels, those it imported, ``prange``) become what they stand for.
    """
    namespace = vars(sys.modules[module])
    for name, value in list(namespace.items()):
        if isinstance(value, _Kernel) and value.target is not None:
            namespace[name] = value.target
