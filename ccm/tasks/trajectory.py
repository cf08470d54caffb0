"""Target motion patterns P: sequences of smooth pose (and force) target segments.

Seed A (§3, opening) takes the target pattern P as a sequence of mappings from time to
end-effector pose and force, split into segments that are each "smooth, continuous, and
jerk-free"; a change of segment comes with a change in the direction of force/motion control.
The segments and their timing are :mod:`ccm.tasks.segments`;
:class:`ccm.tasks.motion_pattern.MotionPattern` joins them, and :func:`build_pattern` (here)
builds one from its YAML description.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from ccm.core.errors import (
    ConfigError,
    check_bool,
    check_finite,
    check_int_positive,
    check_keys,
    check_nonneg,
    check_positive,
    check_vector,
)
from ccm.core.plugins import accepts_key, available, call_plugin, resolve_class
from ccm.tasks.motion_pattern import MotionPattern
from ccm.tasks.segments import (
    ArcSegment,
    HoldSegment,
    LineSegment,
    Segment,
    unit_vector,
)

#: the built-in segment types as import paths (for :func:`segment_class`'s errors and
#: ``ccm list``); a plugin segment is ``_target_: module:Class`` or a ``ccm.segments`` name
SEGMENTS: dict[str, str] = {
    "line": "ccm.tasks.segments:LineSegment",
    "arc": "ccm.tasks.segments:ArcSegment",
    "hold": "ccm.tasks.segments:HoldSegment",
    "recording": "ccm.tasks.recording:RecordingSegment",
}
_COMMON_KEYS = ("type", "duration", "steps", "force", "name")
_TYPE_KEYS: dict[str, tuple[str, ...]] = {
    "line": ("to", "end_speed"),
    "arc": ("center", "sweep_deg", "normal"),
    "hold": (),
}
#: Keys of a ``recording`` entry (its duration and force come from the file).
_RECORDING_KEYS = ("type", "file", "name", "cutoff_hz", "force_threshold_N", "max_offset_m",
                   "max_speed", "orientation_tol_rad", "use_force", "from", "to")  # fmt: skip
_FORCE_KEYS = ("direction", "magnitude")


def _require(key: str, entry: Mapping[str, Any], name: str) -> Any:
    if name not in entry or entry[name] is None:
        raise ConfigError(f"{key}.{name}", "missing (required)")
    return entry[name]


def _parse_duration(key: str, entry: Mapping[str, Any], control_dt: float) -> float:
    has_dur = entry.get("duration") is not None
    has_steps = entry.get("steps") is not None
    if has_dur == has_steps:
        raise ConfigError(
            key, "give exactly one of 'duration' [s] or 'steps' (control steps), not both/neither"
        )
    if has_dur:
        return check_positive(f"{key}.duration", entry["duration"])
    return check_int_positive(f"{key}.steps", entry["steps"]) * control_dt


def _parse_force(key: str, value: Any, dim: int) -> tuple[np.ndarray | None, float]:
    if value is None:
        return None, 0.0
    if not isinstance(value, Mapping):
        raise ConfigError(key, f"must be a mapping with keys {', '.join(_FORCE_KEYS)}")
    check_keys(key, value, _FORCE_KEYS)
    direction = unit_vector(f"{key}.direction", _require(key, value, "direction"), dim)
    magnitude = check_nonneg(f"{key}.magnitude", _require(key, value, "magnitude"))
    return direction, magnitude


def build_pattern(
    spec: Sequence[Mapping[str, Any]],
    start: Sequence[float] | np.ndarray,
    control_dt: float,
    key: str = "task.pattern",
    *,
    orientation: Sequence[float] | np.ndarray | None = None,
) -> MotionPattern:
    """Build a :class:`MotionPattern` from its YAML description (a list of segment mappings).

    Each segment starts where the previous one ended (the first at ``start``). Entries::

        {type: line, to: [x, y(, z)], duration: 1.0}   # optional end_speed [m/s]
        {type: arc, center: [...], sweep_deg: 360, duration: 6.0}   # 3D: optional normal
        {type: hold, duration: 0.5}
        {type: recording, file: demo.csv}   # a demonstration (ccm.tasks.recording);
                                            # use_force: false drops its force target;
                                            # from/to [s]: a window of the file

    Any entry may give ``steps: N`` instead of ``duration`` (duration = N · control_dt),
    ``force: {direction: [...], magnitude: N}`` (hybrid force-motion target, seed A Eq. 1) and
    ``name``.

    Args:
        spec: the segment list.
        start: pattern start position [m], shape (2,) or (3,).
        control_dt: control period [s] used to convert ``steps``.
        key: configuration key of ``spec``, used in error messages.
        orientation: constant orientation target; default ``[0.0]`` in 2D, required in 3D
            (quaternion x, y, z, w).

    Raises:
        ConfigError: naming the offending key (e.g. ``task.pattern[2].duration``).
    """
    parent = key.rsplit(".", 1)[0] + "." if "." in key else ""
    p = check_vector(f"{parent}start", start, (2, 3))
    dim = p.shape[0]
    control_dt = check_positive("control_dt", control_dt)
    if orientation is None:
        if dim == 3:
            raise ConfigError(
                f"{parent}orientation", "required for 3D patterns (quaternion x, y, z, w)"
            )
        orientation = [0.0]
    if isinstance(spec, str | bytes) or not isinstance(spec, Sequence):
        raise ConfigError(key, f"must be a list of segments, got {type(spec).__name__}")
    if len(spec) == 0:
        raise ConfigError(key, "must contain at least one segment")

    segments: list[Segment] = []
    for i, entry in enumerate(spec):
        seg = _segment(f"{key}[{i}]", entry, p, control_dt)
        segments.append(seg)
        p = seg.end
    return MotionPattern(segments, orientation, key=key)


def _segment(k: str, entry: Any, start: np.ndarray, control_dt: float) -> Segment:
    """One segment of a pattern's YAML list, starting at ``start`` (errors name ``k``)."""
    if not isinstance(entry, Mapping):
        raise ConfigError(k, f"must be a mapping, got {entry!r}")
    kind = entry.get("type")
    if kind is None and entry.get("_target_") is None:
        raise ConfigError(
            f"{k}.type", f"missing; allowed: {', '.join(available('segment', SEGMENTS))}"
        )
    if kind not in SEGMENTS or entry.get("_target_") is not None:
        return _plugin(k, entry, start, control_dt)
    if kind == "recording":
        return _recording(k, entry, start)
    check_keys(k, entry, _COMMON_KEYS + _TYPE_KEYS[kind])
    dim = start.shape[0]
    duration = _parse_duration(k, entry, control_dt)
    force_dir, force_mag = _parse_force(f"{k}.force", entry.get("force"), dim)
    name = None if entry.get("name") is None else str(entry["name"])
    if kind == "line":
        return LineSegment(
            start, _require(k, entry, "to"), duration, force_dir, force_mag, name,
            end_speed=entry.get("end_speed", 0.0), key=k,
        )  # fmt: skip
    if kind == "arc":
        normal = entry.get("normal")
        if normal is not None and dim == 2:
            raise ConfigError(f"{k}.normal", "only allowed for 3D patterns")
        sweep_deg = check_finite(f"{k}.sweep_deg", _require(k, entry, "sweep_deg"))
        return ArcSegment(
            start, _require(k, entry, "center"), math.radians(sweep_deg), duration, normal,
            force_dir, force_mag, name, key=k, sweep_key="sweep_deg",
        )  # fmt: skip
    return HoldSegment(start, duration, force_dir, force_mag, name, key=k)


