r"""Fit results as arviz ``DataTree`` objects: build, save, load, summarize.

Layout of a fit (also the layout of ``posterior.nc``):

``posterior``
    One variable per sampled parameter (``a1, n1, a2, n2, S0`` and any extra
    term), plus the derived equivalent damping
    :math:`a_{1eq} = a_1 + n_1\sqrt{8/\pi}\,\sigma_{\dot x}` (eq 65), each with dims
    ``(chain, draw)``; emcee's walkers are the chains.
``sample_stats``
    ``lp`` (log pseudo-posterior), ``log_prior``.
``log_likelihood``
    The log pseudo-likelihood of each cost component (for example ``J2W`` and
    ``J4AW``), tempered, dims ``(chain, draw)``.
``observed_data``
    The record's block-averaged feature cross-spectra on the fitted band
    (``omega``, real and imaginary parts) and the response moments used.
``cost_map``
    The (untempered) cost over an ``(a1, n1)`` grid with the other parameters at
    their posterior medians; the background of the contour plots (Figures 7-8).
Root attributes
    ``cost``, ``constrained`` (0/1), ``temperature``, ``sigma_v``, ``record``,
    ``fit_seconds``, ``settings_json`` and ``truths_json`` (JSON strings), and
    ``calibration_json`` (how the temperature was chosen).
"""

from __future__ import annotations

import json
import math
import warnings
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import arviz as az
import numpy as np
import xarray as xr

__all__ = [
    "ESS_MIN",
    "RHAT_MAX",
    "ConvergenceWarning",
    "build_tree",
    "load",
    "parameter_names",
    "save",
    "summarize",
    "truths",
]

RHAT_MAX = 1.01
ESS_MIN = 400.0


class ConvergenceWarning(UserWarning):
    """R-hat or effective sample size outside the accepted range."""


def build_tree(
    posterior: Mapping[str, np.ndarray],
    *,
    sample_stats: Mapping[str, np.ndarray],
    log_likelihood: Mapping[str, np.ndarray],
    observed: Mapping[str, np.ndarray] | None = None,
    cost_map: Mapping[str, np.ndarray] | None = None,
    attrs: Mapping[str, Any] | None = None,
) -> xr.DataTree:
    """Assemble a fit's ``DataTree``.

    Parameters
    ----------
    posterior, sample_stats, log_likelihood
        Arrays of shape ``(chain, draw)``.
    observed
        Arrays keyed by name; ``omega`` is used as the frequency coordinate for
        any array whose last axis has its length.
    cost_map
        ``{"a1": (na,), "n1": (nn,), "cost": (na, nn)}``.
    attrs
        Root attributes; mappings are stored as JSON strings under ``<key>_json``.
    """
    groups: dict[str, xr.Dataset] = {
        "posterior": _dataset(posterior),
        "sample_stats": _dataset(sample_stats),
        "log_likelihood": _dataset(log_likelihood),
    }
    if observed:
        omega = np.asarray(observed.get("omega", []))
        data_vars = {}
        for k, v in observed.items():
            v = np.asarray(v)
            if k == "omega":
                continue
            if v.ndim == 1 and omega.size and v.shape[-1] == omega.size:
                data_vars[k] = (("omega",), v)
            else:
                data_vars[k] = (tuple(f"{k}_dim_{i}" for i in range(v.ndim)), v)
        coords = {"omega": omega} if omega.size else {}
        groups["observed_data"] = xr.Dataset(data_vars, coords=coords)
    if cost_map:
        groups["cost_map"] = xr.Dataset(
            {"cost": (("a1", "n1"), np.asarray(cost_map["cost"], float))},
            coords={"a1": np.asarray(cost_map["a1"]), "n1": np.asarray(cost_map["n1"])},
        )
    tree = xr.DataTree.from_dict({f"/{k}": v for k, v in groups.items()})
    tree.attrs.update(_attrs(attrs or {}))
    return tree


def _dataset(arrays: Mapping[str, np.ndarray]) -> xr.Dataset:
    data_vars = {}
    for k, v in arrays.items():
        v = np.asarray(v, dtype=float)
        if v.ndim != 2:
            raise ValueError(f"{k}: expected an array of shape (chain, draw), got {v.shape}")
        data_vars[k] = (("chain", "draw"), v)
    ds = xr.Dataset(data_vars)
    n_chain, n_draw = next(iter(data_vars.values()))[1].shape if data_vars else (0, 0)
    return ds.assign_coords(chain=np.arange(n_chain), draw=np.arange(n_draw))


