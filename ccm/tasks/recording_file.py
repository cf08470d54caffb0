"""Reading and checking a demonstration file for the ``recording`` pattern segment.

Seed A (§3) obtains the target pattern P from a kinesthetic demonstration; seed B learns
from a few demonstrations. A demonstration file is a table, one row per sample:

=============================  ==========================================================
column                         meaning
=============================  ==========================================================
``t``                          time [s], strictly increasing (any origin)
``x``, ``y`` (3D: ``z``)       end-effector position, world frame [m]
``fx``, ``fy`` (3D: ``fz``)    optional: force the tool exerts *on the environment* [N]
``theta`` (3D: ``qx`` ..       optional: orientation (2D angle [rad]; 3D quaternion
``qw``)                        x, y, z, w)
=============================  ==========================================================

Other columns are ignored. Formats, by file suffix: ``.csv``, ``.parquet``/``.pq``,
``.json`` (an object of equal-length column arrays, or a list of row objects) and ``.npz``
(one array per column, loaded with ``allow_pickle=False``). Pickle is never read.

Every problem is one :class:`ccm.core.errors.ConfigError` line naming the file and, for a
value, the row: rows count data rows from 1 (a CSV's header line excluded).
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ccm.core.errors import ConfigError, check_regular_file

#: Fewest rows a recording may have (the smoothing spline needs several per knot span).
MIN_ROWS = 10
#: Default speed above which two consecutive samples count as a jump [m/s]: the Franka
#: Panda's Cartesian translation limit (1.7 m/s), the arm of the 3D simulator.
MAX_SPEED_MPS = 1.7

_POS = {2: ("x", "y"), 3: ("x", "y", "z")}
_FORCE = {2: ("fx", "fy"), 3: ("fx", "fy", "fz")}
_ORIENT = {2: ("theta",), 3: ("qx", "qy", "qz", "qw")}


@dataclass(frozen=True)
class Recording:
    """A checked demonstration: times from 0, positions and (optionally) forces.

    Attributes:
        path: the file it came from.
        t: times [s] from 0, strictly increasing, shape (N,).
        position: [m], shape (N, dim).
        force: force on the environment [N], shape (N, dim), or ``None``.
        orientation: 2D angle (N, 1) or 3D quaternion (N, 4), or ``None``.
    """

    path: Path
    t: np.ndarray
    position: np.ndarray
    force: np.ndarray | None
    orientation: np.ndarray | None


def _columns(path: Path, key: str) -> dict[str, np.ndarray]:
    """The file's columns as float arrays (non-numbers become NaN, caught by the checks)."""
    suffix = path.suffix.lower()
    try:
        if suffix in (".csv", ".parquet", ".pq"):
            import pandas as pd

            frame = pd.read_csv(path) if suffix == ".csv" else pd.read_parquet(path)
            return {str(c): pd.to_numeric(frame[c], errors="coerce").to_numpy(float)
                    for c in frame.columns}  # fmt: skip
        if suffix == ".json":
            data = json.loads(path.read_text())
            if isinstance(data, list):  # a list of row objects
                names = {n for row in data if isinstance(row, dict) for n in row}
                data = {n: [r.get(n) if isinstance(r, dict) else None for r in data] for n in names}
            if not isinstance(data, dict):
                raise ConfigError(key, f"{path}: JSON must be an object of column arrays")
            return {str(n): _numeric(v) for n, v in data.items()}
        if suffix == ".npz":
            with np.load(path, allow_pickle=False) as npz:
                return {n: np.asarray(npz[n], dtype=float).reshape(-1) for n in npz.files}
    except ConfigError:
        raise
    except (OSError, ValueError, TypeError) as exc:
        first = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise ConfigError(key, f"{path}: cannot read ({first})") from None
    raise ConfigError(
        key, f"{path}: unknown format {suffix!r}; allowed: .csv, .parquet, .pq, .json, .npz"
    )


def _numeric(values: object) -> np.ndarray:
    """A JSON column as floats; anything that is not a number becomes NaN."""
    seq = values if isinstance(values, list) else [values]
    out = [float(v) if isinstance(v, int | float) and not isinstance(v, bool) else np.nan
           for v in seq]  # fmt: skip
    return np.asarray(out, dtype=float)


def _take(path: Path, key: str, cols: dict[str, np.ndarray], names: tuple[str, ...],
          n: int) -> np.ndarray:  # fmt: skip
    """Stack the named columns (N, len(names)); NaN/inf name the first bad row."""
    missing = [c for c in names if c not in cols]
    if missing:
        have = ", ".join(sorted(cols)) or "none"
        raise ConfigError(key, f"{path}: missing column(s) {', '.join(missing)} (has: {have})")
    out = np.column_stack([cols[c] for c in names])
    if out.shape[0] != n:
        raise ConfigError(key, f"{path}: columns differ in length ({out.shape[0]} vs {n} rows)")
    bad = ~np.isfinite(out)
    if bad.any():
        row, col = (int(v) for v in np.argwhere(bad)[0])
        unit = " (seconds from the start, not a date or clock time)" if names[col] == "t" else ""
        raise ConfigError(
            key, f"{path}: row {row + 1}: column {names[col]} is not a finite number{unit}"
        )
    return out


