"""The settings of seed B's GP-MPC problem (the ``controller.mpc`` block), parsed once.

Every setting is a typed field of :class:`MPCSettings`; the field list is also the list of
allowed keys. :meth:`MPCSettings.parse` checks the whole block with the ``check_*`` helpers, so
each bad value gets one line that names its key. The controller parses the block at start-up,
before any demonstration exists, and :class:`ccm.control.mpc.problem.GPMPCProblem` builds
Eq. 13 from the parsed settings.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, fields
from typing import Any

import numpy as np

from ccm.control.mpc.terms import chance_quantile
from ccm.core.errors import (
    ConfigError,
    check_bounds,
    check_choice,
    check_int_positive,
    check_keys,
    check_nonneg,
    check_positive,
)


@dataclass(frozen=True)
class Weights:
    """Cost weights of Eq. 14 (diagonal Q's; scalars apply to every DOF).

    Attributes:
        vel: Q_μ on velocity ("just a small penalty on velocity", seed B §4.2.1).
        pos_var, vel_var: Q_Σ on the position and velocity variances (trace form, §5.2).
        force: Q_f on the GP mean force μ^f; with ``force_cost: human_match`` the Q_H of
            seed B §4.2.1's (μ^f + f^r)ᵀ Q_H (μ^f + f^r).
        force_var: Q_Σ,f on the GP variance Σ^f.
        f_ref: Q_u on f^r.
        delta_mass, delta_damping: Q_u on ΔM, ΔD.
        f_ref_target: weight on ‖f_target − f^r‖² (seed B §6.2's "‖15 − f^r_2‖" cost).
        joint_torque: Q_τ of Eq. 15 (0 = off).
        disturbance: weight on ‖X^d‖²₂ of Eq. 16 per DOF (0 = off).
    """

    vel: float = 1.0
    pos_var: float = 0.0
    vel_var: float = 0.0
    force: float = 0.0
    force_var: float = 0.0
    f_ref: float = 0.0
    delta_mass: float = 0.0
    delta_damping: float = 0.0
    f_ref_target: float = 0.0
    joint_torque: float = 0.0
    disturbance: float = 0.0


@dataclass(frozen=True)
class JointTorque:
    """The human arm of Eq. 11: shoulder position and link lengths [m], the TCP height z [m]
    that pads a 2-D pose, and which ẋ weights f_H = D ẋ (seed B §4.2.2): ``measured`` (the
    state's velocity at the solve, a parameter, so D is the lever) or ``predicted`` (the plan's
    own velocity, a decision variable)."""

    shoulder: np.ndarray
    l1: float
    l2: float
    z: float
    velocity: str = "measured"


@dataclass(frozen=True)
class MPCSettings:
    """The ``controller.mpc`` block (argument meanings: :class:`GPMPCProblem`).

    ``chance`` is (f_max [N], the Eq. 18 quantile); ``well_damped`` is (ζ, the fixed K_e
    [N/m] or None for the GP gradient); ``disturbance`` is (α, ω_p [rad/s]) when its weight
    is on.
    """

    horizon: int = 10
    ts: float = 0.02
    mass_bounds: tuple[float, float] = (5.0, 60.0)
    damping_bounds: tuple[float, float] = (500.0, 5000.0)
    delta_mass_max: float = 5.0
    delta_damping_max: float = 500.0
    f_ref_max: float = 30.0
    f_ref_rate_max: float = 10.0
    f_ref_target: Any = 0.0
    force_cost: str = "mean"
    weights: Weights = field(default_factory=Weights)
    continuity_slack: float = 0.0
    gp_var_scale: float = 1.0
    chance: tuple[float, float] | None = None
    well_damped: tuple[float, float | None] | None = None
    disturbance: tuple[float, float] | None = None
    joint_torque: JointTorque | None = None
    ipopt: Mapping[str, Any] = field(default_factory=dict)
    codegen: str | None = None

    @classmethod
    def parse(cls, cfg: Mapping[str, Any], key: str = "controller.mpc") -> MPCSettings:
        """Check a ``controller.mpc`` mapping (``weights`` may be a :class:`Weights`)."""
        only(key, cfg, [f.name for f in fields(cls)])
        get = cfg.get
        mass = check_bounds(f"{key}.mass_bounds", get("mass_bounds", (5.0, 60.0)))
        if mass[0] <= 0:
            raise ConfigError(f"{key}.mass_bounds", "minimum mass must be > 0")
        weights = _weights(get("weights"), f"{key}.weights")
        target = np.asarray(get("f_ref_target", 0.0), dtype=float)
        if not np.all(np.isfinite(target)):
            raise ConfigError(f"{key}.f_ref_target", f"must be finite, got {target.tolist()!r}")
        return cls(
            horizon=check_int_positive(f"{key}.horizon", get("horizon", 10)),
            ts=check_positive(f"{key}.ts", get("ts", 0.02)),
            mass_bounds=mass,
            damping_bounds=check_bounds(
                f"{key}.damping_bounds", get("damping_bounds", (500.0, 5000.0))
            ),
            delta_mass_max=check_nonneg(f"{key}.delta_mass_max", get("delta_mass_max", 5.0)),
            delta_damping_max=check_nonneg(
                f"{key}.delta_damping_max", get("delta_damping_max", 500.0)
            ),
            f_ref_max=check_positive(f"{key}.f_ref_max", get("f_ref_max", 30.0)),
            f_ref_rate_max=check_positive(f"{key}.f_ref_rate_max", get("f_ref_rate_max", 10.0)),
            f_ref_target=get("f_ref_target", 0.0),
            force_cost=check_choice(
                f"{key}.force_cost", get("force_cost", "mean"), ("mean", "human_match")
            ),
            weights=weights,
            continuity_slack=check_nonneg(f"{key}.continuity_slack", get("continuity_slack", 0.0)),
            gp_var_scale=check_positive(f"{key}.gp_var_scale", get("gp_var_scale", 1.0)),
            chance=_chance(get("chance"), f"{key}.chance"),
            well_damped=_well_damped(get("well_damped"), f"{key}.well_damped"),
            disturbance=_disturbance(get("disturbance"), weights, f"{key}.disturbance"),
            joint_torque=_joint_torque(get("joint_torque"), weights, f"{key}.joint_torque"),
            ipopt=dict(get("ipopt") or {}),
            codegen=get("codegen"),
        )


def only(key: str, block: Any, allowed: Sequence[str]) -> None:
    """Reject keys of an option block that are not in ``allowed``."""
    if not isinstance(block, Mapping):
        raise ConfigError(key, f"must be a mapping with keys {', '.join(allowed)}")
    check_keys(key, block, allowed)


def vector(key: str, value: Any, n: int) -> np.ndarray:
    """``value`` (one number or ``n``) broadcast to (n,), finite."""
    try:
        arr = np.broadcast_to(np.asarray(value, dtype=float), (n,)).copy()
    except (TypeError, ValueError):
        count = "1 value" if n == 1 else f"1 or {n} values"
        raise ConfigError(key, f"needs {count}, got {value!r}") from None
    if not np.all(np.isfinite(arr)):
        raise ConfigError(key, f"must be finite, got {value!r}")
    return arr


def _weights(value: Any, key: str) -> Weights:
    if isinstance(value, Weights):
        w = value
    else:
        value = value or {}
        only(key, value, [f.name for f in fields(Weights)])
        w = Weights(**value)
    for name, val in vars(w).items():
        check_nonneg(f"{key}.{name}", val)
    return w


def _chance(chance: Mapping[str, Any] | None, k: str) -> tuple[float, float] | None:
    """Eq. 18: (f_max [N], the quantile of ``epsilon``), or None when off."""
    if not chance:
        return None
    only(k, chance, ("f_max", "epsilon", "quantile"))
    f_max = check_positive(f"{k}.f_max", chance.get("f_max", 12.0))
    form = chance.get("quantile", "paper_erfinv")  # Eq. 18 as printed (seed B); "normal" = Φ⁻¹
    q = chance_quantile(chance.get("epsilon", 0.5), form=form, key=k)
    return f_max, float(q)


def _well_damped(wd: Mapping[str, Any] | None, k: str) -> tuple[float, float | None] | None:
    """Eq. 19-20: (ζ, a fixed K_e or None for the GP gradient), or None when off."""
    if not wd:
        return None
    only(k, wd, ("zeta", "stiffness", "fixed_stiffness"))
    zeta = check_positive(f"{k}.zeta", wd.get("zeta", 1.2))
    source = wd.get("stiffness", "gp_gradient")
    if source not in ("gp_gradient", "fixed"):
        raise ConfigError(f"{k}.stiffness", f"must be gp_gradient or fixed, got {source!r}")
    if source == "gp_gradient":
        return zeta, None
    return zeta, check_positive(f"{k}.fixed_stiffness", wd.get("fixed_stiffness", 700.0))


def _disturbance(dist: Mapping[str, Any] | None, w: Weights, k: str) -> tuple[float, float] | None:
    """Eq. 16-17: (α, ω_p) when the weight is on (the block is checked either way). α may be
    ``demonstrations``: NaN here, estimated by the controller before it builds the problem."""
    dist = dist or {}
    only(k, dist, ("alpha", "omega_p"))
    alpha = dist.get("alpha", 1.0)
    if alpha == "demonstrations":  # estimated by the controller (NaN until then)
        alpha = math.nan
    else:
        alpha = check_positive(f"{k}.alpha", alpha)
    omega = check_positive(f"{k}.omega_p", dist.get("omega_p", 2 * np.pi * 15))
    return (alpha, omega) if w.disturbance > 0.0 else None


def _joint_torque(jt: Mapping[str, Any] | None, w: Weights, k: str) -> JointTorque | None:
    """Eq. 11, 15: the arm, when given or when the weight is on (None otherwise)."""
    if not jt and w.joint_torque <= 0.0:
        return None
    jt = dict(jt or {})
    only(k, jt, ("shoulder", "l1", "l2", "z", "velocity"))
    return JointTorque(
        shoulder=vector(f"{k}.shoulder", jt.get("shoulder", (0.0, -0.4, 0.3)), 3),
        l1=check_positive(f"{k}.l1", jt.get("l1", 0.30)),
        l2=check_positive(f"{k}.l2", jt.get("l2", 0.35)),
        z=float(jt.get("z", 0.0)),
        velocity=check_choice(
            f"{k}.velocity", jt.get("velocity", "measured"), ("measured", "predicted")
        ),
    )
