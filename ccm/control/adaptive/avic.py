"""Adaptive variable impedance control with a learned forward model (seed A §3.1, Eq. 4a–4c).

The command adds to the hybrid impedance law of Eq. 1 a feed-forward wrench λ W_pred from
the forward model (Eq. 4a), and moves the stiffness between K_free and K_max with the
model's accuracy (Eq. 4b), where λ is a logistic function of the prediction error (Eq. 4c):

    u_t   = K_p Δx + K_d Δẋ + m ẍ_d + u_fc − λ Ŵ                       (4a)
    K_p   = K_free + (1 − λ)(K_max − K_free)                             (4b)
    λ     = 1 − 1 / (1 + exp(−r (ε − ε₀)))                               (4c)

Timing. The forward model's step is its horizon H = ``forward_model.horizon_s`` (H control
periods; seed A's 2D world stepped its model with the simulation). At control step t the
sensor has just given F_t, so the newest error is ε_t = ‖D_t − D̂_t‖ (D̂_t was predicted from
S_{t−H}), the model learns X_t = [S_{t−H}, D_t] and predicts D̂_{t+H} = f(S_t), and the
command u_t — applied until t+1 — uses λ_t and D̂_{t+1} (predicted from S_{t+1−H}). With
H = 1 this is the paper's λ_{t−1}, W_t^pred shifted to the sample at which each quantity
becomes available.

ε₀ and r of Eq. 4c are given, or set from the first trials' prediction errors
(``calibrate``: :mod:`ccm.control.adaptive.logistic`).

Sign. Ŵ is the predicted *external* force on the end-effector, so the command subtracts it
to cancel it (the paper writes +λ W_pred for the compensating wrench).

Direction. The model predicts magnitudes (Eq. 2–3); ``ff_direction`` turns ‖F̂‖ into a
vector: ``against_motion`` (seed A §3.1: forces act along or against the direction of
motion, as friction and drag do) gives Ŵ = −‖F̂‖ v̂, and no feed-forward below
``min_speed``; ``measured`` keeps the direction of the latest measured force, Ŵ = ‖F̂‖ F̂_t,
which also suits forces that are not aligned with the motion (springs); ``along_motion``
keeps only the part of that vector along the measured direction of motion v̂,
Ŵ = ‖F̂‖ (F̂_t·v̂) v̂, and none below ``min_speed``.

Rigid contacts. Against a surface the tool is pushed into and cannot move through (a target
inside a wall or table), ``measured`` cancels the surface's reaction to the controller's own
push: the command grows by λ‖F̂‖ with no motion to show for it, a positive feedback
F = K δ / (1 − λ) (on ``h4_contact_learning`` |F| climbed from 6 to 197 N in 0.16 s,
measured). ``along_motion`` has no component along the normal of a surface the tool rests
on or slides along (its velocity there is zero), so it cancels friction, drag and the force
of a spring being stretched, but not a constraint's reaction (seed A §3.1: forces act along
or against the motion).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np

from ccm.control.adaptive.logistic import LogisticGate
from ccm.control.adaptive.modal import ContactModes
from ccm.control.base import STATE_ERRORS, Controller, check_state_keys, state_error
from ccm.control.loop import HybridLoop, mean_gain
from ccm.core.errors import (
    ConfigError,
    check_bool,
    check_choice,
    check_nonneg,
    check_positive,
)
from ccm.core.filters import first_order_alpha
from ccm.core.types import Command, Observation, TargetSample
from ccm.learn.mixtures.forecast import ForecastBuffer, horizon_steps
from ccm.learn.mixtures.forward_model import N_STATE, magnitudes, make_forward_model

FF_DIRECTIONS = ("against_motion", "measured", "along_motion")
MODAL_TYPE = "avic_modes"  # the learned-state name of AVIC with Algorithm 1 (a modes block)


class AVIC(Controller):
    """AVIC of seed A Eq. 4a–4c on top of the hybrid impedance law of Eq. 1.

    Args:
        k_free: K_free [N/m], the stiffness used when the model is accurate (> 0).
        k_max: K_max [N/m], the stiffness used when it is not (>= k_free).
        r: logistic growth rate of Eq. 4c [1/N]; None with ``calibrate``.
        eps0: logistic midpoint ε₀ of Eq. 4c [N]; None with ``calibrate``.
        calibrate: ``{trials, quantile, shape}``: set ε₀ and r from the prediction errors of
            the first trials (module docstring), or None to use ``r`` and ``eps0``.
        error_lowpass_s: time constant [s] of a first-order low-pass on ε_t before Eq. 4c
            (and the calibration); 0 = the raw error (module docstring).
        adaptive: False fixes K_p = K_max and drops the feed-forward while the model still
            learns and predicts (the fixed-GMM + high-stiffness baseline of seed A §4.1).
        feedforward: add −λ Ŵ (Eq. 4a).
        ff_direction: ``against_motion``, ``measured`` or ``along_motion`` (see the module
            docstring).
        min_speed: measured speed below which ``against_motion`` and ``along_motion`` have no
            direction [m/s].
        forward_model: ``{kind: igmm | fixed_gmm, ...}`` (:mod:`ccm.learn.mixtures.forward_model`).
        modes: Algorithm 1's ``modes`` block (:class:`ccm.control.adaptive.modal.ContactModes`,
            ``{}`` = its defaults): one forward model per contact mode, held as the ``modes``
            member; None = one forward model (plain AVIC).
        loop: the ``controller.loop`` block (:class:`ccm.control.loop.HybridLoop`: damping
            rule, force loop, inertial feed-forward, orientation hold).
    """

    def __init__(
        self,
        k_free: float = 300.0,
        k_max: float = 3000.0,
        r: float | None = 2.0,
        eps0: float | None = 2.0,
        calibrate: Mapping[str, Any] | None = None,
        error_lowpass_s: float = 0.0,
        adaptive: bool = True,
        feedforward: bool = True,
        ff_direction: str = "measured",
        min_speed: float = 0.005,
        forward_model: Mapping[str, Any] | None = None,
        modes: Mapping[str, Any] | None = None,
        loop: Mapping[str, Any] | None = None,
        key: str = "controller",
    ) -> None:
        self.loop = HybridLoop.from_config(loop, f"{key}.loop")
        self.dim = 0
        self.control_dt = 0.0
        self.k_free = check_positive(f"{key}.k_free", k_free)
        self.k_max = check_positive(f"{key}.k_max", k_max)
        if self.k_max < self.k_free:
            raise ConfigError(f"{key}.k_max", f"must be >= k_free={k_free}, got {k_max}")
        self.key = key
        self.adaptive = check_bool(f"{key}.adaptive", adaptive)
        #: λ(ε) of Eq. 4c with its ε₀ and r (given or calibrated)
        self.gate = LogisticGate(r, eps0, calibrate, active=self.adaptive, key=key)
        self.error_lowpass_s = check_nonneg(f"{key}.error_lowpass_s", error_lowpass_s)
        self.feedforward = check_bool(f"{key}.feedforward", feedforward)
        self.ff_direction = check_choice(f"{key}.ff_direction", ff_direction, FF_DIRECTIONS)
        self.min_speed = check_nonneg(f"{key}.min_speed", min_speed)
        self.model = make_forward_model(dict(forward_model or {}), f"{key}.forward_model")
        self.modes = None if modes is None else ContactModes(modes, self.model, forward_model, key)

    @property
    def type_name(self) -> str:
        """The name a saved learned state records: ``avic``, or ``avic_modes`` with
        Algorithm 1 (a ``modes`` block), so that a state is loaded only into its kind."""
        return "avic" if self.modes is None else MODAL_TYPE

    def reset(self, dim: int, control_dt: float) -> None:
        super().reset(dim, control_dt)
        self.loop.reset(dim, control_dt)
        self._lam = 0.0  # start stiff (K_max) until the model has proven itself
        h = horizon_steps(self.model.horizon_s, control_dt, f"{self.key}.forward_model.horizon_s")
        self.forecast = ForecastBuffer(h)
        if self.modes is not None:
            self.modes.reset(control_dt)
            self.model = self.modes.model
        tau = self.error_lowpass_s
        self._err_alpha = (
            1.0 if tau == 0.0 else first_order_alpha(control_dt, 1 / (2 * math.pi * tau))
        )
        self._err_lp = math.nan  # ε̄_t: the low-passed error of this trial
        # Learning X_t just before predicting (one kernel call) changes nothing in between
        # with one model: only learn() touches it, and the gains and the force loop do not
        # read it (Algorithm 1 may hold back or replay a sample, so it learns separately).
        self._fused = self.modes is None and hasattr(self.model, "update_predict")
        self.last_feedforward = np.zeros(dim)  # λ Ŵ subtracted by the last step (Eq. 4a)
        self._signals = {  # the loop's keys after the gains, as FixedImpedance logs them
            "stiffness_Npm": math.nan,
            "damping_Nspm": self.loop.damping_for(self.k_max),
            **self.loop.signals(),
            **self._avic_signals(math.nan, math.nan, math.nan, math.nan),
            **({} if self.modes is None else self.modes.last_signals),
        }

    @property
    def calibrating(self) -> bool:
        """True while ``calibrate`` still collects the errors that set ε₀ and r (never for the
        non-adaptive baseline, which does not use them)."""
        return self.gate.calibrating

    def _avic_signals(self, pred: float, persist: float, err: float, kp: float) -> dict[str, float]:
        return {
            "lambda": self._lam,
            "pred_force_N": pred,
            "persist_force_N": persist,
            "pred_error_N": err,
            "pred_error_lp_N": self._err_lp,
            "n_components": float(getattr(self.model, "n_components", 0)),
            "stiffness_Npm": kp,
            "calibrating": float(self.calibrating),
        }

    def stiffness_for(self, lam: float) -> float:
        """K_p of Eq. 4b."""
        return self.k_free + (1.0 - lam) * (self.k_max - self.k_free)

    def step(self, obs: Observation, target: TargetSample) -> Command:
        """Eq. 4a–4c: learn from the newest sample, adapt λ and K_p, add the feed-forward."""
        s = magnitudes(obs.lin_vel, obs.ang_vel, obs.force, obs.torque)
        d = s[2:N_STATE]
        modes = self.modes
        if modes is not None:  # Algorithm 1, lines 2–7, on this step's measurements
            modes.before_step(obs, target)
            self._signals.update(modes.last_signals)
            if modes.switched:
                self._use_mode_model()
        s_past, pred_now = self.forecast.past()  # S_{t−H} and D̂_t = f(S_{t−H})
        err = persist = pred = math.nan
        fused = self._fused and s_past is not None  # learn with the prediction below
        if s_past is not None:
            if pred_now is not None and self.model.ready:
                (pred, pred_tq), (_, _, d_f, d_tq) = pred_now.tolist(), s.tolist()
                persist = float(s_past[2])
                err = math.hypot(d_f - pred, d_tq - pred_tq)
                self._observe_error(err)
                if modes is not None:  # the prequential evidence rule's data
                    modes.observe_error(err, self.gate.eps0)
            if not fused:
                self.learn(s_past, d)
        calibrating = self.calibrating  # fixed during a trial
        stiff = not self.adaptive or calibrating or (modes is not None and modes.hold_k_max())
        lam = 0.0 if stiff else self._lam
        kp = self.k_max if stiff else self.stiffness_for(lam)
        loop = self.loop
        kd = loop.damping_for(kp, loop.inertia_of(obs))
        u_motion, u_force = loop.motion_force(obs, target, kp, kd)
        model = self.model
        if fused:
            self.forecast.push(s, model.update_predict(s_past, d, s))
        else:
            self.forecast.push(s, model.predict(s) if model.ready else None)
        pred_next = self.forecast.next_prediction()  # D̂_{t+1}, for the command until t+1
        u = u_motion  # a fresh array; the force loop (if any) is added in place
        if u_force is not loop.zero:
            u += u_force
        self.last_feedforward = loop.zero  # λ Ŵ of Eq. 4a as applied (Eq. 8 reuses it)
        if self.feedforward and pred_next is not None and lam > 0.0:
            w = self.predicted_wrench(float(pred_next[0]), obs)
            if target.force_dir is not None:
                w = w - target.force_dir * float(target.force_dir @ w)
            self.last_feedforward = lam * w
            u -= self.last_feedforward
        sig = self._signals  # the fixed key set of _avic_signals, updated in place
        sig["lambda"], sig["pred_force_N"], sig["persist_force_N"] = self._lam, pred, persist
        sig["pred_error_N"], sig["pred_error_lp_N"] = err, self._err_lp
        sig["stiffness_Npm"], sig["damping_Nspm"] = kp, mean_gain(kd)
        sig["n_components"] = float(getattr(model, "n_components", 0))
        sig["calibrating"] = 1.0 if calibrating else 0.0
        sig["force_error_N"], sig["force_control"] = loop.force_error_N, loop.force_control
        return Command(force=u, torque=loop.rotation_torque(obs, target))

    def signals(self) -> dict[str, float]:
        return dict(self._signals)

    def signal(self, name: str) -> float:
        """One signal of the last step, without the copy :meth:`signals` makes (for a
        controller that holds this one, e.g. the anticipating one)."""
        return self._signals[name]

    def _observe_error(self, err: float) -> None:
        """λ_t of Eq. 4c from ε̄_t (ε_t low-passed), or keep ε̄_t to calibrate ε₀ and r."""
        lp = self._err_lp
        self._err_lp = err if math.isnan(lp) else lp + self._err_alpha * (err - lp)
        if self.gate.calibrating:
            self.gate.keep(self._err_lp)
        else:
            self._lam = self.gate(self._err_lp)

    def _use_mode_model(self) -> None:
        """Make the current mode's model the one that predicts: the previous model's
        predictions are forgotten and λ restarts from K_max (its first error sets it)."""
        assert self.modes is not None
        self.model = self.modes.model
        self.forecast.forget_predictions()
        self._lam = 0.0

    def learn(self, s_prev: np.ndarray, d_now: np.ndarray) -> None:
        """Revise the forward model with X_t = [S_{t−1}, D_t] (Eq. 5); with Algorithm 1 the
        current mode's model, or none while the mode is being decided."""
        if self.modes is None:
            self.model.update(s_prev, d_now)
        else:
            self.modes.learn(s_prev, d_now)

    def predicted_wrench(self, f_mag: float, obs: Observation) -> np.ndarray:
        """Ŵ: the predicted external force as a vector (see ``ff_direction``)."""
        if self.ff_direction == "measured":
            fm = math.hypot(*obs.force.tolist())
            return obs.force * (f_mag / fm) if fm >= 1e-9 else np.zeros(obs.position.shape[0])
        speed = math.hypot(*obs.lin_vel.tolist())
        if speed < self.min_speed:
            return np.zeros(obs.position.shape[0])
        if self.ff_direction == "against_motion":
            return obs.lin_vel * (-f_mag / speed)
        fm = math.hypot(*obs.force.tolist())  # along_motion
        if fm < 1e-9:
            return np.zeros(obs.position.shape[0])
        along = float(obs.force @ obs.lin_vel) / speed  # F·v̂
        return obs.lin_vel * (f_mag * along / (fm * speed))

    def end_trial(self) -> None:
        """The forward model's (every mode's) end-of-trial hook, and the calibration."""
        if self.modes is None:
            self.model.end_trial()
        else:
            self.modes.end_trial()
        self.gate.end_trial(getattr(self.model, "fit_errors", None), self._err_alpha)

    def report(self) -> dict[str, Any]:
        """K_free, K_max and the logistic's ε₀ and r (None while calibrating), for metrics."""
        return {"k_free": self.k_free, "k_max": self.k_max, **self.gate.params()}

    def state_dict(self) -> dict[str, Any]:
        """The calibration of ε₀ and r and the forward model
        (:meth:`IncrementalForwardModel.state_dict` or the fixed GMM's), or with Algorithm 1
        :meth:`ContactModes.state_dict`; λ and the predictions are per-trial state."""
        if self.modes is None:
            return {
                "forward_model": self.model.state_dict(),
                "calibration": self.gate.state_dict(),
            }
        return {"calibration": self.gate.state_dict(), **self.modes.state_dict()}

    def load_state_dict(self, state: Mapping[str, Any]) -> None:
        """Restore :meth:`state_dict` output into the forward model(s) built from the config
        (same ``forward_model.kind`` and ``feature_scale``; other settings stay the config's).

        Raises:
            ConfigError: ``init_from``, on a malformed or mismatched state.
        """
        own = ("forward_model",) if self.modes is None else ("classifier", "modes")
        check_state_keys(state, ("calibration", *own))
        try:  # the model(s) change only if their whole snapshot is accepted
            if self.modes is None:
                self.model.load_state_dict(state["forward_model"])
            else:
                self.modes.load_state_dict({k: state[k] for k in own})
            self.gate.load_state_dict(state["calibration"])
        except STATE_ERRORS as exc:
            raise state_error(exc) from None
        if self.modes is not None:
            self.model = self.modes.model
            if hasattr(self, "forecast"):
                self.forecast.forget_predictions()
            self._lam = 0.0
