"""Exceptions raised by hosid, and the exit code the command line gives each."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

__all__ = ["EXIT_INPUT", "EXIT_INTERRUPTED", "EXIT_REJECTED", "HosidInputError", "RecordRejected"]

#: Exit code of bad input (a malformed record, an impossible setting, a busy folder).
EXIT_INPUT = 2
#: Exit code of a record that hosid cannot describe (:class:`RecordRejected`).
EXIT_REJECTED = 3
#: Exit code after Ctrl-C (128 + SIGINT).
EXIT_INTERRUPTED = 130


class HosidInputError(ValueError):
    """Bad user input: a malformed record, an impossible setting, a missing file.

    The command line turns it into one line ``hosid: error: <message>`` on
    stderr and exit code 2; library callers can catch it as a ``ValueError``.
    """


class RecordRejected(Exception):
    """The record fails a check that says hosid's model class cannot describe it (a
    constant, white noise, a pure tone, a random walk ...).

    The command line prints one line ``hosid: rejected: <message>`` and exits with code 3
    without writing a posterior (``--force`` fits anyway).  ``checks`` holds every check
    of the record (:class:`hosid.verdicts.Check`), failed or not.
    """

    def __init__(self, message: str, checks: Sequence[Any] = ()):
        super().__init__(message)
        self.checks = list(checks)
