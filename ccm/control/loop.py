"""The parts of seed A's Eq. 1 that every impedance controller shares, as one component.

u = P_m [K_p Δx + K_d Δẋ + m ẍ_d] + u_fc + orientation hold, with P_m = I − d dᵀ the motion
subspace and u_fc = d [F_d + k_fp e_F + k_fi ∫e_F] − d dᵀ D_f ẋ the force loop along the
target's force direction d (e_F = F_d − F_c; F_c = −d·F_meas is the force the end-effector
exerts on the environment). The gravity and Coriolis parts of H are applied by the robot's
own torque loop; Λ ẍ_d is the inertial part of H (Eq. 1: "inertia, Coriolis and gravity").
Λ is the robot model's task-space inertia Λ(q) where the observation carries it (the 3-D
arm: 1-10 kg along the plans, issue #38) and the nominal end-effector mass m otherwise.

With Λ(q), the ``critical`` damping rule is the factorization design of Albu-Schäffer et al.
(2003), K_d = ζ (Λ^½ K_p^½ + K_p^½ Λ^½): for K_p = k I it is 2ζ √k Λ^½, so every eigen-
direction of Λ (mass m_i) is damped with ratio ζ at its own ω_i = √(k / m_i); for a scalar
mass it is the scalar rule 2ζ √(K_p m).

A controller holds a :class:`HybridLoop` (its ``controller.loop`` config block) and passes it
the stiffness and damping it chose this step: :class:`ccm.control.impedance.FixedImpedance`
constant ones, AVIC those of Eq. 4b, MRAC and BAC their adapted ones, AIC none.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np

from ccm.control._impedance_kernels import (
    critical_damping_matrix,
    force_direction_terms,
    impedance_kernel,
    impedance_matrix_kernel,
)
from ccm.core.errors import (
    check_bool,
    check_choice,
    check_nonneg,
    check_positive,
    constructor_kwargs,
)
from ccm.core.types import Observation, TargetSample

DAMPING_RULES = ("critical", "paper", "fixed")
#: where the inertia of H and of the critical rule comes from (:class:`HybridLoop`)
INERTIA_SOURCES = ("model", "nominal")
#: the signals a loop logs, in this order, after the controller's gains
LOOP_SIGNALS = ("force_error_N", "force_control")


def damping_from_rule(
    stiffness: np.ndarray | float,
    rule: str,
    mass_kg: float | np.ndarray,
    zeta: float,
    fixed: float,
) -> np.ndarray | float:
    """Damping K_d for stiffness K_p under a named rule.

    * ``critical``: K_d = 2 ζ sqrt(K_p m) — damping ratio ζ for the end-effector mass m; for
      an inertia matrix Λ (n, n) the (n, n) factorization design of the module docstring.
    * ``paper``: K_d = sqrt(K_p) / 4, the rule stated after Eq. 4c of seed A. For m = 1 kg it
      gives ζ = 1/8, i.e. under-damped, despite the paper calling it critical damping.
    * ``fixed``: K_d = ``fixed`` regardless of K_p.
    """
    if rule == "critical":
        if isinstance(mass_kg, np.ndarray):
            kp = float(stiffness) if np.ndim(stiffness) == 0 else np.asarray(stiffness, float)
            return critical_damping_matrix(mass_kg, kp, float(zeta))
        return 2.0 * zeta * np.sqrt(np.asarray(stiffness) * mass_kg)
    if rule == "paper":
        return np.sqrt(np.asarray(stiffness)) / 4.0
    return np.full_like(np.asarray(stiffness, dtype=float), fixed)


def impedance_term(
    obs: Observation,
    target: TargetSample,
    kp: np.ndarray | float,
    kd: np.ndarray | float,
    mass_kg: float | np.ndarray,
    inertia_feedforward: bool,
    compiled: bool = True,
) -> np.ndarray:
    """K_p Δx + K_d Δẋ + Λ ẍ_d in every direction (the motion part of Eq. 1, seed A, before
    the projection P_m onto the motion subspace). A new array.

    ``kp``: a scalar or per-axis vector; ``kd``: that or an (n, n) matrix; ``mass_kg``: the
    scalar mass m or the (n, n) inertia Λ. Scalar masses with scalar or per-axis gains run,
    with ``compiled``, through :func:`ccm.control._impedance_kernels.impedance_kernel` (same
    arithmetic in the same order, bit for bit); everything else through the numpy lines below.
    """
    n = obs.position.shape[0]
    matrix_kd, matrix_mass = _is_matrix(kd), _is_matrix(mass_kg)
    if compiled and matrix_kd and matrix_mass and _kernel_gain(kp, n):
        return impedance_matrix_kernel(
            target.position, obs.position, target.velocity, obs.lin_vel, target.acceleration,
            kp, kd, mass_kg, inertia_feedforward,
        )  # fmt: skip
    if matrix_mass or matrix_kd:
        u = kp * (target.position - obs.position)
        e_vel = target.velocity - obs.lin_vel
        u += kd @ e_vel if _is_matrix(kd) else kd * e_vel
        if inertia_feedforward:
            acc = target.acceleration
            u += mass_kg @ acc if _is_matrix(mass_kg) else mass_kg * acc
        return u
    if compiled and _kernel_gain(kp, n) and _kernel_gain(kd, n):  # checks of ~0.1 µs
        return impedance_kernel(
            target.position, obs.position, target.velocity, obs.lin_vel, target.acceleration,
            kp, kd, mass_kg, inertia_feedforward,
        )  # fmt: skip
    # in-place arithmetic: each temporary costs ~0.5 µs
    u = target.position - obs.position
    u *= kp
    e_vel = target.velocity - obs.lin_vel
    e_vel *= kd
    u += e_vel
    if inertia_feedforward:
        u += mass_kg * target.acceleration
    return u


_F64 = np.dtype(np.float64)


def _is_matrix(x: object) -> bool:
    """Whether a gain or mass is an (n, n) matrix (Λ, or K_d designed from it)."""
    return type(x) is np.ndarray and x.ndim == 2  # type: ignore[attr-defined]


def mean_gain(k: np.ndarray | float) -> float:
    """A gain's logged value: its axis mean (the diagonal's mean for an (n, n) matrix)."""
    if isinstance(k, float):  # np.float64 too: the planar per-step path, no array calls
        return float(k)
    a = np.asarray(k, dtype=float)
    if a.ndim == 2:
        return float(a.trace()) / a.shape[0]
    return float(a.sum()) / a.shape[0]


def _kernel_gain(k: object, n: int) -> bool:
    """Whether the kernel takes gain ``k`` for ``n`` axes: a float, or float64 shape (n,)."""
    t = type(k)
    if t is float or t is np.float64:
        return True
    return t is np.ndarray and k.dtype is _F64 and k.shape == (n,)  # type: ignore[attr-defined]


class HybridLoop:
    """Eq. 1's shared terms (module docstring): the damping rule K_d(K_p), the inertial
    feed-forward m ẍ_d, the force loop u_fc and the orientation hold.

    Args:
        damping_rule: ``critical``, ``paper`` or ``fixed`` (:func:`damping_from_rule`).
        damping_ratio: ζ for the ``critical`` rule.
        damping: K_d [N s/m] for the ``fixed`` rule.
        mass_kg: nominal end-effector mass [kg] (critical rule, inertial feed-forward).
        inertia_feedforward: add Λ ẍ_d (part of H in Eq. 1).
        inertia: ``model``: Λ(q) from the observation where it carries one (the 3-D arm),
            else ``mass_kg``; ``nominal``: ``mass_kg`` always (ccm before issue #38).
        rot_stiffness: orientation stiffness [N m/rad]; rot_damping [N m s/rad].
        force_kp: proportional force gain k_fp [-]; force_ki: integral gain k_fi [1/s].
        force_damping: D_f [N s/m] along the force direction.
        force_integral_limit_N: anti-windup bound on the integral term k_fi ∫e_F [N].
        key: config prefix for errors (``controller.loop``).
    """

    def __init__(
        self,
        damping_rule: str = "critical",
        damping_ratio: float = 1.0,
        damping: float = 30.0,
        mass_kg: float = 1.0,
        inertia_feedforward: bool = True,
        inertia: str = "model",
        rot_stiffness: float = 5.0,
        rot_damping: float = 0.5,
        force_kp: float = 0.5,
        force_ki: float = 5.0,
        force_damping: float = 50.0,
        force_integral_limit_N: float = 5.0,
        key: str = "controller.loop",
    ) -> None:
        self.damping_rule = check_choice(f"{key}.damping_rule", damping_rule, DAMPING_RULES)
        self.damping_ratio = check_positive(f"{key}.damping_ratio", damping_ratio)
        self.fixed_damping = check_nonneg(f"{key}.damping", damping)
        self.mass_kg = check_positive(f"{key}.mass_kg", mass_kg)
        self.inertia_feedforward = check_bool(f"{key}.inertia_feedforward", inertia_feedforward)
        self.inertia = check_choice(f"{key}.inertia", inertia, INERTIA_SOURCES)
        self.rot_stiffness = check_nonneg(f"{key}.rot_stiffness", rot_stiffness)
        self.rot_damping = check_nonneg(f"{key}.rot_damping", rot_damping)
        self.force_kp = check_nonneg(f"{key}.force_kp", force_kp)
        self.force_ki = check_nonneg(f"{key}.force_ki", force_ki)
        self.force_damping = check_nonneg(f"{key}.force_damping", force_damping)
        self.force_integral_limit_N = check_nonneg(
            f"{key}.force_integral_limit_N", force_integral_limit_N
        )
        self.control_dt = 0.0
        self.zero = np.zeros(0)
        self.last_force_loop = self.zero
        self._force_int = 0.0
        self.force_error_N = 0.0
        self.force_control = 0.0

    @classmethod
    def from_config(cls, cfg: Mapping[str, Any] | None, key: str) -> HybridLoop:
        """From a ``controller.loop`` block (every key a constructor argument)."""
        return cls(**constructor_kwargs(cls, dict(cfg or {}), key), key=key)

    def reset(self, dim: int, control_dt: float) -> None:
        """A new trial: clear the force integral."""
        self.control_dt = control_dt
        self.zero = np.zeros(dim)
        self.last_force_loop = self.zero
        self._force_int = 0.0
        self.force_error_N = 0.0
        self.force_control = 0.0

    def inertia_of(self, obs: Observation) -> float | np.ndarray:
        """The inertia of H and of the critical rule this step: the observation's Λ(q)
        [kg], (n, n), under ``inertia: model`` where it has one; else ``mass_kg``."""
        lam = obs.inertia
        return lam if lam is not None and self.inertia == "model" else self.mass_kg

    def damping_for(
        self, kp: np.ndarray | float, inertia: float | np.ndarray | None = None
    ) -> np.ndarray | float:
        """K_d for K_p under the configured rule, for ``inertia`` (:meth:`inertia_of`;
        None: ``mass_kg``). A float for a float and the scalar mass (fast path); an (n, n)
        matrix for Λ under the critical rule."""
        if _is_matrix(inertia):
            return damping_from_rule(
                kp, self.damping_rule, inertia, self.damping_ratio, self.fixed_damping
            )
        if isinstance(kp, float):  # np.float64 too
            if self.damping_rule == "critical":
                return 2.0 * self.damping_ratio * math.sqrt(kp * self.mass_kg)
            if self.damping_rule == "paper":
                return math.sqrt(kp) / 4.0
            return self.fixed_damping
        return damping_from_rule(
            kp, self.damping_rule, self.mass_kg, self.damping_ratio, self.fixed_damping
        )

    def motion_force(
        self, obs: Observation, target: TargetSample, kp: np.ndarray | float, kd: np.ndarray | float
    ) -> tuple[np.ndarray, np.ndarray]:
        """(motion-subspace impedance force, force-loop force u_fc) for gains ``kp``/``kd``.

        Call once per step: the integral advances on every call. u_fc is also kept as
        ``last_force_loop``; it is :attr:`zero` (the same object) on a motion-only segment.
        """
        u_motion = impedance_term(
            obs, target, kp, kd, self.inertia_of(obs), self.inertia_feedforward
        )  # fmt: skip
        d = target.force_dir
        if d is None:
            self._force_int = 0.0
            self.force_error_N = 0.0
            self.force_control = 0.0
            self.last_force_loop = self.zero
            return u_motion, self.zero
        # P_m u, and the measured force and velocity along d
        u_motion, f_along, v_along = force_direction_terms(u_motion, d, obs.force, obs.lin_vel)
        f_contact = -f_along  # force the end-effector exerts on the environment
        err = target.force_mag - f_contact
        lim = self.force_integral_limit_N / self.force_ki if self.force_ki > 0 else 0.0
        self._force_int = min(max(self._force_int + err * self.control_dt, -lim), lim)
        mag = target.force_mag + self.force_kp * err + self.force_ki * self._force_int
        u_force = d * mag - d * (self.force_damping * v_along)
        self.force_error_N = err
        self.force_control = 1.0
        self.last_force_loop = u_force
        return u_motion, u_force

    def rotation_torque(self, obs: Observation, target: TargetSample) -> np.ndarray:
        """Orientation impedance (2D: angle error; 3D handled by the 3D backend's controller)."""
        if obs.orientation.shape[0] == 1:  # plain floats: the same IEEE operations as numpy's
            (a_d,), (a,) = target.orientation.tolist(), obs.orientation.tolist()
            (w,) = obs.ang_vel.tolist()
            err = (a_d - a + math.pi) % (2.0 * math.pi) - math.pi
            return np.array([self.rot_stiffness * err - self.rot_damping * w])
        return np.zeros(3)

    def signals(self) -> dict[str, float]:
        """``force_error_N`` (e_F of the last step) and ``force_control`` (1 on a force segment)."""
        return {"force_error_N": self.force_error_N, "force_control": self.force_control}
