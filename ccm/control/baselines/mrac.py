"""Model reference adaptive control (MRAC) in task space, per axis.

The MRAC baseline of seed A §4.2.1 (Sidhik et al.), which uses the hyperstability-based
adaptive controller of Tarokh (1991) in the decentralised form of Seraji: each task-space axis
has its own second-order reference model and its own adaptive PD law with an adaptive
feed-forward term. The reference model tracks the target pattern; the controller makes the
end-effector follow the reference model.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np

from ccm.control.base import Controller
from ccm.control.baselines._mrac_kernels import mrac_kernel
from ccm.control.loop import HybridLoop
from ccm.core.errors import ConfigError, check_finite, check_nonneg, check_positive
from ccm.core.types import Command, Observation, TargetSample


def _expm(m: np.ndarray) -> np.ndarray:
    """Matrix exponential of a small square matrix (Taylor series with scaling and squaring)."""
    norm = float(np.max(np.sum(np.abs(m), axis=1)))
    squarings = max(0, math.ceil(math.log2(norm / 0.25))) if norm > 0.25 else 0
    a = m / 2.0**squarings
    out = np.eye(m.shape[0])
    term = np.eye(m.shape[0])
    for n in range(1, 20):
        term = term @ a / n
        out = out + term
    for _ in range(squarings):
        out = out @ out
    return out


def reference_model_discrete(omega: float, zeta: float, dt: float) -> np.ndarray:
    """Exact zero-order-hold discretisation of ẍ_m = ω²(r − x_m) − 2ζω ẋ_m.

    Returns a 2 × 3 matrix ``G`` with ``[x_m, ẋ_m](t + dt) = G @ [x_m, ẋ_m, r](t)`` for a target
    ``r`` held constant over the step (exact for the linear model, so a step response matches
    the analytic second-order response to round-off).
    """
    aug = np.zeros((3, 3))
    aug[0, 1] = 1.0
    aug[1, 0] = -(omega**2)
    aug[1, 1] = -2.0 * zeta * omega
    aug[1, 2] = omega**2
    return _expm(aug * dt)[:2, :]


def _per_axis(key: str, value: Any, check: Any) -> np.ndarray:
    """Scalar or list config value -> checked 1-D float array (length checked at reset)."""
    vals = np.atleast_1d(np.asarray(value, dtype=object)).ravel()
    return np.array([check(key, v) for v in vals], dtype=float)


class MRAC(Controller):
    """Decentralised MRAC (Tarokh 1991; Seraji's form), the seed A §4.2.1 baseline.

    Per task-space axis i (all products elementwise), with target position r(t):

    * Reference model (seed A §4.2.1: "second-order spring-damper system for each dimension"
      with natural frequency ω and damping ratio ζ), discretised exactly (zero-order hold on r):

        ẍ_m = ω² (r − x_m) − 2 ζ ω ẋ_m,   x_m(0) = x(0), ẋ_m(0) = ẋ(0).

    * Model-following error e = x_m − x, ė = ẋ_m − ẋ and weighted error q = w_p e + w_v ė.
    * Adaptive gains, each an integral plus a proportional adaptation term of q (integrals by
      the rectangle rule at the control period):

        f(t)   = f_0   + α₁ ∫q dt    + α₂ q
        K_p(t) = K_p0  + β₁ ∫q e dt  + β₂ q e
        K_v(t) = K_v0  + γ₁ ∫q ė dt  + γ₂ q ė

    * Control law: u = f + K_p e + K_v ė (+ m ẍ_m if ``inertia_feedforward``; off by default
      because the law above has no model term). Gains are not bounded, as in the source law.
    * Per step: compute e, ė, q from the current model state, update the integrals, apply u,
      then advance (x_m, ẋ_m) by one control period with r held.

    Effective gains: since ∫ė dt = e − e(0), f hides feedback on e and ė:
    f = f_0 + α₁w_p ∫e dt + (α₁w_v + α₂w_p) e + α₂w_v ė − α₁w_v e(0). The proportional gain on
    e is therefore K_p(t) + α₁w_v + α₂w_p and the one on ė is K_v(t) + α₂w_v; ``stiffness_Npm``
    and ``damping_Nspm`` report these effective gains (axis means), because K_p(t) alone can
    stay near K_p0 while the integral adaptation of f does the stiffening.
    ``adaptive_kp_Npm``/``adaptive_kv_Nspm`` report K_p(t), K_v(t) themselves.

    On force-controlled segments (target ``force_dir`` d) the errors are projected on the
    motion subspace I − d dᵀ and the force loop of :class:`HybridLoop` (seed A Eq. 1,
    u_fc) acts along d; it is reused through :meth:`HybridLoop.motion_force`, to which the
    reference-model state is passed as the "target" and K_p(t), K_v(t) as the gains.

    Defaults are the tuned values of ``configs/controller/mrac.yaml``
    (``experiments/tuning/mrac.md``).

    Args:
        omega: ω [rad/s] of the reference model, scalar or per axis; seed A Fig. 5: 1.5, 1.0.
        zeta: ζ [-] of the reference model, scalar or per axis.
        w_p, w_v: weights [-], [s] of the error q = w_p e + w_v ė; >= 0, not both 0.
        f0: initial feed-forward force f(0) [N].
        kp0, kv0: initial gains K_p(0) [N/m], K_v(0) [N s/m]; >= 0.
        alpha1, alpha2: integral [N/(m s)] and proportional [N/m] adaptation gains of f.
        beta1, beta2: adaptation gains of K_p [N/(m³ s)], [N/m³].
        gamma1, gamma2: adaptation gains of K_v [N s/m³], [N s²/m³].
        loop: the ``controller.loop`` block (:class:`ccm.control.loop.HybridLoop`: damping
            rule, force loop, inertial feed-forward, orientation hold; the feed-forward
            is off unless the block turns it on).
    """

    #: off force segments, step through :func:`ccm.control.baselines._mrac_kernels.mrac_kernel`
    #: (False: the numpy lines of ``_adapt``, ``_stats`` and ``_advance``; tests compare them)
    compiled = True

    def __init__(
        self,
        omega: float | list[float] = 1.5,
        zeta: float | list[float] = 1.0,
        w_p: float = 1.0,
        w_v: float = 0.1,
        f0: float = 0.0,
        kp0: float = 100.0,
        kv0: float = 20.0,
        alpha1: float = 1.0e2,
        alpha2: float = 1.0e3,
        beta1: float = 1.0e4,
        beta2: float = 1.0e4,
        gamma1: float = 1.0e5,
        gamma2: float = 1.0e3,
        loop: Mapping[str, Any] | None = None,
        key: str = "controller",
    ) -> None:
        self.omega = _per_axis(f"{key}.omega", omega, check_positive)
        self.zeta = _per_axis(f"{key}.zeta", zeta, check_positive)
        self.w_p = check_nonneg(f"{key}.w_p", w_p)
        self.w_v = check_nonneg(f"{key}.w_v", w_v)
        if self.w_p == 0.0 and self.w_v == 0.0:
            raise ConfigError(f"{key}.w_p", "w_p and w_v are both 0: the gains could not adapt")
        self.f0 = check_finite(f"{key}.f0", f0)
        self.kp0 = check_nonneg(f"{key}.kp0", kp0)
        self.kv0 = check_nonneg(f"{key}.kv0", kv0)
        self.alpha = (check_nonneg(f"{key}.alpha1", alpha1), check_nonneg(f"{key}.alpha2", alpha2))
        self.beta = (check_nonneg(f"{key}.beta1", beta1), check_nonneg(f"{key}.beta2", beta2))
        self.gamma = (check_nonneg(f"{key}.gamma1", gamma1), check_nonneg(f"{key}.gamma2", gamma2))
        # K, D are passed per call; inertia_feedforward is off unless the block turns it on
        loop = {"inertia_feedforward": False, **(loop or {})}
        self.loop = HybridLoop.from_config(loop, f"{key}.loop")
        self._key = key
        self.dim = 0
        self.control_dt = 0.0
        self._signals: dict[str, float] = {}

    def reset(self, dim: int, control_dt: float) -> None:
        """Start a trial: reference model re-initialised at the first observation, gains at t=0."""
        super().reset(dim, control_dt)
        for name, arr in (("omega", self.omega), ("zeta", self.zeta)):
            if arr.size not in (1, dim):
                raise ConfigError(f"{self._key}.{name}", f"needs 1 or {dim} values, got {arr.size}")
        nyquist = math.pi / control_dt  # rad/s: a faster reference model is not sampled
        if np.any(self.omega > nyquist):
            raise ConfigError(
                f"{self._key}.omega", f"must be <= pi / control step = {nyquist:.4g} rad/s (the "
                f"Nyquist rate at {control_dt:g} s), got {self.omega.max():g}",
            )  # fmt: skip
        self.loop.reset(dim, control_dt)
        omega = np.broadcast_to(self.omega, (dim,))
        zeta = np.broadcast_to(self.zeta, (dim,))
        self._omega2 = omega**2
        self._two_zeta_omega = 2.0 * zeta * omega
        g = np.array(
            [reference_model_discrete(w, z, control_dt) for w, z in zip(omega, zeta, strict=True)]
        )  # (dim, 2, 3)
        self._g = np.array([g[:, i, j] for i in range(2) for j in range(3)])  # (6, dim)
        self.x_m = np.zeros(dim)
        self.v_m = np.zeros(dim)
        self._started = False
        self._ints = np.zeros((3, dim))  # rows: ∫q, ∫q e, ∫q ė (views below)
        self._int_q, self._int_qe, self._int_qv = self._ints
        self._gains = np.array([
            self.w_p, self.w_v, control_dt, self.f0, *self.alpha, *self.beta, *self.gamma,
            self.kp0, self.kv0,
        ])  # fmt: skip
        self.f = np.full(dim, self.f0)
        self.kp = np.full(dim, self.kp0)
        self.kv = np.full(dim, self.kv0)
        # feedback on e and ė hidden in f (class docstring, "Effective gains")
        self._kp_hidden = self.alpha[0] * self.w_v + self.alpha[1] * self.w_p
        self._kv_hidden = self.alpha[1] * self.w_v
        self._signals = {
            "stiffness_Npm": self.kp0 + self._kp_hidden,
            "damping_Nspm": self.kv0 + self._kv_hidden,
            "adaptive_kp_Npm": self.kp0,
            "adaptive_kv_Nspm": self.kv0,
            "adaptive_force_N": abs(self.f0) * math.sqrt(dim),
            "ref_error_m": 0.0,
            "ref_lag_m": 0.0,
            "force_error_N": 0.0,
            "force_control": 0.0,
        }

    def step(self, obs: Observation, target: TargetSample) -> Command:
        """One control step of the MRAC law (see the class docstring for the equations).
        Off force segments the arithmetic of ``_adapt``, ``_stats`` and ``_advance`` runs as
        one compiled call (:mod:`ccm.control.baselines._mrac_kernels`), unless ``compiled``
        is False."""
        if not self._started:
            self.x_m = obs.position.astype(float).copy()
            self.v_m = obs.lin_vel.astype(float).copy()
            self._started = True
        r, d = target.position, target.force_dir
        if d is None and self.compiled:
            a_m, self.f, self.kp, self.kv, x_next, v_next, stats = mrac_kernel(
                obs.position, obs.lin_vel, r, self.x_m, self.v_m, self._omega2,
                self._two_zeta_omega, self._gains, self._ints, self._g,
            )  # fmt: skip
        else:
            a_m = self._adapt(obs, r, d)
            stats = self._stats(obs, r)
            x_next, v_next = self._advance(r)
        ref = TargetSample(
            t=target.t,
            position=self.x_m,
            velocity=self.v_m,
            acceleration=a_m,
            orientation=target.orientation,
            force_dir=d,
            force_mag=target.force_mag,
            segment=target.segment,
            done=target.done,
        )
        u_motion, u_force = self.loop.motion_force(obs, ref, self.kp, self.kv)
        f = self.f if d is None else self.f - d * float(d @ self.f)
        force = u_motion + f + u_force
        hyb = self.loop.signals()
        s = self._signals
        kp_mean, kv_mean, s["adaptive_force_N"], s["ref_error_m"], s["ref_lag_m"] = stats
        s["stiffness_Npm"] = kp_mean + self._kp_hidden
        s["damping_Nspm"] = kv_mean + self._kv_hidden
        s["adaptive_kp_Npm"] = kp_mean
        s["adaptive_kv_Nspm"] = kv_mean
        s["force_error_N"] = hyb["force_error_N"]
        s["force_control"] = hyb["force_control"]
        # the reference model at the next control step (exact ZOH on r)
        self.x_m, self.v_m = x_next, v_next
        return Command(force=force, torque=self.loop.rotation_torque(obs, target))

    def _adapt(self, obs: Observation, r: np.ndarray, d: np.ndarray | None) -> np.ndarray:
        """Model-following errors, the integrals and the adapted f, K_p, K_v (set in place);
        returns the reference model's acceleration a_m."""
        a_m = self._omega2 * (r - self.x_m) - self._two_zeta_omega * self.v_m
        e = self.x_m - obs.position
        ed = self.v_m - obs.lin_vel
        if d is not None:  # adapt on the motion subspace only
            e = e - d * float(d @ e)
            ed = ed - d * float(d @ ed)
        q = self.w_p * e + self.w_v * ed
        dt = self.control_dt
        self._int_q += q * dt
        self._int_qe += q * e * dt
        self._int_qv += q * ed * dt
        self.f = self.f0 + self.alpha[0] * self._int_q + self.alpha[1] * q
        self.kp = self.kp0 + self.beta[0] * self._int_qe + self.beta[1] * q * e
        self.kv = self.kv0 + self.gamma[0] * self._int_qv + self.gamma[1] * q * ed
        return a_m

    def _stats(self, obs: Observation, r: np.ndarray) -> tuple[float, ...]:
        """(mean K_p, mean K_v, |f|, |x_m − x|, |r − x_m|) for the signals."""
        return (
            float(np.mean(self.kp)),
            float(np.mean(self.kv)),
            float(np.linalg.norm(self.f)),
            float(np.linalg.norm(self.x_m - obs.position)),
            float(np.linalg.norm(r - self.x_m)),
        )

    def _advance(self, r: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(x_m, ẋ_m) one control period later, with r held (exact ZOH)."""
        g00, g01, g02, g10, g11, g12 = self._g
        x_next = g00 * self.x_m + g01 * self.v_m + g02 * r
        v_next = g10 * self.x_m + g11 * self.v_m + g12 * r
        return x_next, v_next

    def signals(self) -> dict[str, float]:
        """``stiffness_Npm``/``damping_Nspm`` effective gains (class docstring), ``adaptive_kp_Npm``
        mean K_p, ``adaptive_kv_Nspm`` mean K_v, ``adaptive_force_N`` |f|,
        ``ref_error_m`` |x_m − x| (model following), ``ref_lag_m`` |r − x_m| (model vs target),
        plus the force-loop signals of :class:`HybridLoop`."""
        return dict(self._signals)
