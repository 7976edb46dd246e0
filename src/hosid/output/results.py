r"""A fit as an arviz ``DataTree``: groups, attributes, summary, netCDF.

Groups (``posterior.nc`` holds the same):

``posterior``
    Every model parameter (``a1, n1, a2, n2, S0`` for the paper model, plus each added
    term's) and the equivalent damping ``a1eq`` of eq (65), dims ``(chain, draw)``;
    emcee's walkers are the chains.
``sample_stats``
    ``lp`` (log quasi-posterior) and ``log_prior``.
``log_likelihood``
    One variable per likelihood component (``identities``, ``J2``, ``J4A`` ...): its
    exact share of the quasi-log-likelihood (:mod:`hosid.inference.gmm`).
``prior``
    Draws from the priors, constraints applied.
``observed_data``
    ``omega``, the record's displacement spectrum ``Sxx`` on the fitted band and the
    periodogram of the force inferred at the estimate, ``force`` (eq 45).
``constant_data``
    ``theta_hat`` (the mode) and ``laplace_cov`` (the calibrated curvature's inverse).
``likelihood_map`` (optional)
    The calibrated quasi-log-likelihood over an ``(a1, n1)`` grid, the other parameters
    at the estimate: the valley of J2 and the twin minima of J4 (paper Figures 7-8).

Root attributes: ``created_at``, ``inference_library`` (emcee) and its version,
``versions`` (:func:`versions`: hosid's and its libraries'), the model, components,
calibration, settings, state, sampler diagnostics and timings (mappings as JSON strings
``<key>_json``).
"""

from __future__ import annotations

import json
import math
import platform
import sys
import warnings
from collections.abc import Iterator, Mapping
from contextlib import contextmanager
from importlib.metadata import PackageNotFoundError, version
from pathlib import Path
from typing import Any

import numpy as np
import xarray as xr

from ..errors import HosidInputError
from ..verdicts import ESS_MIN, RHAT_MAX, Check, overall

__all__ = [
    "ESS_MIN",
    "LIBRARIES",
    "RHAT_MAX",
    "ConvergenceWarning",
    "attr",
    "build_tree",
    "jsonable",
    "load",
    "parameter_names",
    "save",
    "summarize",
    "versions",
]

#: The distributions whose versions every result records (:func:`versions`).
LIBRARIES = ("hosid", "numpy", "scipy", "emcee", "arviz", "numba", "matplotlib", "xarray")
#: A system's modal view in ``summary.json`` (:func:`hosid.inference.structure.modal`).
MODAL = ("modes", "modes_small_amplitude", "modes_linearisation")


class ConvergenceWarning(UserWarning):
    """R-hat or effective sample size outside the accepted range."""