def segment_class(entry: Mapping[str, Any], key: str) -> tuple[type[Segment], str]:
    """The class of a plugin segment entry (its ``_target_``, or a ``type`` that an installed
    package registers under ``ccm.segments``) and its label; errors name ``key``."""
    return resolve_class("segment", entry, "type", SEGMENTS, key, Segment)


def _plugin(k: str, entry: Mapping[str, Any], start: np.ndarray, control_dt: float) -> Segment:
    """A segment from outside ccm: ``cls(start, duration, force_dir, force_mag, name,
    **params)``, params being the entry's other keys (``key=`` too if it takes one). The
    class subclasses :class:`ccm.tasks.segments.Segment` (it gives ``_coeffs`` and
    ``_coeffs_many`` on a basis and calls ``_finish``)."""
    cls, label = segment_class(entry, k)
    dim = start.shape[0]
    params = {p: v for p, v in entry.items() if p not in (*_COMMON_KEYS, "_target_")}
    force_dir, force_mag = _parse_force(f"{k}.force", entry.get("force"), dim)
    name = None if entry.get("name") is None else str(entry["name"])
    if accepts_key(cls):
        params["key"] = k
    seg = call_plugin(label, k, cls, start.copy(), _parse_duration(k, entry, control_dt),
                      force_dir, force_mag, name, **params)  # fmt: skip
    if not np.allclose(seg.start, start, atol=1e-9):
        raise ConfigError(k, f"plugin {label!r} starts at {seg.start.tolist()}, not where the "
                          f"previous segment ends ({start.tolist()})")  # fmt: skip
    return seg


def _recording(k: str, entry: Mapping[str, Any], start: np.ndarray) -> Segment:
    """A ``{type: recording, file: PATH}`` entry (:mod:`ccm.tasks.recording`)."""
    from ccm.tasks import recording as rs

    check_keys(k, entry, _RECORDING_KEYS)
    path = _require(k, entry, "file")
    if not isinstance(path, str) or not path:
        raise ConfigError(f"{k}.file", f"must be a file path, got {path!r}")

    def opt(name: str, default: float) -> float:
        value = entry.get(name)
        return default if value is None else check_positive(f"{k}.{name}", value)

    smoothed = rs.load_smoothed(
        path, start.shape[0], k, max_speed=opt("max_speed", rs.MAX_SPEED_MPS),
        cutoff_hz=opt("cutoff_hz", rs.CUTOFF_HZ),
    )  # fmt: skip
    window = None
    if entry.get("from") is not None or entry.get("to") is not None:
        t0 = check_nonneg(f"{k}.from", entry.get("from", 0.0))
        t1 = float(smoothed.recording.t[-1]) if entry.get("to") is None else entry["to"]
        window = (t0, check_positive(f"{k}.to", t1))
    return rs.RecordingSegment(
        start, smoothed, window=window,
        use_force=check_bool(f"{k}.use_force", entry.get("use_force", True)),
        force_threshold_N=opt("force_threshold_N", rs.FORCE_THRESHOLD_N),
        max_offset_m=opt("max_offset_m", rs.MAX_OFFSET_M),
        orientation_tol_rad=opt("orientation_tol_rad", rs.ORIENTATION_TOL_RAD),
        name=None if entry.get("name") is None else str(entry["name"]), key=k,
    )  # fmt: skip