def _attrs(attrs: Mapping[str, Any]) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for k, v in attrs.items():
        if v is None:
            continue
        if isinstance(v, Mapping | list | tuple):
            out[f"{k}_json"] = json.dumps(_jsonable(v))
        elif isinstance(v, bool | np.bool_):
            out[k] = int(v)
        else:
            out[k] = v
    return out


def _jsonable(value: Any) -> Any:
    if isinstance(value, Mapping):
        return {str(k): _jsonable(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_jsonable(v) for v in value]
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray):
        return _jsonable(value.tolist())
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


def save(tree: xr.DataTree, path: str | Path) -> Path:
    """Write a fit to netCDF (``h5netcdf`` engine)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tree.to_netcdf(path, engine="h5netcdf")
    return path


def load(path: str | Path) -> xr.DataTree:
    """Read a fit written by :func:`save`."""
    path = Path(path)
    if not path.is_file():
        from .errors import HosidInputError

        raise HosidInputError(f"{path}: no such file")
    return xr.open_datatree(path, engine="h5netcdf").load()


def _json_attr(tree: xr.DataTree, key: str) -> Any:
    text = tree.attrs.get(f"{key}_json")
    return json.loads(text) if text else None


def truths(tree: xr.DataTree) -> dict[str, float] | None:
    """The true parameter values stored with a fit of simulated data, if any."""
    return _json_attr(tree, "truths")


def parameter_names(tree: xr.DataTree) -> list[str]:
    """Sampled parameters (posterior variables except the derived ``a1eq``)."""
    return [k for k in tree["posterior"].data_vars if k != "a1eq"]


def summarize(tree: xr.DataTree, *, warn: bool = True) -> dict[str, Any]:
    """Posterior summary with convergence diagnostics.

    For every posterior variable: ``mean``, ``sd``, ``q05``, ``q50``, ``q95``,
    ``r_hat`` (rank-normalized split R-hat), ``ess_bulk`` and ``ess_tail``.  The
    walkers of an ensemble are not independent chains, so R-hat over walkers is
    a conservative check.  ``converged`` is true when every R-hat is below
    :data:`RHAT_MAX` and every bulk and tail ESS at least :data:`ESS_MIN`; otherwise a
    :class:`ConvergenceWarning` is issued (when ``warn``) and the failures listed.
    """
    post = tree["posterior"].to_dataset()
    params: dict[str, dict[str, float]] = {}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        rhat = az.rhat(post)
        ess_bulk = az.ess(post, method="bulk")
        ess_tail = az.ess(post, method="tail")
    failures = []
    for k in post.data_vars:
        v = post[k].values.ravel()
        q05, q50, q95 = np.quantile(v, [0.05, 0.5, 0.95])
        row = {
            "mean": float(np.mean(v)),
            "sd": float(np.std(v, ddof=1)),
            "q05": float(q05),
            "q50": float(q50),
            "q95": float(q95),
            "r_hat": float(rhat[k]),
            "ess_bulk": float(ess_bulk[k]),
            "ess_tail": float(ess_tail[k]),
        }
        params[k] = row
        if not row["r_hat"] < RHAT_MAX:
            failures.append(f"{k}: r_hat {row['r_hat']:.3f} >= {RHAT_MAX}")
        for e in ("ess_bulk", "ess_tail"):
            if not row[e] >= ESS_MIN:
                failures.append(f"{k}: {e} {row[e]:.0f} < {ESS_MIN:.0f}")
    if failures and warn:
        warnings.warn(
            "convergence diagnostics failed: " + "; ".join(failures),
            ConvergenceWarning,
            stacklevel=2,
        )
    a = tree.attrs
    return {
        "parameters": params,
        "cost": a.get("cost"),
        "constrained": bool(a.get("constrained", 0)),
        "temperature": a.get("temperature"),
        "sigma_v": a.get("sigma_v"),
        "record": a.get("record"),
        "fit_seconds": a.get("fit_seconds"),
        "n_walkers": int(post.sizes["chain"]),
        "n_draws": int(post.sizes["draw"]),
        "converged": not failures,
        "diagnostic_failures": failures,
        "settings": _json_attr(tree, "settings"),
        "calibration": _json_attr(tree, "calibration"),
        "truths": truths(tree),
    }
