r"""A system's parameter vector read by name: the values by dof, the log-handled ones.

:class:`ParameterLayout` holds what :class:`hosid.model.system.System` does with its
:attr:`~hosid.model.system.System.param_names` (the one place of the layout): a mapping
or a vector checked against it, the masses, levels and sensor noises by dof, the
parameters solved for in their logarithm, and the forces' spectral shape.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from functools import cached_property

import numpy as np

from ..errors import HosidInputError

__all__ = ["ParameterLayout", "named"]


def named(names: Sequence[str], theta, owner: str) -> dict:
    """``theta`` (a mapping, or a vector in ``names`` order) as a dict by name, checked
    against ``names`` (the parameters of ``owner``, a model or a system).

    Raises
    ------
    HosidInputError
        If a parameter is missing or unknown, or the vector has the wrong length.
    """
    if isinstance(theta, Mapping):
        missing = [n for n in names if n not in theta]
        extra = [k for k in theta if k not in names]
        if missing or extra:
            raise HosidInputError(
                f"parameters do not match the {owner} ({', '.join(names)}): "
                f"missing {missing or 'none'}, unknown {extra or 'none'}"
            )
        return {n: float(theta[n]) for n in names}
    values = np.asarray(theta, dtype=float)
    if values.shape != (len(names),):
        raise HosidInputError(
            f"theta has shape {values.shape}; expected ({len(names)},) for {', '.join(names)}"
        )
    return dict(zip(names, values.tolist(), strict=True))


class ParameterLayout:
    """Access to a system's parameters by name (module docstring); a mixin of
    :class:`hosid.model.system.System`.
    """

    def index(self, name: str) -> int:
        """Position of parameter ``name`` in ``theta``."""
        return self.param_names.index(name)

    def has(self, name: str) -> bool:
        """Whether ``name`` is a parameter of the system."""
        return name in self.param_names

    @property
    def log_params(self) -> list[int]:
        """Parameters handled in their logarithm: unknown masses, levels, the shape's."""
        shape = tuple(p for t in self.excitation or () for p in t.params)
        return [i for i, n in enumerate(self.param_names)
                if n.startswith(("mass[", "S0", "N[")) or n in shape]  # fmt: skip

    @cached_property
    def spectrum(self):
        r"""The forces' shape :math:`L(\omega;\theta)`
        (:class:`hosid.model.excitation.Spectrum`; white without :attr:`excitation`).
        """
        from .excitation import Spectrum

        return Spectrum(self)

    def params(self, theta: Mapping[str, float] | Sequence[float] | np.ndarray) -> dict:
        """``theta`` (a mapping, or a vector in :attr:`param_names` order) as a dict
        (:func:`named`).

        Raises
        ------
        HosidInputError
            If a parameter is missing or unknown, or the vector has the wrong length.
        """
        return named(self.param_names, theta, "system")

    def vector(self, theta=None) -> np.ndarray:
        """A parameter mapping (default: the system's own values, all needed) as a vector.

        Raises
        ------
        HosidInputError
            If a parameter is missing (e.g. a simulation of a file without all values).
        """
        if theta is None:
            given = dict(self.values)
            missing = [n for n in self.param_names if n not in given]
            if missing:
                raise HosidInputError(f"values missing for {', '.join(missing)}")
            theta = given
        if isinstance(theta, Mapping):
            return np.array(list(self.params(theta).values()))
        th = np.asarray(theta, dtype=float)
        if th.shape[-1:] != (len(self.param_names),):
            raise HosidInputError(
                f"theta has shape {th.shape}; expected (..., {len(self.param_names)})"
            )
        return th

    def mass_vector(self, theta) -> np.ndarray:
        """:math:`m`, ``(..., n)``: known masses and those of ``theta`` (``(..., p)``)."""
        free = tuple(d for d, m in zip(self.dofs, self.masses, strict=True) if m is None)
        known = np.array([0.0 if m is None else m for m in self.masses])
        return known + self._by_dof(self.vector(theta), free, "mass")

    def levels(self, theta) -> np.ndarray:
        r""":math:`S_{0,d}`, ``(..., n)``: 0 on the dofs without a force."""
        return self._by_dof(self.vector(theta), self.driven, "S0")

    def noise_levels(self, theta) -> np.ndarray:
        r""":math:`N_d`, ``(..., n)``: 0 on the channels without a sensor noise."""
        return self._by_dof(self.vector(theta), self.sensor_noise or (), "N")

    def _by_dof(self, th: np.ndarray, dofs: tuple[str, ...], kind: str) -> np.ndarray:
        out = np.zeros((*th.shape[:-1], self.n))
        names = self.param_names
        for d in dofs:
            name = kind if self.single_names else f"{kind}[{d}]"
            out[..., self.dofs.index(d)] = th[..., names.index(name)]
        return out
