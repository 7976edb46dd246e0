"""Exceptions raised by hosid."""


class HosidInputError(ValueError):
    """Bad user input: a malformed record, an impossible setting, a missing file.

    The command line turns it into one line ``hosid: error: <message>`` on
    stderr and exit code 2; library callers can catch it as a ``ValueError``.
    """
