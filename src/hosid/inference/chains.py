r"""Chains that survive an interruption: an emcee backend checkpointed to HDF5.

:class:`ChainFile` keeps the chain in memory while emcee runs (emcee's own
``HDFBackend`` opens the file at every step, which costs about as much as the sampling
itself here) and writes it to its file in emcee's HDF5 layout at every checkpoint (each
chunk of the stop rule, and when the run is interrupted): to a temporary name first, then
renamed, so the file always holds a complete chain.  ``emcee.backends.HDFBackend(path)``
reads it.

The file remembers what it was run on, a *signature* (the record's hash, the model, the
components and the settings that shape the posterior), and refuses to resume on anything
else: resuming a chain of another record would silently mix two posteriors.
"""

from __future__ import annotations

import json
import os
import secrets
from pathlib import Path

import emcee
import numpy as np

from ..errors import HosidInputError

__all__ = ["ChainFile"]

_GROUP = "mcmc"
_SIGNATURE = "hosid_signature"


class ChainFile(emcee.backends.Backend):
    """An in-memory emcee backend stored in ``path`` at :meth:`save` (module docstring).

    Parameters
    ----------
    path : str or Path
        The HDF5 file (``.h5`` / ``.hdf5``); an existing chain in it is resumed.
    signature : dict
        What the chain is a posterior of (JSON-serializable).
    n_walkers, ndim : int
        The ensemble's shape.

    Raises
    ------
    HosidInputError
        If the file is not a chain, holds a chain of another record or other settings or
        of another shape, or cannot be written.
    """

    def __init__(self, path: str | Path, signature: dict, n_walkers: int, ndim: int):
        super().__init__()
        self.path = Path(path)
        self.signature = json.dumps(signature, sort_keys=True)
        self.reset(n_walkers, ndim)
        if self.path.exists() and self.path.stat().st_size > 0:
            self._load()
        else:
            self._probe()

    def _probe(self) -> None:
        """Fail now, not after the sampling, when the file cannot be written."""
        if self.path.is_dir():
            raise HosidInputError(f"{self.path}: is a directory, not a chain file")
        parent = self.path.parent
        if not parent.is_dir():
            raise HosidInputError(f"cannot store the chain in {self.path}: no folder {parent}")
        if not os.access(parent, os.W_OK):
            raise HosidInputError(f"cannot store the chain in {self.path}: {parent} is read-only")

    def _load(self) -> None:
        import h5py

        try:
            with h5py.File(self.path, "r") as f:
                g = f[_GROUP]
                stored = g.attrs.get(_SIGNATURE)
                shape = (int(g.attrs["nwalkers"]), int(g.attrs["ndim"]))
                it = int(g.attrs["iteration"])
                chain = g["chain"][:it]
                log_prob = g["log_prob"][:it]
                accepted = np.asarray(g["accepted"][...], dtype=float)
                blobs = g["blobs"][:it] if g.attrs["has_blobs"] and it else None
                state = [v for k, v in sorted(g.attrs.items()) if k.startswith("random_state_")]
        except (OSError, KeyError, ValueError) as exc:
            reason = str(exc).split("(")[0].strip() or type(exc).__name__
            raise HosidInputError(f"{self.path}: not a hosid chain file ({reason})") from None
        if isinstance(stored, bytes):
            stored = stored.decode()
        if stored != self.signature:
            raise HosidInputError(
                f"{self.path} holds a chain of another record or other settings"
                f"{_difference(stored, self.signature)}; remove it or choose another --backend"
            )
        if shape != (self.nwalkers, self.ndim):
            raise HosidInputError(f"{self.path} holds {shape[0]} walkers x {shape[1]} params")
        self.iteration = it
        self.chain = np.asarray(chain, dtype=float)
        self.log_prob = np.asarray(log_prob, dtype=float)
        self.accepted = accepted
        self.blobs = None if blobs is None else np.asarray(blobs, dtype=float)
        self.random_state = tuple(state) if state else None

    def save(self) -> Path:
        """Write the chain so far to :attr:`path` (atomically, emcee's layout)."""
        import h5py

        it = self.iteration
        tmp = self.path.with_name(f".{self.path.name}.{secrets.token_hex(4)}.tmp")
        try:
            with h5py.File(tmp, "w") as f:
                g = f.create_group(_GROUP)
                g.attrs["version"] = emcee.__version__
                g.attrs["nwalkers"] = self.nwalkers
                g.attrs["ndim"] = self.ndim
                g.attrs["iteration"] = it
                g.attrs[_SIGNATURE] = self.signature
                g.create_dataset("accepted", data=self.accepted)
                shape = (self.nwalkers, self.ndim)
                g.create_dataset("chain", data=self.chain[:it], maxshape=(None, *shape))
                g.create_dataset(
                    "log_prob", data=self.log_prob[:it], maxshape=(None, self.nwalkers)
                )
                g.attrs["has_blobs"] = self.blobs is not None
                if self.blobs is not None:
                    b = self.blobs[:it]
                    g.create_dataset("blobs", data=b, maxshape=(None, *b.shape[1:]))
                for i, v in enumerate(self.random_state or ()):
                    g.attrs[f"random_state_{i}"] = v
            os.replace(tmp, self.path)
        except OSError as exc:
            tmp.unlink(missing_ok=True)
            raise HosidInputError(
                f"cannot store the chain in {self.path}: {exc.strerror or exc}"
            ) from None
        return self.path


def _difference(stored, current: str) -> str:
    """`` (record: 'a1b2' there, 'c3d4' here)``: what differs between two signatures."""
    try:
        old, new = json.loads(stored), json.loads(current)
    except (TypeError, ValueError):
        return ""
    if not isinstance(old, dict):
        return ""
    keys = [k for k in sorted(set(old) | set(new)) if old.get(k) != new.get(k)]
    keys.sort(key=lambda k: k != "record")  # the record first
    parts = [f"{k}: {old.get(k)!r} there, {new.get(k)!r} here" for k in keys[:3]]
    return f" ({'; '.join(parts)})" if parts else ""
