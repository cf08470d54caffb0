"""Saving and loading an :class:`ccm.learn.mixtures.igmm.IGMM` without pickle.

Two forms hold the same content: JSON-safe data (:func:`to_state`, :func:`from_state`; what a
run's ``state/<condition>.json`` holds through the forward model) and an uncompressed NPZ file
(:func:`save_npz`, :func:`load_npz`; ``np.load(..., allow_pickle=False)``). Every malformed
input is a ``ValueError`` that says what is wrong.
"""

from __future__ import annotations

import inspect
import json
import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from ccm.core.errors import ConfigError

FORMAT = "ccm.igmm"
FORMAT_VERSION = 1
_ARRAYS = ("means", "covariances", "support", "ages")


def to_state(model: Any) -> dict[str, Any]:
    """JSON-safe snapshot of ``model``: settings, components, counters."""
    return {
        "format": FORMAT,
        "format_version": FORMAT_VERSION,
        "params": model.get_params(),
        "n_seen": model.n_seen_,
        "stats": model.stats_,
        "means": model.means_.tolist(),
        "covariances": model.covariances_.tolist(),
        "support": model.support_.tolist(),
        "ages": [int(a) for a in model.ages_],
    }


def from_state(cls: type, data: Mapping[str, Any], key: str) -> Any:
    """A new ``cls`` (IGMM) rebuilt from :func:`to_state` output (ConfigError for bad
    settings, ValueError for anything else)."""
    params = _checked_header(cls, data)
    model = cls(**dict(params), key=key)
    arrays, n_seen = _component_arrays(data, model.n_features, model.max_components)
    stats = data.get("stats", {})
    model.restore(*arrays, n_seen=n_seen, stats=stats if isinstance(stats, Mapping) else {})
    return model


def _checked_header(cls: type, data: Any) -> Mapping[str, Any]:
    """The format fields and the settings of a snapshot; ValueError if they do not fit."""
    if not isinstance(data, Mapping):
        raise ValueError(f"IGMM data must be a mapping, got {type(data).__name__}")
    if data.get("format") != FORMAT:
        raise ValueError(f"not an IGMM snapshot: format={data.get('format')!r}")
    if data.get("format_version") != FORMAT_VERSION:
        raise ValueError(
            f"unsupported IGMM format_version {data.get('format_version')!r} "
            f"(this code reads {FORMAT_VERSION})"
        )
    missing = [k for k in ("params", "n_seen", *_ARRAYS) if k not in data]
    if missing:
        raise ValueError(f"IGMM data is missing {', '.join(missing)}")
    params = data["params"]
    if not isinstance(params, Mapping):
        raise ValueError("IGMM data: params must be a mapping")
    allowed = set(inspect.signature(cls.__init__).parameters) - {"self", "key"}
    unknown = sorted(set(params) - allowed)
    if unknown:
        raise ValueError(f"IGMM data: unknown params {', '.join(map(str, unknown))}")
    absent = [k for k in ("n_features", "sigma_init") if k not in params]
    if absent:
        raise ValueError(f"IGMM data: params is missing {', '.join(absent)}")
    return params


def _component_arrays(
    data: Mapping[str, Any], d: int, kmax: int
) -> tuple[tuple[np.ndarray, ...], int]:
    """(means, covariances, support, ages) as checked float64 arrays, and n_seen."""
    try:
        means, covs, sp, ages = (np.asarray(data[k], dtype=np.float64) for k in _ARRAYS)
        n_seen = int(data["n_seen"])
    except (TypeError, ValueError) as exc:
        raise ValueError(f"IGMM data: non-numeric component arrays ({exc})") from None
    if means.size == 0:  # an empty model ([] in JSON)
        means, covs = means.reshape(0, d), covs.reshape(0, d, d)
        sp, ages = sp.reshape(0), ages.reshape(0)
    n = means.shape[0]
    if means.ndim != 2 or means.shape[1] != d or n > kmax:
        raise ValueError(f"IGMM data: means must have shape (K<={kmax}, {d}), got {means.shape}")
    if covs.shape != (n, d, d) or sp.shape != (n,) or ages.shape != (n,):
        raise ValueError(
            f"IGMM data: inconsistent shapes means {means.shape}, covariances {covs.shape}, "
            f"support {sp.shape}, ages {ages.shape}"
        )
    for name, arr in zip(_ARRAYS, (means, covs, sp, ages), strict=True):
        if not np.all(np.isfinite(arr)):
            raise ValueError(f"IGMM data: {name} must be finite")
    if np.any(sp <= 0.0) or np.any(ages < 1.0) or n_seen < 0:
        raise ValueError("IGMM data: support must be > 0, ages >= 1 and n_seen >= 0")
    if not np.allclose(covs, np.swapaxes(covs, 1, 2), rtol=1e-12, atol=0.0):
        raise ValueError("IGMM data: covariances must be symmetric")
    return (means, covs, sp, ages), n_seen


def save_npz(model: Any, path: str | os.PathLike[str]) -> Path:
    """Write ``model`` to ``path`` as an uncompressed NPZ (no pickled objects), through a
    temporary name and a rename, so a crash never leaves a half-written model behind."""
    path = Path(path)
    arrays = {
        "format": np.array(FORMAT),
        "format_version": np.array(FORMAT_VERSION, dtype=np.int64),
        "params_json": np.array(json.dumps(model.get_params(), sort_keys=True)),
        "stats_json": np.array(json.dumps(model.stats_, sort_keys=True)),
        "n_seen": np.array(model.n_seen_, dtype=np.int64),
        "means": model.means_,
        "covariances": model.covariances_,
        "support": model.support_,
        "ages": model.ages_,
    }
    tmp = path.with_name(path.name + ".tmp")
    with open(tmp, "wb") as fh:
        np.savez(fh, **arrays)
    os.replace(tmp, path)
    return path


def load_npz(cls: type, path: str | os.PathLike[str], key: str) -> Any:
    """A ``cls`` (IGMM) read from a file :func:`save_npz` wrote (ValueError for a bad file)."""
    path = Path(path)
    raw = _read_npz(path)
    try:
        data = {
            "format": str(raw["format"][()]),
            "format_version": int(raw["format_version"]),
            "params": json.loads(str(raw["params_json"][()])),
            "stats": json.loads(str(raw["stats_json"][()])) if "stats_json" in raw else {},
            "n_seen": int(raw["n_seen"]),
            **{k: raw[k] for k in _ARRAYS},
        }
        return from_state(cls, data, key)
    except ConfigError as exc:
        raise ValueError(f"{path}: invalid IGMM settings ({exc})") from None
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{path}: not a valid IGMM file ({exc})") from None


def _read_npz(path: Path) -> dict[str, np.ndarray]:
    """Every array of the NPZ at ``path`` (ValueError if it is not one, or lacks any)."""
    needed = ("format", "format_version", "params_json", "n_seen", *_ARRAYS)
    try:
        npz = np.load(path, allow_pickle=False)
    except Exception as exc:  # any failure to parse is a bad file for the caller
        raise ValueError(f"{path}: not a valid IGMM file ({type(exc).__name__}: {exc})") from None
    try:
        if not isinstance(npz, np.lib.npyio.NpzFile):
            raise ValueError("not an NPZ archive")
        missing = [k for k in needed if k not in npz.files]
        if missing:
            raise ValueError(f"missing arrays {', '.join(missing)}")
        return {k: npz[k] for k in npz.files}
    except Exception as exc:
        raise ValueError(f"{path}: not a valid IGMM file ({type(exc).__name__}: {exc})") from None
    finally:
        if isinstance(npz, np.lib.npyio.NpzFile):
            npz.close()