def _optional(path: Path, key: str, cols: dict[str, np.ndarray], names: tuple[str, ...],
              n: int) -> np.ndarray | None:  # fmt: skip
    """The named columns if the file has any of them (then it must have all)."""
    if not any(c in cols for c in names):
        return None
    return _take(path, key, cols, names, n)


#: the sampling steps a demonstration may have [s]: 100 kHz (above any F/T sensor's rate) to
#: 10 Hz (slower misses a contact's transient altogether); issue #39: a time column in
#: milliseconds passed as seconds was caught only by the smoothing's cut-off, named instead
STEP_RANGE_S = (1e-5, 0.1)


def _check_time(path: Path, key: str, t: np.ndarray) -> None:
    step = np.diff(t)
    median = float(np.median(step))
    low, high = STEP_RANGE_S
    if not low <= median <= high:
        hint = " (milliseconds? t is in seconds)" if median > high else ""
        raise ConfigError(
            key, f"{path}: column t steps by {median:.4g} s (median); a recording is sampled "
            f"every {low:g} to {high:g} s{hint}",
        )  # fmt: skip
    bad = np.flatnonzero(step <= 0.0)
    if bad.size:
        i = int(bad[0]) + 1
        raise ConfigError(
            key,
            f"{path}: row {i + 1}: time does not increase "
            f"(t = {t[i]:.6g} s after {t[i - 1]:.6g} s)",
        )


def _check_speed(path: Path, key: str, t: np.ndarray, p: np.ndarray, max_speed: float) -> None:
    speed = np.linalg.norm(np.diff(p, axis=0), axis=1) / np.diff(t)
    bad = np.flatnonzero(speed > max_speed)
    if bad.size:
        i = int(bad[0]) + 1
        raise ConfigError(
            key,
            f"{path}: row {i + 1}: position jumps at {speed[i - 1]:.4g} m/s from the row before, "
            f"above the limit of {max_speed:.4g} m/s (max_speed)",
        )


#: Prefix of a path inside ccm's config directory (``configs/``; ``ccm/_configs`` in a wheel).
PACKAGE_PREFIX = "ccm://"


def resolve_path(path: str | Path) -> Path:
    """A recording's path: absolute as given; ``ccm://demos/x.csv`` inside ccm's config
    directory (where the repository's demonstrations live, shipped with the package); any
    other relative path from the current working directory (ccm never changes directory,
    so it is where the command was started)."""
    text = str(path)
    if not text.startswith(PACKAGE_PREFIX):
        return Path(text)
    package = Path(__file__).resolve().parents[1]  # the ccm package
    configs = package / "_configs"
    root = configs if configs.is_dir() else package.parent / "configs"
    return root / text[len(PACKAGE_PREFIX) :]


def read_recording(
    path: str | Path, dim: int, key: str, *, max_speed: float = MAX_SPEED_MPS
) -> Recording:
    """Read and check a demonstration file (format: see the module docstring).

    Args:
        path: the file (:func:`resolve_path`).
        dim: the task's dimension, 2 or 3 (which position/force columns are required).
        key: configuration key for error messages (e.g. ``task.pattern[0].file``).
        max_speed: consecutive samples further apart than ``max_speed`` x their time step
            are a jump [m/s].

    Raises:
        ConfigError: one line naming the file (and the row) for a missing file or column,
            too few rows, a value that is not a finite number, a time that does not
            increase, or a jump above ``max_speed``.
    """
    p = check_regular_file(key, resolve_path(path))
    cols = _columns(p, key)
    if "t" not in cols:
        raise ConfigError(key, f"{p}: missing column t (has: {', '.join(sorted(cols)) or 'none'})")
    n = cols["t"].shape[0]
    if dim == 2 and "z" in cols:
        raise ConfigError(key, f"{p}: has a z column but the task is 2D")
    t = _take(p, key, cols, ("t",), n)[:, 0]
    position = _take(p, key, cols, _POS[dim], n)
    if n < MIN_ROWS:
        raise ConfigError(key, f"{p}: {n} rows; a recording needs at least {MIN_ROWS}")
    force = _optional(p, key, cols, _FORCE[dim], n)
    orientation = _optional(p, key, cols, _ORIENT[dim], n)
    _check_time(p, key, t)
    _check_speed(p, key, t, position, max_speed)
    return Recording(p, t - t[0], position, force, orientation)