def jsonable(value: Any) -> Any:
    """Plain JSON types: numpy scalars and arrays converted, NaN and inf to ``None``."""
    if isinstance(value, Mapping):
        return {str(k): jsonable(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [jsonable(v) for v in value]
    if isinstance(value, np.ndarray):
        return jsonable(value.tolist())
    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, Path):
        return str(value)
    return value


def versions() -> dict[str, str | None]:
    """The installed versions of :data:`LIBRARIES` and Python's, by name (``None`` for a
    library that is not installed); read from the installed metadata, nothing imported.
    """
    out: dict[str, str | None] = {}
    for name in LIBRARIES:
        try:
            out[name] = version(name)
        except PackageNotFoundError:
            out[name] = None
    out["python"] = platform.python_version()
    return out


def build_tree(
    *,
    posterior: Mapping[str, np.ndarray],
    sample_stats: Mapping[str, np.ndarray],
    log_likelihood: Mapping[str, np.ndarray],
    prior: Mapping[str, np.ndarray],
    observed_data: Mapping[str, np.ndarray],
    constant_data: Mapping[str, np.ndarray],
    param_names: tuple[str, ...],
    likelihood_map: Mapping[str, np.ndarray] | None = None,
    attrs: Mapping[str, Any] | None = None,
) -> xr.DataTree:
    """Assemble a fit (module docstring) with :func:`arviz.from_dict`; the root
    attributes are ``attrs`` and ``versions`` (:func:`versions`, unless ``attrs`` has them).
    """
    from arviz_base import from_dict  # arviz.from_dict, without arviz's plotting (pyplot)

    omega = np.asarray(observed_data["omega"])
    dims = {k: ["omega"] for k in observed_data if k != "omega"}
    dims.update({"theta_hat": ["param"], "laplace_cov": ["param", "param_"]})
    coords = {"omega": omega, "param": list(param_names), "param_": list(param_names)}
    obs = {k: v for k, v in observed_data.items() if k != "omega"}
    with warnings.catch_warnings():
        # emcee's walkers are the chains: a short run has more of them than draws
        warnings.filterwarnings("ignore", message=".*chain dimension.*", category=UserWarning)
        tree = from_dict(
            {
                "posterior": dict(posterior),
                "sample_stats": dict(sample_stats),
                "log_likelihood": dict(log_likelihood),
                "prior": dict(prior),
                "observed_data": obs,
                "constant_data": dict(constant_data),
            },
            coords=coords,
            dims=dims,
        )
    if likelihood_map is not None:
        tree["likelihood_map"] = xr.DataTree(
            xr.Dataset(
                {"log_likelihood": (("a1", "n1"), np.asarray(likelihood_map["log_likelihood"]))},
                coords={"a1": likelihood_map["a1"], "n1": likelihood_map["n1"]},
                attrs={
                    "what": "calibrated quasi-log-likelihood, other parameters at the estimate"
                },
            )
        )
    for k, v in {**(attrs or {}), "versions": (attrs or {}).get("versions") or versions()}.items():
        if v is None:
            continue
        if isinstance(v, Mapping | list | tuple):
            tree.attrs[f"{k}_json"] = json.dumps(jsonable(v))
        elif isinstance(v, bool | np.bool_):
            tree.attrs[k] = int(v)
        else:
            tree.attrs[k] = v
    return tree


def attr(tree: xr.DataTree, key: str, default: Any = None) -> Any:
    """A root attribute, decoding ``<key>_json``."""
    if f"{key}_json" in tree.attrs:
        return json.loads(tree.attrs[f"{key}_json"])
    return tree.attrs.get(key, default)


def stored_model(tree: xr.DataTree):
    """The fitted model (with the excitation terms the fit added), or ``None``; a
    measured excitation shape comes back from its stored table.
    """
    from ..model.measured import MeasuredExcitation
    from ..model.model import Model

    names = list(attr(tree, "model") or [])
    if not names or ":" in "".join(names):  # none, or a system's elements
        return None
    table = attr(tree, "excitation_shape")
    terms = [
        MeasuredExcitation.from_table(table["omega"], table["level"])
        if n == MeasuredExcitation.name and table
        else n
        for n in names
    ]
    return Model.from_spec(terms)


def parameter_names(tree: xr.DataTree) -> list[str]:
    """Sampled parameters (posterior variables except the derived ``a1eq``, of a system's
    elements ``a1eq[...]``).
    """
    return [k for k in tree["posterior"].data_vars if k != "a1eq" and not k.startswith("a1eq[")]


@contextmanager
def _without_distributed() -> Iterator[None]:
    """Refuse imports of dask's ``distributed`` while the block runs, unless it is loaded.

    xarray's ``to_netcdf`` asks dask which scheduler is active, and dask imports
    ``distributed`` to find out (about half a second), although a fit holds no dask arrays:
    refused, the answer is "none", which is what in-memory arrays need.  dask remembers
    the refusal (``dask.base._DISTRIBUTED_AVAILABLE``): it is forgotten again, so that
    the process can still use ``distributed`` later.  A process that uses it already
    (``hosid batch``) is left alone.
    """
    if "distributed" in sys.modules:
        yield
        return
    sys.modules["distributed"] = None  # type: ignore[assignment]
    try:
        yield
    finally:
        if sys.modules.get("distributed", 0) is None:
            del sys.modules["distributed"]
        base = sys.modules.get("dask.base")
        if getattr(base, "_DISTRIBUTED_AVAILABLE", None) is False:
            base._DISTRIBUTED_AVAILABLE = None  # type: ignore[union-attr]


def save(tree: xr.DataTree, path: str | Path) -> Path:
    """Write a fit to netCDF (``h5netcdf``)."""
    path = Path(path)
    with _without_distributed():
        tree.to_netcdf(path, engine="h5netcdf")
    return path


def load(path: str | Path) -> xr.DataTree:
    """Read a fit written by :func:`save`.

    Raises
    ------
    HosidInputError
        If the file is missing, unreadable or not a hosid fit.
    """
    path = Path(path)
    if not path.is_file():
        raise HosidInputError(f"{path}: no such file")
    try:
        tree = xr.open_datatree(path, engine="h5netcdf").load()
    except (OSError, ValueError) as exc:
        raise HosidInputError(f"{path}: cannot read ({exc})") from None
    if "posterior" not in tree.children:
        raise HosidInputError(f"{path}: not a hosid fit (no posterior group)")
    return tree


def summarize(tree: xr.DataTree, *, warn: bool = True) -> dict[str, Any]:
    """Posterior summary (the columns of :func:`arviz.summary`) with convergence checks.

    Per variable: ``mean``, ``sd``, the 5 / 25 / 50 / 75 / 95 % quantiles, ``r_hat``,
    ``ess_bulk``, ``ess_tail``.  ``checks`` lists the fit's verdicts
    (:mod:`hosid.verdicts`: the record checks, calibration, convergence) and ``verdict``
    is the worst of them; ``forced`` says that a record that failed a check was fitted
    anyway.  ``converged`` is true when every R-hat is below
    :data:`RHAT_MAX` and every ESS at least :data:`ESS_MIN`; otherwise the failures are
    listed (and a :class:`ConvergenceWarning` issued when ``warn``).  ``versions`` are
    those the fit was made with (:func:`versions`; ``None`` for a fit written before
    hosid recorded them).
    """
    from arviz_stats import ess, rhat  # what arviz.summary computes, without its MCSE

    post = tree["posterior"].to_dataset()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        # short chains: arviz warns when walkers (chains) outnumber draws
        warnings.filterwarnings("ignore", message=".*chain dimension.*", category=UserWarning)
        r_hat, bulk, tail = rhat(post), ess(post, method="bulk"), ess(post, method="tail")
    params: dict[str, dict[str, float]] = {}
    failures = []
    for k in post.data_vars:
        v = post[k].values.ravel()
        q = np.quantile(v, [0.05, 0.25, 0.5, 0.75, 0.95])
        row = {
            "mean": float(np.mean(v)),
            "sd": float(np.std(v, ddof=1)),
            **{
                f"q{int(100 * p):02d}": float(x)
                for p, x in zip((0.05, 0.25, 0.5, 0.75, 0.95), q, strict=True)
            },
            "r_hat": float(r_hat[k]),
            "ess_bulk": float(bulk[k]),
            "ess_tail": float(tail[k]),
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
    checks = attr(tree, "checks") or []
    return {
        "record": attr(tree, "record"),
        "record_hash": attr(tree, "record_hash"),
        "model": attr(tree, "model"),
        "components": attr(tree, "components"),
        "cost": attr(tree, "cost"),
        "constrained": bool(attr(tree, "constrained", 1)),
        "parameters": params,
        "n_walkers": int(post.sizes["chain"]),
        "n_draws": int(post.sizes["draw"]),
        "converged": not failures,
        "diagnostic_failures": failures,
        "checks": checks,
        "verdict": overall(Check.from_dict(c) for c in checks),
        "record_notes": attr(tree, "record_notes") or [],
        "excitation_test": attr(tree, "excitation_test"),
        **{k: attr(tree, k) for k in MODAL if attr(tree, k) is not None},
        "forced": bool(attr(tree, "forced", 0)),
        "fit_seconds": attr(tree, "fit_seconds"),
        "calibration": attr(tree, "calibration"),
        "settings": attr(tree, "settings"),
        "truths": attr(tree, "truths"),
        "versions": attr(tree, "versions"),
    }
