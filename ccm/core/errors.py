"""User-facing errors and input checks.

Every check names the configuration key it guards and the allowed range, so the CLI can
print one line and exit non-zero (the contract for bad input: docs/user-guide/running.md, "What a
run writes").
"""

from __future__ import annotations

import math
import re
from collections.abc import Iterable, Iterator, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np


class ConfigError(ValueError):
    """A configuration value the user can fix. ``str(err)`` is a single line."""

    def __init__(self, key: str, problem: str) -> None:
        self.key = key
        self.problem = problem
        super().__init__(f"{key}: {problem}")


def exception_line(exc: BaseException) -> str:
    """``"<Type>: <first line of the message>"`` (just the type if the message is empty): an
    exception from someone else's code (a plugin) as one line."""
    text = str(exc).strip()
    return f"{type(exc).__name__}: {text.splitlines()[0]}" if text else type(exc).__name__


class SimulationDiverged(RuntimeError):
    """The simulation produced NaN/inf or a runaway state; the run is marked failed."""


def _as_float(key: str, value: Any) -> float:
    if isinstance(value, bool):
        raise ConfigError(key, f"must be a number, got {value!r}")
    try:
        out = float(value)
    except (TypeError, ValueError):
        raise ConfigError(key, f"must be a number, got {value!r}") from None
    if not math.isfinite(out):
        raise ConfigError(key, f"must be a finite number, got {value!r}")
    return out


def check_finite(key: str, value: Any) -> float:
    """Return ``value`` as a float; reject NaN, inf and non-numbers."""
    return _as_float(key, value)


def check_positive(key: str, value: Any) -> float:
    """Return ``value`` as a float; it must be finite and > 0."""
    out = _as_float(key, value)
    if out <= 0.0:
        raise ConfigError(key, f"must be > 0, got {value!r}")
    return out


def check_nonneg(key: str, value: Any) -> float:
    """Return ``value`` as a float; it must be finite and >= 0."""
    out = _as_float(key, value)
    if out < 0.0:
        raise ConfigError(key, f"must be >= 0, got {value!r}")
    return out


def check_range(key: str, value: Any, lo: float, hi: float) -> float:
    """Return ``value`` as a float; it must lie in the closed interval [lo, hi]."""
    out = _as_float(key, value)
    if not lo <= out <= hi:
        raise ConfigError(key, f"must be in [{lo}, {hi}], got {value!r}")
    return out


def check_restitution(key: str, value: Any) -> float:
    """A coefficient of restitution, in [0, 1] (both backends' surfaces and boxes)."""
    return check_range(key, value, 0.0, 1.0)


def check_int_positive(key: str, value: Any) -> int:
    """Return ``value`` as an int >= 1."""
    if isinstance(value, bool) or not isinstance(value, int | np.integer):
        raise ConfigError(key, f"must be an integer >= 1, got {value!r}")
    if value < 1:
        raise ConfigError(key, f"must be an integer >= 1, got {value!r}")
    return int(value)


def check_int_nonneg(key: str, value: Any) -> int:
    """Return ``value`` as an int >= 0."""
    if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < 0:
        raise ConfigError(key, f"must be an integer >= 0, got {value!r}")
    return int(value)


def check_bool(key: str, value: Any) -> bool:
    """Return ``value`` if it is a bool (YAML ``true``/``false``): ``no``, ``off`` or ``2``
    reach a config as a string or a number, which Python would take as true."""
    if not isinstance(value, bool):
        raise ConfigError(key, f"must be true or false, got {value!r}")
    return value


#: a name that becomes a file or directory name: no '/', no leading '.' (so never '..')
_FILE_NAME = re.compile(r"[A-Za-z0-9_\-][A-Za-z0-9_.\-]*")
NAME_MAX = 255  # bytes in one path component (Linux, macOS)


def check_file_name(key: str, value: Any) -> str:
    """Return ``value`` if it can name a directory: letters, digits, ``_``, ``-`` and ``.``
    (not first), at most :data:`NAME_MAX` characters."""
    if not isinstance(value, str) or not _FILE_NAME.fullmatch(value) or len(value) > NAME_MAX:
        text = repr(value)
        shown = text if len(text) <= 60 else f"{text[:40]}… ({len(text)} characters)"
        raise ConfigError(
            key, f"may use letters, digits, '_', '-' and '.' (not first), at most {NAME_MAX} "
            f"characters; got {shown}",
        )  # fmt: skip
    return value


def leaves(node: Any, path: str = "") -> Iterator[tuple[str, Any, Any]]:
    """``(dotted path, key, value)`` of every value of a plain config tree (dicts and lists,
    as :func:`to_plain` gives) that is neither: ``a.b[2].c`` paths, the key the last dict or
    list index."""
    if isinstance(node, dict):
        for k, v in node.items():
            where = f"{path}.{k}" if path else str(k)
            yield from leaves(v, where) if isinstance(v, dict | list) else [(where, k, v)]
    elif isinstance(node, list):
        for i, v in enumerate(node):
            where = f"{path}[{i}]"
            yield from leaves(v, where) if isinstance(v, dict | list) else [(where, i, v)]


