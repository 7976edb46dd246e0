"""Measured records (:mod:`hosid.record.core`) and their files
(:mod:`hosid.record.files`).
"""

from .core import MIN_SAMPLES, UNIFORM_RTOL, Record
from .files import read_record, read_truths, write_record

__all__ = ["MIN_SAMPLES", "UNIFORM_RTOL", "Record", "read_record", "read_truths", "write_record"]
