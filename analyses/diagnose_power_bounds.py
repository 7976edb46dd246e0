"""The information limit of each candidate effect of the power study (``bounds.json``).

:func:`compute_bounds` is called by ``diagnose_power.py`` for the bounds its design
needs and does not find in ``bounds.json``.
"""

from __future__ import annotations

import zlib
from collections.abc import Iterable

import numpy as np
from regimes import BY_NAME

from hosid.check.evidence import COORDINATES


def compute_bounds(
    keys: Iterable[tuple[str, str, str]], *, seed: int, known: dict | None = None
) -> dict:
    """``(regime, system, effect) -> sd`` of the effect's regular coordinate; for a key
    ``"e given o=k,..."``, the full-state bound of the drift coefficient of ``e`` in the
    model base + e + o, at e = 0 and each ``o`` at ``k`` times its own bound (one step of
    the fixed point: the other's bound moves little, 0.00149 -> 0.00133 for friction).
    ``known`` bounds (read from ``bounds.json``) are not computed again.
    """
    from diagnose_power import _set, systems

    from hosid.model.information import candidate_bound, cramer_rao
    from hosid.model.model import Model

    keys = sorted(keys, key=lambda k: " given " in k[2])  # own bounds first
    out = dict(known or {})
    for regime, system, effect in keys:
        r = BY_NAME[regime]
        base, params = systems(regime)[system]
        rng = np.random.default_rng(np.random.SeedSequence([seed, zlib.crc32(regime.encode())]))
        sim = {"duration": r.duration, "dt": r.dt, "rng": rng,
               "sim_duration": max(40000.0, 20.0 * r.duration)}  # fmt: skip
        if " given " not in effect:
            out[(regime, system, effect)] = candidate_bound(base, params, effect, **sim)
            continue
        e, given = effect.split(" given ")
        others = {o: float(k) for o, k in (g.split("=") for g in given.split(","))}
        model = Model.from_spec([base, e, *others])
        point = {"n1": 0.0, "n2": 0.0, **params}
        for o, k in others.items():
            if (regime, system, o) not in out:
                out[(regime, system, o)] = candidate_bound(base, params, o, **sim)
            _set(point, o, k * out[(regime, system, o)])
        point[COORDINATES[e].param] = 0.0
        crb = cramer_rao(model, {n: point[n] for n in model.param_names}, **sim)
        out[(regime, system, effect)] = crb.sd[COORDINATES[e].param]
    return out