def check_regular_file(key: str, path: Path) -> Path:
    """Return ``path`` if it is a regular file (or a link to one); else a ConfigError saying
    what it is: missing, a directory, or another kind (a FIFO or a device, which reading
    would block on or stream from: issue #39)."""
    if path.is_file():
        return path
    if not path.exists():
        what = "no such file"
    elif path.is_dir():
        what = "is a directory, not a file"
    else:
        what = "is not a regular file (a FIFO, socket or device)"
    raise ConfigError(key, f"{path}: {what}")


def check_choice(key: str, value: Any, allowed: Iterable[str]) -> str:
    """Return ``value`` if it is one of ``allowed``."""
    options = list(allowed)
    if value not in options:
        raise ConfigError(key, f"unknown value {value!r}; allowed: {', '.join(options)}")
    return str(value)


def check_keys(key: str, cfg: Mapping[str, Any], allowed: Iterable[str]) -> None:
    """Reject keys of ``cfg`` not in ``allowed``; the error names ``<key>.<name>`` and the
    options (the first unknown key in the mapping's order)."""
    options = list(allowed)
    for name in cfg:
        if name not in options:
            raise ConfigError(f"{key}.{name}", f"unknown key; allowed: {', '.join(options)}")


def check_vector(key: str, value: Any, dim: int | Sequence[int]) -> np.ndarray:
    """Return ``value`` as a finite float vector whose length is ``dim`` (or one of them)."""
    dims = (dim,) if isinstance(dim, int) else tuple(dim)
    try:
        arr = np.asarray(list(value), dtype=float)
    except (TypeError, ValueError):
        raise ConfigError(key, f"must be a list of {dims} numbers, got {value!r}") from None
    if arr.ndim != 1 or arr.shape[0] not in dims:
        raise ConfigError(key, f"must have length {' or '.join(map(str, dims))}, got {value!r}")
    if not np.all(np.isfinite(arr)):
        raise ConfigError(key, f"must be finite, got {value!r}")
    return arr


#: fields of a component config that name or describe it, never constructor arguments
BOOKKEEPING_KEYS = ("type", "_target_", "name", "description")


def constructor_kwargs(cls: type, cfg: Any, key: str) -> dict[str, Any]:
    """Keyword arguments for ``cls(...)`` from a config mapping, rejecting unknown keys.

    ``type``, ``_target_``, ``name`` (a preset's) and ``description`` are bookkeeping fields
    of a component config and are dropped; ``key`` is reserved for the error prefix.
    """
    import inspect

    allowed = [p for p in inspect.signature(cls.__init__).parameters if p not in ("self", "key")]
    out = {k: v for k, v in dict(cfg).items() if k not in BOOKKEEPING_KEYS}
    check_keys(key, out, allowed)
    return out


def check_bounds(key: str, value: Any) -> tuple[float, float]:
    """A hyperparameter search interval ``(low, high)`` with 0 < low < high, both finite."""
    try:
        lo, hi = (float(v) for v in value)
    except (TypeError, ValueError):
        raise ConfigError(key, f"must be a pair (low, high), got {value!r}") from None
    if not (math.isfinite(lo) and math.isfinite(hi) and 0.0 < lo < hi):
        raise ConfigError(key, f"must satisfy 0 < low < high (finite), got {value!r}")
    return lo, hi


def to_plain(node: Any, key: str | None = None) -> Any:
    """An OmegaConf node as plain Python containers (interpolations resolved); anything else
    as it is. The one converter from config to data.

    With ``key`` the result must be a mapping: ``None`` gives ``{}``, a mapping a new
    ``dict``, and anything else, or an interpolation that does not resolve, a ConfigError
    naming ``key``.
    """
    from omegaconf import OmegaConf
    from omegaconf.errors import OmegaConfBaseException

    if OmegaConf.is_config(node):
        try:
            node = OmegaConf.to_container(node, resolve=True)
        except OmegaConfBaseException as err:
            if key is None:
                raise
            raise ConfigError(key, str(err).splitlines()[0]) from None
    if key is None:
        return node
    if node is None:
        return {}
    if not isinstance(node, Mapping):
        raise ConfigError(key, f"must be a mapping, got {type(node).__name__}")
    return dict(node)


def config_block(cfg: Any, name: str, allowed: Sequence[str]) -> dict[str, Any]:
    """The root config's ``name`` block as a plain dict (interpolations resolved), with
    unknown keys rejected (one line naming ``<name>.<key>``)."""
    block = to_plain(cfg.get(name), name)
    check_keys(name, block, allowed)
    return block
