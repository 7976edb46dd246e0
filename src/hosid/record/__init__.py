"""Measured records (:mod:`hosid.record.core`: one channel or several) and their files
(:mod:`hosid.record.files`); the checks across channels are
:mod:`hosid.record.channel_checks` (imported on use: it needs scipy).
"""

from .core import MEASURED, MIN_SAMPLES, RESERVED_NAMES, UNIFORM_RTOL, Record
from .files import read_record, read_truths, write_record

__all__ = [
    "MEASURED",
    "MIN_SAMPLES",
    "RESERVED_NAMES",
    "UNIFORM_RTOL",
    "Record",
    "read_record",
    "read_truths",
    "write_record",
]
