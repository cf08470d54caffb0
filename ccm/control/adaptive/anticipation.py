"""Seed A's full framework: AVIC with mode detection plus contact change handling (§3.3–3.5).

On top of :class:`ccm.control.adaptive.avic.AVIC` holding Algorithm 1 (Eq. 4a–4c, §3.2):

* **Contact anticipation** (§3.3): a :class:`ccm.learn.contact.contacts.ContactMap` holds one
Gaussian
  belief per expected contact, started from the task's nominal contacts plus seeded noise
  (the stand-in for vision) and revised by a Kalman update with the end-effector position at
  each detected contact. The region C of a contact is its belief ellipsoid at
  ``sigma_scale``.
* **Re-timing** (§3.5.2, Eq. 11): at the start of each trial the planned pattern is re-timed
  so that wherever the path approaches a collision inside its region C the target moves no
  faster than that contact's learned approach velocity v_a (Eq. 9,
  :class:`ccm.learn.contact.approach.ApproachVelocityModel`), a speed limit along the path
  (:mod:`ccm.control.adaptive.contact_regions`: C from the belief and the detection noise, capped
  per plan segment, every approaching pass). The slow-down is complete where the pass
  begins (p_c); it lasts until the contact is made (or the path leaves C), and then the
  plan's speed returns, all with C∞ rate changes. Holds, slow segments and the path outside
  C keep the plan's timing.
* **Transition-phase controllers** (§3.4, Eq. 8) blended in by Eq. 10: before an expected
  collision K* = ``k_collision``, with the base's force loop kept across the motion (the
  10 N press while sliding into a wall) but not along it (there the re-timed target, not a
  force loop, must set the approach speed); around an expected impact-less transition
  K* = K_max with the base's force loop; Eq. 8's u_ff (the base's λ Ŵ) only for the kinds
  in ``transition_feedforward`` (:mod:`ccm.control.adaptive.transition`). The collision weight takes
  precedence; the weights rise linearly to 1 by p_c and fall back over ``blend_s`` once the
  contact is made.
* **Events** (§3.3, :mod:`ccm.control.adaptive.contact_events`): collisions from
  :class:`ccm.learn.contact.collisions.CollisionDetector` (force jump and loss of velocity) when the
  tool was moving along the commanded motion; quasi-static contacts (the tool stalls and the
  force against the motion rises, with no detectable impact: position only); impact-less
  transitions from Algorithm 1's mode changes. Collisions are associated in plan order, the
  rest with the contact whose window is open (or a new one); a collision's commanded approach
  speed and measured impact force update that contact's approach model (Eq. 9). Recording
  an event in the map is :mod:`ccm.control.adaptive.contact_records`.

The controller sees only the Observation, the planned pattern and the task's nominal
contact list; never the scene. Results and how they compare with seed A: ``experiments/h4.md``.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from ccm.control.adaptive.anticipation_settings import AnticipationSettings
from ccm.control.adaptive.avic import AVIC
from ccm.control.adaptive.contact_events import ContactEvents, TransitionWindow
from ccm.control.adaptive.contact_records import ContactRecords
from ccm.control.adaptive.replan import plan_passes, rate_changes, windows_ahead
from ccm.control.adaptive.transition import KINDS, transition_force
from ccm.control.base import STATE_ERRORS, Controller, check_state_keys, state_error
from ccm.core.errors import ConfigError
from ccm.core.types import Command, Observation, TargetSample
from ccm.learn.contact.collisions import CollisionDetector
from ccm.learn.contact.contacts import ContactMap
from ccm.tasks.retiming import RetimedPattern, TimeWarp


class AnticipatoryAVIC(ContactRecords, ContactEvents, Controller):
    """AVIC + Algorithm 1 + contact anticipation and transition handling (seed A §3.3–3.5).

    Args:
        anticipation: ``sigma_scale`` (region C, Mahalanobis radius under the innovation
            covariance P + R: :mod:`ccm.control.adaptive.contact_regions`), ``min_region_radius_m``
            (floor on C's semi-axes [m]; 0 = none),
            ``blend_s`` (T of Eq. 10 and of the Eq. 11 rate changes [s]), ``k_collision``
            (K* of Eq. 8 before a collision [N/m]), ``path_dt`` (sampling of the plan for p_c [s]),
            ``init_noise_std`` / ``init_std`` (vision-noise and initial belief std [m]),
            ``detection_noise_std`` (noise of a detected contact's measured position, per
            axis [m]: :meth:`_measured`),
            ``use_kinds`` (which kinds of the task's contacts the robot is told about),
            ``stall_fraction`` / ``stall_lookback_s`` / ``stall_travel_m`` (the quasi-static
            contact rule of
            :meth:`_pressed`), ``association_gate`` (:meth:`_in_sequence`, in σ),
            ``approach_cos_min`` (:meth:`_approaching`), ``force_along_cos``
            (:meth:`_force_along_motion`), ``transition_feedforward`` (the kinds of
            transition controller that keep Eq. 8's u_ff: :mod:`ccm.control.adaptive.transition`),
            ``map`` (:class:`ContactMap` arguments) and ``collisions``
            (:class:`CollisionDetector` arguments).
        base: the base controller (:class:`AVIC`, Eq. 4a-4c, holding Algorithm 1's
            :class:`ContactModes`), or None to build one from ``avic``.
        **avic: the :class:`AVIC` arguments when ``base`` is None (``modes`` defaults to
            ``{}``: Algorithm 1 with its default settings).

    The base controller is a member: its command is blended with the transition-phase
    controllers', its signals and learned state are extended with the anticipation's.
    """

    def __init__(
        self,
        anticipation: Mapping[str, Any] | None = None,
        base: AVIC | None = None,
        **avic: Any,
    ) -> None:
        self.base = base if base is not None else AVIC(**{"modes": {}, **avic})
        if self.base.modes is None:
            raise ConfigError(f"{self.base.key}.modes", "the base AVIC needs Algorithm 1's modes")
        key = f"{self.base.key}.anticipation"
        self.ant_key = key
        self.cfg = cfg = AnticipationSettings.from_mapping(anticipation, key)
        self.k_collision = self.base.k_free if cfg.k_collision is None else cfg.k_collision
        self._meas_rng: np.random.Generator | None = None
        self.detector = CollisionDetector(**cfg.collisions, key=f"{key}.collisions")
        self.contact_map: ContactMap | None = None  # built at the first prepare(), then kept

    @classmethod
    def from_config(cls, cfg: Mapping[str, Any], key: str = "controller") -> AnticipatoryAVIC:
        """The ``anticipation`` block; everything else builds the base :class:`AVIC` with
        Algorithm 1 (its ``modes`` block, defaults where absent)."""
        rest = {k: v for k, v in cfg.items() if k != "anticipation"}
        base = AVIC.from_config({**rest, "modes": rest.get("modes") or {}}, key)
        return cls(anticipation=cfg.get("anticipation"), base=base)

    def reset(self, dim: int, control_dt: float) -> None:
        super().reset(dim, control_dt)
        self.base.reset(dim, control_dt)
        self.detector.reset()
        self._windows: list[TransitionWindow] = []
        self._impacts0: list[int] = []
        self._prior: list[tuple[list[float], float]] = []
        self._retimed: RetimedPattern | None = None
        self._slow: list[tuple[int, float, float, float]] = []  # contact, φ_c, φ_exit, v_a
        self._changes: list[tuple[float, float, float]] = []
        self._hits: dict[int, float] = {}  # contact -> wall time of the detected contact
        self._z: dict[int, list[list[float]]] = {}  # contact -> positions measured this trial
        self._trigger_pos: np.ndarray | None = None
        self._last_mode = -1.0
        # (t, planned velocity) of the last ~0.2 s: a collision's v of Eq. 9 is the speed the
        # robot was *commanded* to approach with at the onset (the quantity Eq. 9 revises)
        keep = self.cfg.stall_lookback_s + 2.0 * self.detector.peak_window_s + 0.2  # s of history
        self._vel_hist: deque[tuple[float, np.ndarray]] = deque(
            maxlen=max(2, round(keep / control_dt))
        )
        self._force_hist: deque[tuple[float, np.ndarray]] = deque(maxlen=self._vel_hist.maxlen)
        self._target_hist: deque[tuple[float, np.ndarray]] = deque(maxlen=self._vel_hist.maxlen)
        self._trigger_target: tuple[np.ndarray, np.ndarray] | None = None
        self._resist_hist: deque[tuple[float, float]] = deque(maxlen=self._vel_hist.maxlen)
        self._new_direction(None)  # the stall and sliding-resistance state (ContactEvents)
        self._ant = self._ant_signals(0.0, 0.0)
        self._stiffness: float | None = None  # K_p blended with the transition controllers

    def _force_along_motion(self, d: np.ndarray, target: TargetSample) -> bool:
        """Whether the force-controlled direction d points along the planned motion (|cos| >
        ``force_along_cos``): then a force loop would drive the approach itself. Across the
        motion (a press on the table while sliding into a wall) the hybrid law keeps its force
        loop."""
        speed = math.sqrt(float(target.velocity @ target.velocity))
        return speed > 1e-9 and abs(float(d @ target.velocity)) > self.cfg.force_along_cos * speed

    def signals(self) -> dict[str, float]:
        """The base's signals (K_p blended while a transition controller acts) and the
        anticipation's: ``transition_alpha``, ``collision_event``, ``n_contacts_believed``,
        ``pattern_rate``."""
        out = self.base.signals()
        if self._stiffness is not None:
            out["stiffness_Npm"] = self._stiffness
        out.update(self._ant)
        return out

    def _ant_signals(self, alpha: float, event: float) -> dict[str, float]:
        return {
            "transition_alpha": alpha,
            "collision_event": event,
            "n_contacts_believed": float(len(self.contact_map.contacts) if self.contact_map else 0),
            "pattern_rate": 1.0,
        }

    # ------------------------------------------------------------------ planning (§3.5)

    def prepare(
        self, pattern: Any, contacts: Sequence[Mapping[str, Any]], rng: np.random.Generator
    ) -> Any:
        """Build the beliefs once (trial 1), then re-time P around every expected collision."""
        if self.contact_map is None:
            told = [c for c in contacts if c.get("kind", "collision") in self.cfg.use_kinds]
            self.contact_map = ContactMap.from_config(
                told, rng, init_noise_std=self.cfg.init_noise_std, init_std=self.cfg.init_std,
                dim=pattern.dim, key=f"{self.ant_key}.map", **self.cfg.map,
            )  # fmt: skip
        self._pattern = pattern
        self._meas_rng = rng  # this trial's detection noise (:meth:`_measured`)
        self._prior = [  # beliefs before this trial (report(): Table 1's "initial" column)
            (c.belief.mean.tolist(), float(np.sqrt(np.max(np.diag(c.belief.cov)))))
            for c in self.contact_map.contacts
        ]
        self._impacts0 = [  # Eq. 9 measurements before this trial, per contact (report())
            len(c.approach.velocities) if c.approach is not None else 0
            for c in self.contact_map.contacts
        ]
        self._slow, self._impactless = plan_passes(
            self.contact_map.contacts,
            pattern,
            self.cfg.path_dt,
            self.cfg.sigma_scale,
            self.cfg.min_region_radius_m,
        )
        self._changes, self._rate0 = [], 1.0
        self._replan(0.0)
        return self._retimed

    def _replan(self, t_from: float) -> None:
        """(Re)build the warp and the transition windows from wall time ``t_from`` on,
        keeping earlier rate changes (:mod:`ccm.control.adaptive.replan`)."""
        changes = [c for c in self._changes if c[0] < t_from]
        warp = TimeWarp(changes, rate0=self._rate0)
        phi_from = float(warp.phi(t_from)) if t_from > 0 else 0.0
        warp, self._rate0 = rate_changes(
            changes, warp, self._rate0, self._slow, self._hits, t_from, phi_from, self.cfg.blend_s
        )
        windows = [w for w in self._windows if w.t0 < t_from]
        windows += windows_ahead(
            self._slow, self._impactless, self._hits, warp, t_from, phi_from, self.cfg.blend_s
        )
        self._changes, self._windows = changes, windows
        if self._retimed is None:
            self._retimed = RetimedPattern(self._pattern, warp)
        else:  # the runner holds this object: swap its clock in place (φ is unchanged so far)
            self._retimed.warp = warp
            self._retimed.duration = warp.inverse(self._retimed.pattern.duration)

    # ------------------------------------------------------------------ control (Eq. 8, 10)

    def step(self, obs: Observation, target: TargetSample) -> Command:
        """Base command (Eq. 4a) blended with the transition-phase command (Eq. 8, Eq. 10)."""
        event = self.detector.update_obs(obs)
        # copies: the step objects may be reused (issue #40)
        self._vel_hist.append((obs.t, target.velocity.copy()))
        self._force_hist.append((obs.t, obs.force.copy()))
        self._target_hist.append((obs.t, target.position.copy()))
        base = self.base
        if base.signal("mode_trigger") == 1.0:
            self._trigger_pos = obs.position.copy()
            self._trigger_target = (target.position.copy(), target.velocity.copy())
        cmd = base.step(obs, target)
        self._impactless_event(obs)
        hit = self._contact_made(obs, target, event)
        cmd, alpha = self._blend_transitions(obs, target, cmd)
        self._ant = self._ant_signals(alpha, hit)
        if self._retimed is not None:
            self._ant["pattern_rate"] = float(self._retimed.warp.rate(obs.t))
        return cmd

    def _blend_transitions(
        self, obs: Observation, target: TargetSample, cmd: Command
    ) -> tuple[Command, float]:
        """Eq. 10 between the base command and the transition controllers (Eq. 8); the
        command and the total transition weight α."""
        # Eq. 10 with two transition controllers (Eq. 8): the collision one (K* = k_collision;
        # the base's force loop kept unless the force direction lies along the motion, where
        # the re-timed target, not the force loop, must set the approach speed) takes
        # precedence over the impact-less one (K* = K_max, force loop kept); weights
        # a_c + a_i <= 1, continuous in both.
        t, blend = obs.t, self.cfg.blend_s
        a_c = max((w.alpha(t, blend) for w in self._windows if w.kind == "collision"), default=0.0)
        a_i = max((w.alpha(t, blend) for w in self._windows if w.kind != "collision"), default=0.0)
        a_i = min(a_i, 1.0 - a_c)
        alpha = a_c + a_i
        self._stiffness = None
        if alpha > 0.0:
            base = self.base
            k1 = base.signal("stiffness_Npm")
            force = (1.0 - alpha) * cmd.force
            ff = base.last_feedforward  # Eq. 8's u_ff, for the kinds configured to keep it
            ff_c, ff_i = (ff if k in self.cfg.transition_feedforward else None for k in KINDS)
            hyb = base.loop
            d, u_fc = target.force_dir, hyb.last_force_loop
            m, m_ff = hyb.inertia_of(obs), hyb.inertia_feedforward
            if a_c > 0.0:  # Eq. 1's force loop kept across the motion only
                keep = d is not None and not self._force_along_motion(d, target)
                gains = (self.k_collision, hyb.damping_for(self.k_collision, m))
                force += a_c * transition_force(
                    obs, target, gains, m, m_ff, u_fc if keep else None, ff_c
                )
            if a_i > 0.0:
                gains = (base.k_max, hyb.damping_for(base.k_max, m))
                force += a_i * transition_force(obs, target, gains, m, m_ff, u_fc, ff_i)
            cmd = Command(force=force, torque=cmd.torque)
            self._stiffness = (1.0 - alpha) * k1 + a_c * self.k_collision + a_i * base.k_max
        return cmd, alpha

    def report(self) -> dict[str, Any]:
        """``contacts``: per contact belief, its name, kind and source, ``mean`` [m], ``std``
        (the largest standard deviation along an axis, the ± of seed A Table 1 [m]),
        ``region_m`` (the largest semi-axis of region C, R and floor included [m]),
        ``prior_mean`` / ``prior_std`` (the same before the trial; None for a contact first
        seen in it), ``measured`` (the contact positions z the Kalman update took this trial,
        [m] each: :meth:`_measured`) and, for a collision made this trial,
        ``approach_velocity`` (the commanded speed Eq. 9 recorded, m/s) and ``impact_force``
        (the F_m it measured, N); plus :meth:`AVIC.report`."""
        out = []
        contacts = self.contact_map.contacts if self.contact_map is not None else []
        for i, c in enumerate(contacts):
            before = self._impacts0[i] if i < len(self._impacts0) else 0
            prior = self._prior[i] if i < len(self._prior) else (None, None)
            made = c.approach is not None and len(c.approach.velocities) > before
            out.append({
                "name": c.name, "kind": c.kind, "source": c.source,
                "mean": c.belief.mean.tolist(),
                "std": float(np.sqrt(np.max(np.diag(c.belief.cov)))),
                "region_m": max(
                    self.cfg.sigma_scale
                    * float(np.sqrt(np.max(np.linalg.eigvalsh(c.belief.cov + c.belief.R)))),
                    self.cfg.min_region_radius_m,
                ),
                "prior_mean": prior[0], "prior_std": prior[1],
                "approach_velocity": c.approach.velocities[-1] if made else None,
                "impact_force": c.approach.forces[-1] if made else None,
                "measured": self._z.get(i, []),
            })  # fmt: skip
        return {**self.base.report(), "contacts": out}

    def end_trial(self) -> None:
        """Kalman predict step for every belief (§3.3); models of every mode (Algorithm 1)."""
        self.base.end_trial()
        if self.contact_map is not None:
            self.contact_map.end_trial()

    def state_dict(self) -> dict[str, Any]:
        """:meth:`AVIC.state_dict` (with Algorithm 1's modes) plus ``contact_map``: the contact
        beliefs and their approach-velocity models (:meth:`ContactMap.state_dict`; None before
        the first trial)."""
        state = self.base.state_dict()
        state["contact_map"] = None if self.contact_map is None else self.contact_map.state_dict()
        return state

    def load_state_dict(self, state: Mapping[str, Any]) -> None:
        """Restore :meth:`state_dict` output. A saved contact map replaces the one
        :meth:`prepare` would build from the task's nominal contacts (it builds one only while
        there is none); its settings (``anticipation.map``) stay this config's.

        Raises:
            ConfigError: ``init_from``, on a malformed or mismatched state.
        """
        check_state_keys(state, ("calibration", "classifier", "modes", "contact_map"))
        data, cmap = state["contact_map"], None
        if data is not None:
            try:
                key = f"{self.ant_key}.map"
                ours = ContactMap(data["settings"]["dim"], **self.cfg.map, key=key)
                approach = ours.approach_params
                contacts = [
                    {**c, "approach": c["approach"] and {**c["approach"], "params": approach}}
                    for c in data["contacts"]
                ]
                merged = {**data, "settings": ours.state_dict()["settings"], "contacts": contacts}
                cmap = ContactMap.from_state_dict(merged, key="init_from")
                dim = getattr(self, "dim", cmap.dim)
                if cmap.dim != dim:
                    raise ConfigError(
                        "init_from", f"the contact map is {cmap.dim}-D, the task {dim}-D"
                    )
            except STATE_ERRORS as exc:
                raise state_error(exc) from None
        self.base.load_state_dict({k: v for k, v in state.items() if k != "contact_map"})
        self.contact_map = cmap
