r"""The five-storey building's system files and hosid's controls on its own simulations.

``analyses/building.py`` reads the building as a five-storey shear chain
(:func:`system_file`); the controls ask whether hosid recovers a chain it simulated like
the building, with what the building's record holds:

- :func:`twin`: a uniform chain with the reference's first mode, driven at the roof by a
  white force, as simulated and with each floor's sensor noise at the building's ratio
  (:func:`sensor_floors`), the noise not modelled and modelled;
- :func:`coloured_twin`: the same chain driven by a narrow-band force like the mass
  damper's (its shaping filter at the building's estimate, peaked between the first two
  modes) with that sensor noise, estimated with a white force and with the shaped one
  (``excitation = "narrowband_excitation"``).
"""

from __future__ import annotations

import dataclasses
import json
import math
from collections.abc import Sequence
from pathlib import Path

import numpy as np
from building_reference import DT, NPERSEG
from scipy import signal

import hosid
from hosid.model.linear_chain import modes as chain_modes

HOSID_STEP = 5
DOFS, TERMS = ("x1", "x2", "x3", "x4", "x5"), ("linear_damping", "linear_stiffness")
#: The narrow-band roof force of :func:`coloured_twin` (rad/s; near the building's estimate)
SHAKER = {"wf": 8.7, "zf": 0.55}


def system_file(driven: Sequence[str], equal: bool, path: Path, noise: bool | None = None,
                shape: str | None = None) -> Path:  # fmt: skip
    """The five-storey shear chain's system file (``noise`` its ``sensor_noise``, ``shape``
    its ``excitation``; not given if None)."""
    text = f'dofs = {json.dumps(DOFS)}\ndriven = {json.dumps(driven)}\nmeasured = "acceleration"\n'
    text += "" if noise is None else f"sensor_noise = {str(noise).lower()}\n"
    text += "" if shape is None else f'excitation = "{shape}"\n'
    for a, b in zip(("ground", *DOFS[:-1]), DOFS, strict=True):
        text += f'[[element]]\nbetween = ["{a}", "{b}"]\nterms = {json.dumps(TERMS)}\n'
    path.write_text(text + ("[masses]\n" + "".join(f"{d} = 1.0\n" for d in DOFS)) * equal)
    return path


def sensor_floors(floors) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The floors' Welch frequencies (Hz), spectra ``(5, F)`` and sensor floors (each
    channel's least ordinate at 0.2-0.45 Hz, below the first mode: its noise)."""
    f, Q = signal.welch(floors.T, fs=1 / DT, nperseg=NPERSEG)
    return f, Q, Q[:, (f > 0.2) & (f < 0.45)].min(axis=1)


def _uniform(system, ref) -> tuple[dict, float]:
    """The uniform chain's values with the reference's first mode (stiffness-proportional
    damping), and its storey stiffness."""
    k = (math.pi * ref[0]["f"] / math.sin(math.pi / 22)) ** 2  # w1 = 2 sqrt(k) sin(pi / 22)
    kinds = {"a1": ref[0]["zeta"] * k / (math.pi * ref[0]["f"]), "a2": k, "S0": 1e-3, "ma": 1,
             **SHAKER}  # fmt: skip
    return {n: kinds.get(n[:2], kinds.get(n)) for n in system.param_names}, k


def _with_noise(rec, floors, ref, seed: int = 2):
    """``rec`` with each floor's white noise at the building's ratio of its sensor floor to
    its first mode's peak, and those ratios."""
    f, Q, floor = sensor_floors(floors)
    ratio = floor / Q[:, np.argmin(np.abs(f - ref[0]["f"]))]
    ft, Qt = signal.welch(rec.x.T, fs=1 / rec.dt, nperseg=NPERSEG // HOSID_STEP)
    sd = np.sqrt(ratio * Qt[:, np.argmin(np.abs(ft - ref[0]["f"]))] / (2 * rec.dt))
    noisy = hosid.Record(rec.x + sd * np.random.default_rng(seed).standard_normal(rec.x.shape),
                         rec.dt, "twin", channels=rec.channels, measured=rec.measured)  # fmt: skip
    return noisy, ratio


def _estimated(r, s, k: float) -> str:
    """hosid's estimate of record ``r`` under system ``s``, in words."""
    try:
        est = hosid.estimate(r, s)
        got = chain_modes(est.model, est.theta)
    except Exception as exc:  # as said
        return f"the estimate fails: {type(exc).__name__}: {exc}"
    a2 = [round(float(est.theta[est.model.param_names.index(n)]), 1)
          for n in s.param_names if n.startswith("a2")]  # fmt: skip
    shape = "".join(f", {n} {est.theta[est.model.index(n)]:.3g}" for n in SHAKER
                    if est.model.has(n))  # fmt: skip
    return (f"estimated modes {np.round(got.omega / (2 * math.pi), 3).tolist()} Hz "
            f"(damping ratios {np.round(got.zeta, 3).tolist()}), storey stiffnesses "
            f"{a2} (true {k:.1f}){shape}, Hansen's J = {est.test['J']:.4g} on "
            f"{est.test['df']} df")  # fmt: skip


def twin(ref: list[dict], work: Path, floors) -> list[str]:
    """hosid's estimate on its own 409.6 s simulation of a uniform chain (roof driven,
    stiffness-proportional damping) with the reference's first mode: as simulated, and
    with a white noise on each floor at the building's ratio of that floor's sensor floor
    (:func:`sensor_floors`) to its first mode's peak, not modelled and modelled."""
    system = hosid.System.from_toml(system_file(["x5"], False, work / "twin.toml", False))
    values, k = _uniform(system, ref)
    rec = hosid.simulate_chain(system, values, duration=409.6, dt=DT * HOSID_STEP,
                               rng=np.random.default_rng(1), measured="acceleration")  # fmt: skip
    noisy, ratio = _with_noise(rec, floors, ref)
    true = chain_modes(system, values)
    modelled = hosid.System.from_toml(system_file(["x5"], False, work / "twin-noise.toml"))
    out = [_estimated(r, s, k) for r, s in ((rec, system), (noisy, system), (noisy, modelled))]
    return [
        f"true modes {np.round(true.omega / (2 * math.pi), 3).tolist()} Hz; noise over "
        f"first-mode peak, floors 1-5: {', '.join(f'{v:.2g}' for v in ratio)}",
        *out,
    ]


def coloured_twin(ref: list[dict], work: Path, floors) -> list[str]:
    """The twin driven at the roof by the narrow-band force :data:`SHAKER` with the
    building's sensor noise (module docstring), estimated with a white force
    (``excitation = "white"``) and with the shaped one."""
    white = hosid.System.from_toml(system_file(["x5"], False, work / "twin-white.toml",
                                               shape="white"))  # fmt: skip
    shaped = hosid.System.from_toml(system_file(["x5"], False, work / "twin-shaped.toml",
                                                shape="narrowband_excitation"))  # fmt: skip
    quiet = dataclasses.replace(shaped, sensor_noise=False)
    values, k = _uniform(quiet, ref)
    rec = hosid.simulate_chain(quiet, values, duration=409.6, dt=DT * HOSID_STEP,
                               rng=np.random.default_rng(3))  # fmt: skip
    noisy, _ = _with_noise(rec, floors, ref, seed=4)
    return [
        f"wf {SHAKER['wf']} rad/s, zf {SHAKER['zf']}",
        *(_estimated(noisy, s, k) for s in (white, shaped)),
    ]
