"""Active Inference Controller (AIC) in task space, per axis.

The self-tuning-regulator baseline of seed A §4.2.2 (Sidhik et al.): the active inference
controller of Pezzato, Ferrari and Hernández Corbato (2020, IEEE RA-L 5(2)), written here for
task-space positions instead of joint angles. The robot holds beliefs about its state in
generalised coordinates and descends the variational free energy: perception moves the
beliefs, action moves the world so that the senses match the beliefs. The target enters only
as the attractor of the generative model; there is no explicit stiffness.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np

from ccm.control.base import Controller
from ccm.control.loop import HybridLoop
from ccm.core import vector
from ccm.core.errors import check_positive
from ccm.core.types import Command, Observation, TargetSample


class AIC(Controller):
    """Active inference control (Pezzato et al. 2020), the seed A §4.2.2 baseline.

    Per task-space axis (all products elementwise), with sensed position y = x and velocity
    y' = ẋ, beliefs μ, μ', μ'' (generalised coordinates up to second order) and the target
    position μ_d(t) as the attractor:

    * Generative model, a first-order attractor with rate λ (λ = 1/s is Pezzato et al.'s
      f(μ) = μ_d − μ): μ' = f(μ) = λ(μ_d − μ) and μ'' = ∂f/∂μ · μ' = −λ μ'. The attractor
      is static in the model; a moving target only moves μ_d from step to step.
    * Prediction errors: ε_y = y − μ, ε_y' = y' − μ', ε_μ = μ' − λ(μ_d − μ), ε_μ' = μ'' + λ μ'.
    * Free energy (Laplace approximation, constants dropped), each error weighted by the
      precision 1/σ of its variance σ (``sigma_*``; the paper's diagonal Σ = σ I):

        F = ½ [ε_y²/σ_y + ε_y'²/σ_y' + ε_μ²/σ_μ + ε_μ'²/σ_μ']

    * Perception, gradient descent in generalised coordinates with learning rate k_μ:

        μ̇   = μ'  − k_μ ∂F/∂μ,    ∂F/∂μ   = −ε_y/σ_y + λ ε_μ/σ_μ
        μ̇'  = μ'' − k_μ ∂F/∂μ',   ∂F/∂μ'  = −ε_y'/σ_y' + ε_μ/σ_μ + λ ε_μ'/σ_μ'
        μ̇'' =     − k_μ ∂F/∂μ'',  ∂F/∂μ'' = ε_μ'/σ_μ'

    * Action (the paper's ∂y/∂u taken as the identity: only its sign is assumed known):

        u̇ = −k_a ∂F/∂u = −k_a (ε_y/σ_y + ε_y'/σ_y')

      so u integrates the sensory prediction errors. Everything is integrated with forward
      Euler at the control period; beliefs start at the first observation, u at 0.

    Effective stiffness: if the beliefs are consistent (μ̇ ≈ μ'), u = −(k_a/σ_y')(y − μ)
    − (k_a/σ_y)∫(y − μ) dt, a PI law on the error *to the belief* (derived here from the
    action law). ``stiffness_Npm`` reports that proportional gain k_a/σ_y';
    it is a constant, not a stiffness to the target (μ lags between y and μ_d).

    On force-controlled segments (target ``force_dir`` d) the action acts on the motion
    subspace I − d dᵀ only and the force loop of :class:`HybridLoop` (seed A Eq. 1, u_fc)
    acts along d (reused through :meth:`HybridLoop.motion_force` with zero gains).

    Defaults are the tuned values of ``configs/controller/aic.yaml``
    (``experiments/tuning/aic.md``).

    Args:
        k_mu: belief learning rate k_μ; > 0.
        k_a: action gain k_a (u̇ [N/s] per precision-weighted error); > 0.
        sigma_y: sensory variance of position σ_y; > 0.
        sigma_yp: sensory variance of velocity σ_y'; > 0.
        sigma_mu: model variance of the first-order dynamics σ_μ; > 0.
        sigma_mup: model variance of the second-order dynamics σ_μ'; > 0.
        attractor_rate: λ [1/s] of the attractor f(μ) = λ(μ_d − μ); > 0.
        loop: the ``controller.loop`` block (:class:`ccm.control.loop.HybridLoop`: damping
            rule, force loop, inertial feed-forward, orientation hold; the feed-forward
            is off unless the block turns it on).
    """

    def __init__(
        self,
        k_mu: float = 50.0,
        k_a: float = 500.0,
        sigma_y: float = 1.0,
        sigma_yp: float = 1.0,
        sigma_mu: float = 1.0,
        sigma_mup: float = 1.0,
        attractor_rate: float = 1.0,
        loop: Mapping[str, Any] | None = None,
        key: str = "controller",
    ) -> None:
        self.k_mu = check_positive(f"{key}.k_mu", k_mu)
        self.k_a = check_positive(f"{key}.k_a", k_a)
        self.p_y = 1.0 / check_positive(f"{key}.sigma_y", sigma_y)
        self.p_yp = 1.0 / check_positive(f"{key}.sigma_yp", sigma_yp)
        self.p_mu = 1.0 / check_positive(f"{key}.sigma_mu", sigma_mu)
        self.p_mup = 1.0 / check_positive(f"{key}.sigma_mup", sigma_mup)
        self.lam = check_positive(f"{key}.attractor_rate", attractor_rate)
        # K, D are passed per call; inertia_feedforward is off unless the block turns it on
        loop = {"inertia_feedforward": False, **(loop or {})}
        self.loop = HybridLoop.from_config(loop, f"{key}.loop")
        self._key = key
        self.dim = 0
        self.control_dt = 0.0
        self._signals: dict[str, float] = {}

    @property
    def effective_stiffness(self) -> float:
        """k_a/σ_y' [N/m]: proportional gain of u on the error to the belief (class docstring)."""
        return self.k_a * self.p_yp

    def reset(self, dim: int, control_dt: float) -> None:
        """Start a trial: beliefs re-initialised at the first observation, action at 0."""
        super().reset(dim, control_dt)
        self.loop.reset(dim, control_dt)
        self.mu = np.zeros(dim)
        self.mu_p = np.zeros(dim)
        self.mu_pp = np.zeros(dim)
        self.u = np.zeros(dim)
        self._zero = np.zeros(dim)
        self._started = False
        self._signals = {
            "stiffness_Npm": self.effective_stiffness,
            "damping_Nspm": math.nan,  # no damping gain: velocity error enters u only integrated
            "belief_error_m": 0.0,
            "belief_lag_m": 0.0,
            "action_N": 0.0,
            "force_error_N": 0.0,
            "force_control": 0.0,
        }

    def step(self, obs: Observation, target: TargetSample) -> Command:
        """One control step: apply u, then one Euler step of perception and action."""
        if not self._started:
            self.mu = obs.position.astype(float).copy()
            self.mu_p = obs.lin_vel.astype(float).copy()
            self.mu_pp = np.zeros(self.dim)
            self._started = True
        d = target.force_dir
        u_motion, u_force = self.loop.motion_force(obs, target, self._zero, self._zero)
        u = self.u if d is None else self.u - d * float(d @ self.u)
        force = u_motion + u + u_force

        lam, dt = self.lam, self.control_dt
        e_y = obs.position - self.mu
        e_yp = obs.lin_vel - self.mu_p
        e_mu = self.mu_p - lam * (target.position - self.mu)
        e_mup = self.mu_pp + lam * self.mu_p
        g_mu = -self.p_y * e_y + lam * self.p_mu * e_mu
        g_mup = -self.p_yp * e_yp + self.p_mu * e_mu + lam * self.p_mup * e_mup
        g_mupp = self.p_mup * e_mup
        s = self._signals
        s["belief_error_m"] = vector.norm(e_y)
        s["belief_lag_m"] = vector.norm(target.position - self.mu)
        s["action_N"] = vector.norm(u)
        s["force_error_N"] = self.loop.force_error_N
        s["force_control"] = self.loop.force_control

        du = -self.k_a * (self.p_y * e_y + self.p_yp * e_yp)
        if d is not None:
            du = du - d * float(d @ du)
        mu_p_old = self.mu_p
        self.mu = self.mu + dt * (mu_p_old - self.k_mu * g_mu)
        self.mu_p = mu_p_old + dt * (self.mu_pp - self.k_mu * g_mup)
        self.mu_pp = self.mu_pp - dt * self.k_mu * g_mupp
        self.u = self.u + dt * du
        return Command(force=force, torque=self.loop.rotation_torque(obs, target))

    def signals(self) -> dict[str, float]:
        """``stiffness_Npm`` k_a/σ_y' (see class docstring), ``damping_Nspm`` NaN (none),
        ``belief_error_m`` |y − μ|, ``belief_lag_m`` |μ_d − μ|, ``action_N`` |u|, plus the
        force-loop signals of :class:`HybridLoop`."""
        return dict(self._signals)
