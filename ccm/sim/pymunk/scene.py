"""The 2D scene vocabulary: end-effector, surfaces, boxes, springs and viscous fields.

A scene is plain data, parsed and validated from a mapping (a ``dict`` or an OmegaConf
``DictConfig``). Every invalid value raises :class:`ccm.core.errors.ConfigError` naming the full
dotted key, e.g. ``task.scene.springs[1].stiffness``. Units are SI (metres, kg, seconds);
the world frame has x to the right and y up.

The elements mirror the environments of seed A (Sidhik et al.): surfaces with friction
patches (Fig. 1a, Fig. 8, "changing surface" task), walls and blocks (Fig. 1b), springs
pulling the end-effector (Fig. 1c, "multi-spring") and a viscous medium whose coefficient
changes over time or distance (§4.1, "porridge stirring"). Seed B's (Haninger et al.)
physical-HRI elements -- compliant walls, a simulated human hand and a vibration
disturbance -- are specified in :mod:`ccm.sim.pymunk.hri` and re-exported here.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Any

from ccm.core.errors import (
    ConfigError,
    check_bool,
    check_choice,
    check_finite,
    check_keys,
    check_nonneg,
    check_positive,
    check_restitution,
    to_plain,
)
from ccm.core.fields import checked, field_values, nested
from ccm.sim.pymunk.hri import CompliantWallSpec, HumanSpec, VibrationSpec
from ccm.sim.pymunk.parse import (
    RegionSpec,
    Vec2,
    as_list,
    positive_vec2,
    vec2,
)

# --------------------------------------------------------------------------- elements


@dataclass(frozen=True)
class EESpec:
    """The end-effector: a box driven by a task-space force (seed A Eq. 1, u_t).

    Attributes:
        size: box width and height [m].
        mass: [kg], > 0.
        rotate: if False (default) the rotation is locked (infinite moment of inertia).
    """

    size: Vec2 = checked(positive_vec2, (0.05, 0.05))
    mass: float = checked(check_positive, 1.0)
    rotate: bool = checked(check_bool, False)

    @classmethod
    def from_mapping(cls, cfg: Any, key: str) -> EESpec:
        return cls(**field_values(cls, cfg, key)[0])


@dataclass(frozen=True)
class Patch:
    """A stretch of a surface with its own friction (seed A Fig. 1a, surface change).

    Attributes:
        start: distance along the segment from its point ``a`` where the patch begins [m]
            (config key ``from``).
        end: distance from ``a`` where it ends [m] (config key ``to``).
        friction: Coulomb friction coefficient on the patch, >= 0.
    """

    start: float
    end: float
    friction: float


@dataclass(frozen=True)
class SurfaceSpec:
    """A static line segment from ``a`` to ``b`` (a table top, a wall face).

    Attributes:
        a, b: endpoints [m].
        friction: Coulomb coefficient outside the patches (default 0.5).
        restitution: coefficient of restitution in [0, 1] (default 0.0, no bounce).
        radius: segment thickness radius [m] (default 0.002).
        patches: non-overlapping stretches with other friction, sorted by ``start``.
    """

    a: Vec2 = checked(vec2, required="is required (segment endpoint [x, y] in m)")
    b: Vec2 = checked(vec2, required="is required (segment endpoint [x, y] in m)")
    friction: float = checked(check_nonneg, 0.5)
    restitution: float = checked(check_restitution, 0.0)
    radius: float = checked(check_nonneg, 0.002)
    patches: tuple[Patch, ...] = ()

    @property
    def length(self) -> float:
        return float(((self.b[0] - self.a[0]) ** 2 + (self.b[1] - self.a[1]) ** 2) ** 0.5)

    def pieces(self) -> list[tuple[float, float, float]]:
        """Split the segment into consecutive ``(s0, s1, friction)`` pieces along its length."""
        out: list[tuple[float, float, float]] = []
        s = 0.0
        for p in self.patches:
            if p.start > s:
                out.append((s, p.start, self.friction))
            out.append((p.start, p.end, p.friction))
            s = p.end
        if self.length > s:
            out.append((s, self.length, self.friction))
        return out

    @classmethod
    def from_mapping(cls, cfg: Any, key: str) -> SurfaceSpec:
        values, d = field_values(cls, cfg, key)
        surf = cls(**values)
        if surf.length <= 0.0:
            raise ConfigError(f"{key}.b", "must differ from a (zero-length segment)")
        patches: list[Patch] = []
        for i, pcfg in enumerate(as_list(f"{key}.patches", d.get("patches"))):
            pk = f"{key}.patches[{i}]"
            pd = to_plain(pcfg, pk)
            check_keys(pk, pd, ("from", "to", "friction"))
            for req in ("from", "to", "friction"):
                if req not in pd:
                    raise ConfigError(f"{pk}.{req}", "is required")
            s0 = check_nonneg(f"{pk}.from", pd["from"])
            s1 = check_finite(f"{pk}.to", pd["to"])
            if not s0 < s1 <= surf.length + 1e-12:
                raise ConfigError(
                    f"{pk}.to", f"must satisfy from < to <= segment length {surf.length:.6g} m"
                )
            mu = check_nonneg(f"{pk}.friction", pd["friction"])
            patches.append(Patch(start=s0, end=min(s1, surf.length), friction=mu))
        patches.sort(key=lambda p: p.start)
        for prev, nxt in zip(patches, patches[1:], strict=False):
            if nxt.start < prev.end:
                raise ConfigError(f"{key}.patches", f"patches overlap at {nxt.start:.6g} m")
        return dataclasses.replace(surf, patches=tuple(patches))


@dataclass(frozen=True)
class BoxSpec:
    """A static axis-aligned block (a wall or an obstacle, seed A Fig. 1b).

    Attributes:
        center: [m]; size: width and height [m];
        friction: Coulomb coefficient (default 0.5); restitution: in [0, 1] (default 0.0).
    """

    center: Vec2 = checked(vec2)
    size: Vec2 = checked(positive_vec2)
    friction: float = checked(check_nonneg, 0.5)
    restitution: float = checked(check_restitution, 0.0)

    @classmethod
    def from_mapping(cls, cfg: Any, key: str) -> BoxSpec:
        return cls(**field_values(cls, cfg, key)[0])


@dataclass(frozen=True)
class SpringSpec:
    """A linear spring from a fixed anchor to the end-effector centre (seed A Fig. 1c).

    The force on the end-effector is ``F = -k (|d| - L0) d / |d|`` with ``d = p_ee - anchor``,
    while the spring is attached: from ``attach_s`` (simulated time since the reset) until
    ``detach_s``. A spring that attaches while stretched makes the external force jump, an
    environment change within one contact mode.

    Attributes:
        anchor: [m]; stiffness: k [N/m] > 0; rest_length: L0 [m] >= 0 (default 0);
        attach_s: [s] >= 0 (default 0, attached from the start); detach_s: [s] > attach_s,
        or None (default: never detaches).
    """

    anchor: Vec2 = checked(vec2)
    stiffness: float = checked(check_positive)
    rest_length: float = checked(check_nonneg, 0.0)
    attach_s: float = checked(check_nonneg, 0.0)
    detach_s: float | None = checked(check_positive, None)

    @property
    def scheduled(self) -> bool:
        """True if the spring attaches after the start or detaches at some time."""
        return self.attach_s > 0.0 or self.detach_s is not None

    @classmethod
    def from_mapping(cls, cfg: Any, key: str) -> SpringSpec:
        spec = cls(**field_values(cls, cfg, key)[0])
        if spec.detach_s is not None and spec.detach_s <= spec.attach_s:
            raise ConfigError(
                f"{key}.detach_s", f"must be > attach_s={spec.attach_s!r}, got {spec.detach_s!r}"
            )
        return spec


_SCHEDULE_KEYS = {
    "constant": ("kind", "value"),
    "ramp_per_step": ("kind", "start", "end", "rate"),
    "ramp_per_distance": ("kind", "start", "end", "rate"),
}


@dataclass(frozen=True)
class ScheduleSpec:
    """How a viscous coefficient c [N s/m] evolves (seed A §4.1, changing viscosity).

    Kinds:
        ``constant``: ``c = value``.
        ``ramp_per_step``: ``c = start + rate * n`` with ``n`` physics steps since reset,
            clipped to the interval between ``start`` and ``end``.
        ``ramp_per_distance``: ``c = start + rate * s`` with ``s`` the end-effector's path
            length since reset [m], clipped likewise.

    A negative ``rate`` ramps down; its sign must agree with ``end - start``.
    """

    kind: str
    start: float
    end: float
    rate: float = 0.0

    def coefficient(self, steps: int, distance: float) -> float:
        """Coefficient [N s/m] after ``steps`` physics steps and ``distance`` metres of travel."""
        if self.kind == "constant":
            return self.start
        x = steps if self.kind == "ramp_per_step" else distance
        c = self.start + self.rate * x
        lo, hi = (self.start, self.end) if self.start <= self.end else (self.end, self.start)
        return min(max(c, lo), hi)

    @classmethod
    def from_mapping(cls, cfg: Any, key: str) -> ScheduleSpec:
        d = to_plain(cfg, key)
        kind = check_choice(f"{key}.kind", d.get("kind"), _SCHEDULE_KEYS)
        check_keys(key, d, _SCHEDULE_KEYS[kind])
        for req in _SCHEDULE_KEYS[kind][1:]:
            if req not in d:
                raise ConfigError(f"{key}.{req}", f"is required for kind {kind!r}")
        if kind == "constant":
            v = check_nonneg(f"{key}.value", d["value"])
            return cls(kind=kind, start=v, end=v)
        start = check_nonneg(f"{key}.start", d["start"])
        end = check_nonneg(f"{key}.end", d["end"])
        rate = check_finite(f"{key}.rate", d["rate"])
        if (end - start) * rate < 0.0:
            raise ConfigError(f"{key}.rate", f"sign must agree with end - start, got rate={rate!r}")
        return cls(kind=kind, start=start, end=end, rate=rate)


@dataclass(frozen=True)
class ViscousSpec:
    """A viscous field: inside ``region`` (everywhere if ``None``) the EE feels ``F = -c v``."""

    schedule: ScheduleSpec = checked(nested(ScheduleSpec.from_mapping))
    region: RegionSpec | None = checked(nested(RegionSpec.from_mapping), None)

    @classmethod
    def from_mapping(cls, cfg: Any, key: str) -> ViscousSpec:
        return cls(**field_values(cls, cfg, key)[0])


@dataclass(frozen=True)
class SceneSpec:
    """A whole 2D scene.

    Attributes:
        gravity: magnitude along -y [m/s^2] (default 0.0: a top-down planar world).
        ee: the end-effector.
        surfaces, boxes, springs, viscous: the scene elements (each may be empty).
        compliant_walls, human, vibration: seed B's physical-HRI elements
            (:mod:`ccm.sim.pymunk.hri`; empty / ``None`` when absent).
    """

    gravity: float = 0.0
    ee: EESpec = field(default_factory=EESpec)
    surfaces: tuple[SurfaceSpec, ...] = ()
    boxes: tuple[BoxSpec, ...] = ()
    springs: tuple[SpringSpec, ...] = ()
    viscous: tuple[ViscousSpec, ...] = ()
    compliant_walls: tuple[CompliantWallSpec, ...] = ()
    human: HumanSpec | None = None
    vibration: VibrationSpec | None = None

    @property
    def has_hri(self) -> bool:
        """True if the scene has any of the seed-B elements (walls, human, vibration)."""
        return bool(self.compliant_walls) or self.human is not None or self.vibration is not None

    @classmethod
    def from_mapping(cls, cfg: Any, prefix: str = "task.scene") -> SceneSpec:
        """Parse and validate a scene mapping; keys in errors start with ``prefix``."""
        d = to_plain(cfg, prefix)
        check_keys(prefix, d, (
            "gravity", "ee", "surfaces", "boxes", "springs", "viscous", "compliant_walls",
            "human", "vibration",
        ))  # fmt: skip

        def parse_list(name: str, parser: Any) -> tuple[Any, ...]:
            items = as_list(f"{prefix}.{name}", d.get(name))
            return tuple(parser(c, f"{prefix}.{name}[{i}]") for i, c in enumerate(items))

        def parse_opt(name: str, parser: Any) -> Any:
            return None if d.get(name) is None else parser(d[name], f"{prefix}.{name}")

        return cls(
            gravity=check_nonneg(f"{prefix}.gravity", d.get("gravity", 0.0)),
            ee=EESpec.from_mapping(d.get("ee"), f"{prefix}.ee"),
            surfaces=parse_list("surfaces", SurfaceSpec.from_mapping),
            boxes=parse_list("boxes", BoxSpec.from_mapping),
            springs=parse_list("springs", SpringSpec.from_mapping),
            viscous=parse_list("viscous", ViscousSpec.from_mapping),
            compliant_walls=parse_list("compliant_walls", CompliantWallSpec.from_mapping),
            human=parse_opt("human", HumanSpec.from_mapping),
            vibration=parse_opt("vibration", VibrationSpec.from_mapping),
        )


def parse_scene(cfg: Any, prefix: str = "task.scene") -> SceneSpec:
    """Parse a scene mapping (dict or ``DictConfig``); see :meth:`SceneSpec.from_mapping`."""
    return SceneSpec.from_mapping(cfg, prefix)
