"""Biomimetic adaptive control (BAC): feed-forward force and stiffness learned across trials.

The gain-scheduling baseline of seed A §4.2.3 (Sidhik et al.): the biomimetic controller of
Yang, Ganesh, Haddadin, Parusel, Albu-Schäffer and Burdet (2011, IEEE T-RO 27(5)), which adapts
a feed-forward force and an impedance at every time index of a repeated movement, the way
humans learn to move in a novel force field. Parameters are time-indexed: the update of index
k in trial j uses the errors at the same index k of trial j − 1, so the task must last the
same number of control steps in every trial (seed A §4.2.3).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from ccm.control.base import STATE_ERRORS, Controller, check_state_keys, state_error
from ccm.control.loop import HybridLoop, mean_gain
from ccm.core import vector
from ccm.core.errors import (
    ConfigError,
    check_finite,
    check_int_nonneg,
    check_nonneg,
    check_positive,
)
from ccm.core.types import Command, Observation, TargetSample


class BAC(Controller):
    """Biomimetic adaptive control (Yang et al. 2011), the seed A §4.2.3 baseline.

    Per task-space axis (all products elementwise), at control step k of a trial, with
    e_p = x_d − x and e_v = ẋ_d − ẋ (target minus actual):

    * Control law (seed A Eq. 1 form, through :meth:`HybridLoop.motion_force`):

        u(k) = F(k) + K(k) e_p(k) + D(k) e_v(k) + m ẍ_d(k)

      with D(k) derived from K(k) by ``damping_rule`` (Yang et al. adapt D with the same law;
      here it is derived, which the seed A description allows) and the inertial feed-forward
      m ẍ_d standing for the model term of Yang et al.'s reference torque. The fixed minimal
      feedback of Yang et al.'s controller is represented by the floor ``k_min`` of K with
      its damping.
    * Tracking error ε(k) = e_v(k) + κ e_p(k), recorded for every step of the trial.
    * After the trial (:meth:`end_trial`), for every recorded index k:

        F(k) ← F(k) + Q_F (ε(k) − γ_F F(k))
        K(k) ← clip(K(k) + Q_K (ε(k) e_p(k) − γ_K K(k)), k_min, k_max)

      ε e_p is the diagonal of Yang et al.'s outer product ε e_pᵀ (one stiffness per axis, no
      cross-coupling). γ is the forgetting factor that keeps F and K from growing where the
      error is small. Yang et al. use one γ in normalised units; F [N] and K [N/m] here have
      different units and their Q differ by orders of magnitude, so each gets its own γ (at a
      fixed point F = ε/γ_F and K = ε e_p/γ_K: the residual error grows with γ).

    The profiles F, K have a fixed length N: the number of steps of the first trial. Later
    trials that run longer use the parameters of index N − 1 for the extra steps and do not
    learn there; shorter trials update only the indices they reached.

    On force-controlled segments (target ``force_dir`` d) errors are projected on the motion
    subspace I − d dᵀ and the force loop of :class:`HybridLoop` (seed A Eq. 1, u_fc)
    acts along d.

    Defaults are the tuned values of ``configs/controller/bac.yaml``
    (``experiments/tuning/bac.md``).

    Args:
        init_stiffness: K before learning [N/m], scalar or per axis; in [k_min, k_max].
        init_force: F before learning [N], scalar or per axis.
        kappa: κ [1/s] weighting position in ε; > 0.
        gamma_force: forgetting factor γ_F [m/(N s)]; >= 0 (Q_F γ_F < 1: fraction per trial).
        gamma_stiffness: forgetting factor γ_K [m³/(N s)]; >= 0 (Q_K γ_K < 1).
        q_force: Q_F [N s/m per trial]; >= 0.
        q_stiffness: Q_K [N s/m³ per trial]; >= 0.
        k_min, k_max: stiffness bounds [N/m]; 0 <= k_min <= k_max.
        loop: the ``controller.loop`` block (:class:`ccm.control.loop.HybridLoop`: damping
            rule, force loop, inertial feed-forward, orientation hold).
    """

    def __init__(
        self,
        init_stiffness: float | list[float] = 300.0,
        init_force: float | list[float] = 0.0,
        kappa: float = 100.0,
        gamma_force: float = 1.0e-3,
        gamma_stiffness: float = 1.0e-7,
        q_force: float = 3.0,
        q_stiffness: float = 1.0e6,
        k_min: float = 50.0,
        k_max: float = 3000.0,
        loop: Mapping[str, Any] | None = None,
        key: str = "controller",
    ) -> None:
        self.k_min = check_nonneg(f"{key}.k_min", k_min)
        self.k_max = check_positive(f"{key}.k_max", k_max)
        if self.k_max < self.k_min:
            raise ConfigError(f"{key}.k_max", f"must be >= k_min={self.k_min}, got {k_max!r}")
        k0 = np.atleast_1d(np.asarray(init_stiffness, dtype=object)).ravel()
        self.init_stiffness = np.array(
            [check_nonneg(f"{key}.init_stiffness", v) for v in k0], dtype=float
        )
        if np.any(self.init_stiffness < self.k_min) or np.any(self.init_stiffness > self.k_max):
            raise ConfigError(
                f"{key}.init_stiffness",
                f"must be in [k_min, k_max] = [{self.k_min}, {self.k_max}], got {init_stiffness!r}",
            )
        f0 = np.atleast_1d(np.asarray(init_force, dtype=object)).ravel()
        self.init_force = np.array([check_finite(f"{key}.init_force", v) for v in f0], dtype=float)
        self.kappa = check_positive(f"{key}.kappa", kappa)
        self.gamma_force = check_nonneg(f"{key}.gamma_force", gamma_force)
        self.gamma_stiffness = check_nonneg(f"{key}.gamma_stiffness", gamma_stiffness)
        self.q_force = check_nonneg(f"{key}.q_force", q_force)
        self.q_stiffness = check_nonneg(f"{key}.q_stiffness", q_stiffness)
        for name, q, g in (
            ("gamma_force", self.q_force, self.gamma_force),
            ("gamma_stiffness", self.q_stiffness, self.gamma_stiffness),
        ):
            if q * g > 1.0:  # the update would flip the sign of F or K every trial
                raise ConfigError(f"{key}.{name}", f"Q * gamma = {q * g:g} must be <= 1")
        self.loop = HybridLoop.from_config(loop, f"{key}.loop")  # K, D passed per call
        self._key = key
        self.dim = 0
        self.control_dt = 0.0
        self.trials_learned = 0
        self.force_profile: np.ndarray | None = None  # F, shape (N, dim), after the 1st trial
        self.stiffness_profile: np.ndarray | None = None  # K, shape (N, dim)
        self._eps: list[np.ndarray] = []
        self._ep: list[np.ndarray] = []
        self._signals: dict[str, float] = {}

    def reset(self, dim: int, control_dt: float) -> None:
        """Start a trial at index 0; the learned profiles are kept."""
        super().reset(dim, control_dt)
        for name, arr in (("init_stiffness", self.init_stiffness), ("init_force", self.init_force)):
            if arr.size not in (1, dim):
                raise ConfigError(f"{self._key}.{name}", f"needs 1 or {dim} values, got {arr.size}")
        if self.force_profile is not None and self.force_profile.shape[1] != dim:
            raise ConfigError(
                f"{self._key}", f"learned for {self.force_profile.shape[1]}-D, reset for {dim}-D"
            )
        self.loop.reset(dim, control_dt)
        self._k0 = np.broadcast_to(self.init_stiffness, (dim,)).astype(float)
        self._f0 = np.broadcast_to(self.init_force, (dim,)).astype(float)
        self._step = 0
        self._eps = []
        self._ep = []
        self._signals = {
            "stiffness_Npm": float(np.mean(self._k0)),
            "damping_Nspm": float(np.mean(self._damping(self._k0))),
            "ff_force_N": float(np.linalg.norm(self._f0)),
            "force_error_N": 0.0,
            "force_control": 0.0,
        }

    def _damping(self, k: np.ndarray, obs: Observation | None = None) -> np.ndarray:
        """D(k) by the loop's rule, for this step's inertia (the nominal mass without ``obs``)."""
        inertia = None if obs is None else self.loop.inertia_of(obs)
        return np.asarray(self.loop.damping_for(k, inertia), dtype=float)

    @property
    def horizon_steps(self) -> int | None:
        """N, the fixed length of the time-indexed profiles (``None`` before the first trial)."""
        return None if self.force_profile is None else int(self.force_profile.shape[0])

    def step(self, obs: Observation, target: TargetSample) -> Command:
        """u(k) = F(k) + K(k) e_p + D(k) e_v + m ẍ_d; records ε(k), e_p(k) for learning."""
        if self.force_profile is None or self.stiffness_profile is None:
            f, k = self._f0, self._k0
        else:
            idx = min(self._step, self.force_profile.shape[0] - 1)
            f, k = self.force_profile[idx], self.stiffness_profile[idx]
        kd = self._damping(k, obs)
        u_motion, u_force = self.loop.motion_force(obs, target, k, kd)
        d = target.force_dir
        e_p = target.position - obs.position
        e_v = target.velocity - obs.lin_vel
        if d is not None:
            f = f - d * float(d @ f)
            e_p = e_p - d * float(d @ e_p)
            e_v = e_v - d * float(d @ e_v)
        self._eps.append(e_v + self.kappa * e_p)
        self._ep.append(e_p)
        self._step += 1
        s = self._signals
        s["stiffness_Npm"] = vector.mean(k)
        s["damping_Nspm"] = mean_gain(kd)
        s["ff_force_N"] = vector.norm(f)
        s["force_error_N"] = self.loop.force_error_N
        s["force_control"] = self.loop.force_control
        return Command(force=u_motion + f + u_force, torque=self.loop.rotation_torque(obs, target))

    def end_trial(self) -> None:
        """Yang et al.'s trial-to-trial update of F(k) and K(k) from this trial's errors."""
        n = len(self._eps)
        if n == 0:
            return
        if self.force_profile is None or self.stiffness_profile is None:
            self.force_profile = np.tile(self._f0, (n, 1))
            self.stiffness_profile = np.tile(self._k0, (n, 1))
        m = min(n, self.force_profile.shape[0])
        eps = np.asarray(self._eps[:m])
        e_p = np.asarray(self._ep[:m])
        f = self.force_profile[:m]
        k = self.stiffness_profile[:m]
        f += self.q_force * (eps - self.gamma_force * f)
        k += self.q_stiffness * (eps * e_p - self.gamma_stiffness * k)
        np.clip(k, self.k_min, self.k_max, out=k)
        self.trials_learned += 1
        self._eps = []
        self._ep = []

    def state_dict(self) -> dict[str, Any]:
        """The learned profiles F(k), K(k) as nested lists (JSON-safe; null before the first
        trial) and the number of trials they have learned from."""
        learned = self.force_profile is not None and self.stiffness_profile is not None
        return {
            "force_profile": self.force_profile.tolist() if learned else None,
            "stiffness_profile": self.stiffness_profile.tolist() if learned else None,
            "trials_learned": self.trials_learned,
        }

    def load_state_dict(self, state: Mapping[str, Any]) -> None:
        """Restore profiles saved by :meth:`state_dict` (lists or arrays).

        Raises:
            ConfigError: ``init_from``, on malformed profiles or another dimension.
        """
        check_state_keys(state, ("force_profile", "stiffness_profile", "trials_learned"))
        try:
            trials = check_int_nonneg("trials_learned", state["trials_learned"])
            if state["force_profile"] is None and state["stiffness_profile"] is None:
                self.force_profile = self.stiffness_profile = None
                self.trials_learned = trials
                return
            f = np.asarray(state["force_profile"], dtype=float)
            k = np.asarray(state["stiffness_profile"], dtype=float)
        except STATE_ERRORS as exc:
            raise state_error(exc) from None
        if f.ndim != 2 or f.shape != k.shape or not f.size:
            raise ConfigError(
                "init_from", f"profiles must be (N, dim) alike, got {f.shape}, {k.shape}"
            )
        if not (np.all(np.isfinite(f)) and np.all(np.isfinite(k))):
            raise ConfigError("init_from", "profiles must be finite")
        if self.dim and f.shape[1] != self.dim:
            raise ConfigError("init_from", f"profiles are {f.shape[1]}-D, the task {self.dim}-D")
        self.force_profile = f.copy()
        self.stiffness_profile = np.clip(k, self.k_min, self.k_max)
        self.trials_learned = trials

    def signals(self) -> dict[str, float]:
        """``stiffness_Npm`` mean K(k), ``damping_Nspm`` mean D(k), ``ff_force_N`` |F(k)|, plus
        the force-loop signals of :class:`HybridLoop`."""
        return dict(self._signals)
