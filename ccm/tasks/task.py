"""Tasks: a scene description plus a target motion pattern P, loaded from YAML (``configs/task``).

A task says *what* the robot must do (seed A §3: the target pattern P of pose and force targets)
and *where* (the scene: surfaces, springs, viscous fields…). The scene is passed through as a
plain mapping; the simulator validates it. This module must not import ``ccm.sim`` or
``ccm.control`` (imports point one way: tasks never import control).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from omegaconf import DictConfig

from ccm.core.errors import ConfigError, check_choice, check_keys, check_vector, to_plain
from ccm.tasks.motion_pattern import MotionPattern
from ccm.tasks.trajectory import build_pattern

__all__ = ["CONTACT_KINDS", "TASK_KEYS", "Task", "load_task"]

#: Top-level keys a task mapping may hold.
TASK_KEYS: tuple[str, ...] = (
    "name",
    "description",
    "dim",
    "start",
    "orientation",
    "scene",
    "pattern",
    "params",
    "contacts",
)
_REQUIRED = ("name", "dim", "start", "scene", "pattern")
#: Kinds of expected contact (seed A §3.3): a collision, or a change of surface without impact.
CONTACT_KINDS: tuple[str, ...] = ("collision", "impactless")
_CONTACT_KEYS = ("name", "position", "kind", "segment", "normal")
_CONTACT_REQUIRED = ("name", "position", "kind")


@dataclass
class Task:
    """A changing-contact task: scene plus target motion pattern.

    Attributes:
        name: task identifier (e.g. ``porridge_stirring``).
        dim: task-space dimension, 2 (planar world) or 3.
        start: end-effector start position, world frame [m], shape (dim,).
        scene: simulator scene description (validated by the simulator, not here).
        pattern: the target motion pattern P (seed A §3).
        description: one-line human description.
        params: task-specific extras that are not part of the scene or pattern (e.g. the
            viscosity ramps of seed A §4.1), passed through unvalidated.
        contacts: the *expected* contacts of the pattern, in the order it meets them: plain
            dicts ``{"name": str, "position": tuple of dim floats [m], "kind": "collision" |
            "impactless"}``. They stand in for a vision system's estimates (seed A §3.3,
            Table 1): nominal positions a controller may use (noise is added elsewhere, from a
            seeded generator), never ground truth, which stays in the scene. The mapping form
            is what :meth:`ccm.learn.contact.contacts.ContactMap.from_config` takes.
        contact_annotations: one dict per entry of ``contacts`` (same order) with the optional
            keys ``segment`` and ``normal`` of that entry, for metrics (seed A §4.5.1, Fig. 16;
            :mod:`ccm.metrics.contacts`): ``{"segment": name or None, "segment_index": index of
            that segment in ``pattern`` or None, "normal": unit tuple of dim floats or None}``.
            ``normal`` is the outward surface normal, i.e. the direction of the contact force
            on the end-effector; ``segment`` names the pattern segment during which the
            contact is made. They are kept apart from ``contacts`` so that what a controller
            is told stays the vision stand-in (``ContactMap.from_config`` takes only
            ``name``, ``position`` and ``kind``).
    """

    name: str
    dim: int
    start: np.ndarray
    scene: dict[str, Any]
    pattern: MotionPattern
    description: str = ""
    params: dict[str, Any] = field(default_factory=dict)
    contacts: tuple[dict[str, Any], ...] = ()
    contact_annotations: tuple[dict[str, Any], ...] = ()

    @property
    def duration(self) -> float:
        """Duration of the target pattern [s]."""
        return self.pattern.duration


def _required_and_name(key: str, cfg: Mapping[str, Any], required: tuple[str, ...]) -> str:
    """Check that every ``required`` key of ``cfg`` is set; return its non-empty ``name``."""
    for req in required:
        if cfg.get(req) is None:
            raise ConfigError(f"{key}.{req}", "missing (required)")
    name = cfg["name"]
    if not isinstance(name, str) or not name:
        raise ConfigError(f"{key}.name", f"must be a non-empty string, got {name!r}")
    return name


def _segment_index(key: str, value: Any, segment_names: Sequence[str | None]) -> int:
    """Index of the pattern segment named ``value`` (it must name exactly one segment)."""
    if not isinstance(value, str) or not value:
        raise ConfigError(key, f"must be a non-empty segment name, got {value!r}")
    hits = [i for i, n in enumerate(segment_names) if n == value]
    named = ", ".join(repr(n) for n in segment_names if n)
    if not hits:
        raise ConfigError(key, f"unknown pattern segment {value!r}; segments: {named or 'none'}")
    if len(hits) > 1:
        raise ConfigError(key, f"segment name {value!r} names {len(hits)} pattern segments")
    return hits[0]


def _unit_normal(key: str, value: Any, dim: int) -> tuple[float, ...]:
    """A nonzero ``dim``-vector, normalised."""
    n = check_vector(key, value, dim)
    norm = float(np.linalg.norm(n))
    if norm < 1e-12:
        raise ConfigError(key, f"must be a nonzero vector, got {n.tolist()}")
    return tuple(float(v) for v in n / norm)


def _load_contacts(
    key: str, value: Any, dim: int, segment_names: Sequence[str | None] = ()
) -> tuple[tuple[dict[str, Any], ...], tuple[dict[str, Any], ...]]:
    """Validate the optional ``contacts`` list (see :class:`Task`); errors name the entry.

    Returns ``(contacts, contact_annotations)``; ``segment_names`` are the names of the
    pattern's segments (None for an unnamed one), against which ``segment`` is checked.
    """
    if value is None:
        return (), ()
    if isinstance(value, str | bytes | Mapping) or not isinstance(value, list | tuple):
        raise ConfigError(key, f"must be a list of {{{', '.join(_CONTACT_KEYS)}}}, got {value!r}")
    out: list[dict[str, Any]] = []
    notes: list[dict[str, Any]] = []
    seen: set[str] = set()
    for i, entry in enumerate(value):
        k = f"{key}[{i}]"
        if not isinstance(entry, Mapping):
            raise ConfigError(k, f"must be a mapping with keys {', '.join(_CONTACT_KEYS)}")
        check_keys(k, entry, _CONTACT_KEYS)
        name = _required_and_name(k, entry, _CONTACT_REQUIRED)
        if name in seen:
            raise ConfigError(f"{k}.name", f"duplicate contact name {name!r}")
        seen.add(name)
        position = check_vector(f"{k}.position", entry["position"], dim)
        kind = check_choice(f"{k}.kind", entry["kind"], CONTACT_KINDS)
        out.append({"name": name, "position": tuple(float(v) for v in position), "kind": kind})
        segment = entry.get("segment")
        normal = entry.get("normal")
        notes.append(
            {
                "segment": None if segment is None else str(segment),
                "segment_index": None
                if segment is None
                else _segment_index(f"{k}.segment", segment, segment_names),
                "normal": None if normal is None else _unit_normal(f"{k}.normal", normal, dim),
            }
        )
    return tuple(out), tuple(notes)


def load_task(
    task_cfg: Mapping[str, Any] | DictConfig, control_dt: float, key: str = "task"
) -> Task:
    """Build a :class:`Task` from its configuration mapping (the Hydra ``task`` group).

    Args:
        task_cfg: dict or OmegaConf ``DictConfig`` with keys ``name``, ``description``,
            ``dim`` (2 or 3), ``start``, ``orientation`` (default ``[0.0]`` in 2D; a quaternion
            x, y, z, w is required in 3D), ``scene``, ``pattern`` and optional ``params`` and
            ``contacts`` (see :class:`Task`).
            Interpolations are resolved.
        control_dt: control period [s], used for pattern segments given in ``steps``.
        key: configuration key of ``task_cfg`` for error messages.

    Raises:
        ConfigError: on unknown or missing keys and invalid values, naming the full key.
    """
    cfg = to_plain(task_cfg, key)
    check_keys(key, cfg, TASK_KEYS)
    name = _required_and_name(key, cfg, _REQUIRED)
    description = cfg.get("description") or ""
    if not isinstance(description, str):
        raise ConfigError(f"{key}.description", f"must be a string, got {description!r}")
    dim = cfg["dim"]
    if isinstance(dim, bool) or dim not in (2, 3):
        raise ConfigError(f"{key}.dim", f"unknown value {dim!r}; allowed: 2, 3")
    dim = int(dim)
    start = check_vector(f"{key}.start", cfg["start"], dim)
    scene = cfg["scene"]
    if not isinstance(scene, Mapping):
        raise ConfigError(f"{key}.scene", f"must be a mapping, got {type(scene).__name__}")
    params = cfg.get("params") or {}
    if not isinstance(params, Mapping):
        raise ConfigError(f"{key}.params", f"must be a mapping, got {type(params).__name__}")
    orientation = cfg.get("orientation")
    if orientation is not None:
        check_vector(f"{key}.orientation", orientation, 1 if dim == 2 else 4)

    pattern = build_pattern(
        cfg["pattern"], start, control_dt, key=f"{key}.pattern", orientation=orientation
    )
    contacts, notes = _load_contacts(
        f"{key}.contacts", cfg.get("contacts"), dim, [s.name for s in pattern.segments]
    )
    return Task(
        name=name,
        dim=dim,
        start=start,
        scene=dict(scene),
        pattern=pattern,
        description=description,
        params=dict(params),
        contacts=contacts,
        contact_annotations=notes,
    )
