"""Recording the contacts the anticipating controller detects (seed A §3.3, Eq. 9).

:class:`ContactRecords` is a mixin of :class:`ccm.control.adaptive.anticipation.AnticipatoryAVIC`
beside :class:`ccm.control.adaptive.contact_events.ContactEvents` (which decides what an event
is): a collision, a quasi-static contact or an Algorithm 1 mode change becomes a Kalman update
of the contact's belief in the ``contact_map`` (:class:`ccm.learn.contact.contacts.ContactMap`)
at the measured position z, with the commanded approach speed and the measured impact force
for Eq. 9 where the contact was approached under Eq. 8's controller; the measurement and the
target's lead are kept for the report and the next trial's p_c, and the contact's transition
windows are released (the controller's ``_replan`` then restores the plan's speed). It reads
the controller's ``base`` (:class:`ccm.control.adaptive.avic.AVIC`), ``detector``,
``contact_map``, ``cfg`` (``association_gate``, ``detection_noise_std``), the target history
``_target_hist``, the state ``_windows``, ``_hits``, ``_slow``, ``_z``, ``_retimed``,
``_trigger_pos`` / ``_trigger_target``, ``_last_mode``, ``_meas_rng`` and the stall state
``_stall_used`` / ``_stall_speed`` / ``_stall_peak``.
"""

from __future__ import annotations

from collections import deque
from typing import Any

import numpy as np

from ccm.control.adaptive.contact_events import TransitionWindow
from ccm.core.types import Observation, TargetSample


class ContactRecords:
    """Contact recording for :class:`ccm.control.adaptive.anticipation.AnticipatoryAVIC`."""

    base: Any  # AVIC
    detector: Any
    contact_map: Any
    cfg: Any  # AnticipationSettings
    _windows: list[TransitionWindow]
    _hits: dict[int, float]
    _slow: list[tuple[int, float, float, float]]
    _z: dict[int, list[list[float]]]
    _retimed: Any
    _target_hist: deque[tuple[float, np.ndarray]]
    _trigger_pos: np.ndarray | None
    _trigger_target: tuple[np.ndarray, np.ndarray] | None
    _last_mode: float
    _meas_rng: np.random.Generator | None
    _stall_used: bool

    def _contact_made(self, obs: Observation, target: TargetSample, event: Any) -> float:
        """Record a collision (1) or a quasi-static contact (2) in the map; 0 for none."""
        hit = 0.0
        if event is not None and not self._approaching(event):
            event = None
        if event is not None and self.contact_map is not None:
            z = self._measured(event.position)
            v_cmd = float(np.linalg.norm(self._commanded_velocity(event.onset_time)))
            measured = {"v_used": v_cmd, "f_measured": event.impact_force_N}
            if v_cmd < self.detector.min_approach_speed or not self._anticipated(event.onset_time):
                measured = {}  # not an approach under Eq. 8's controller: no Eq. 9 measurement
            ev = self.contact_map.observe(
                z, "collision", **measured,
                expected=self._in_sequence(z), expected_gate=self.cfg.association_gate,
            )  # fmt: skip
            t_on = event.onset_time
            at = (self._history(self._target_hist, t_on), self._commanded_velocity(t_on))
            self._record(ev.index, z, at)
            hit = 1.0
            self._release(ev.index, obs.t)
        elif self.contact_map is not None and self._pressed(obs, target):
            # contact made without a detectable impact (Eq. 9 gets the stall's peak force:
            # below F_d, so the next approach is faster); weaker evidence than a collision,
            # so it must lie within the map's gate of the next contact
            gate = self.contact_map.gate
            z = self._measured(obs.position)
            expected = self._in_sequence(z, gate)
            if expected is None:
                self._stall_used = True  # e.g. stick-slip short of the contact: not again
            else:
                ev = self.contact_map.observe(
                    z, "collision", v_used=self._stall_speed,
                    f_measured=self._stall_peak, expected=expected, expected_gate=gate,
                )  # fmt: skip
                self._record(ev.index, z, (target.position, target.velocity))
                hit = 2.0
                self._release(ev.index, obs.t)
        return hit

    def _impactless_event(self, obs: Observation) -> None:
        """An Algorithm 1 decision that changes the mode is an impact-less contact event."""
        event, mode = self.base.signal("mode_event"), self.base.signal("mode")
        if event > 0 and self._trigger_pos is not None and self.contact_map is not None:
            if self._last_mode >= 0 and mode != self._last_mode:
                z = self._measured(self._trigger_pos)
                ev = self.contact_map.observe(
                    z, "impactless", expected=self._expected(obs.t, "impactless")
                )
                self._record(ev.index, z, self._trigger_target)
                for w in self._windows:
                    if w.contact == ev.index and not w.done:
                        w.release, w.done = min(w.release, obs.t), True
        self._last_mode = mode

    def _measured(self, position: np.ndarray) -> np.ndarray:
        """The contact position z the robot measures when it detects a contact (§3.3: the
        end-effector position "obtained by forward kinematics with joint positions"): the tool
        position at the detected onset. What separates z from the true contact is then what the
        detection chain does: the onset is found on the noisy F/T stream (the jump test's
        latency, the tool's travel into the compliant contact meanwhile) and the tool's
        tracking error while sliding (issue #38 item 3; the error is measured per contact as
        ``detection_error_m_<name>``, :mod:`ccm.metrics.contacts`: 0.05-0.26 mm in the H4
        scenes, experiments/h4.md). ``detection_noise_std`` > 0 adds seeded Gaussian noise per
        axis on top, drawn from this trial's generator: a stand-in for the kinematic error of a
        real arm, which the simulator's exact pose lacks (the paper configs: 5 mm)."""
        z = np.array(position, dtype=float)
        if self.cfg.detection_noise_std > 0.0 and self._meas_rng is not None:
            z = z + self._meas_rng.normal(0.0, self.cfg.detection_noise_std, size=z.shape)
        return z

    def _record(
        self, contact: int, z: np.ndarray, target: tuple[np.ndarray, np.ndarray] | None
    ) -> None:
        """Keep a measurement z for :meth:`report`, and the contact's ``lead``: the target's
        offset from z across the planned motion when z was taken (``target`` = the target's
        position and velocity then). It is where the target runs when the tool meets the
        contact, which the next trial's p_c is found with
        (:func:`ccm.control.adaptive.replan.plan_passes`). Along the motion the offset is the
        tool's lag, which depends on the stiffness acting then (K* after a slow-down, the
        base's K before one: carried over, it made every other trial meet the wall at 0.06
        m/s, measured); it is left out, so p_c comes early rather than late."""
        self._z.setdefault(contact, []).append(z.tolist())
        if target is None or self.contact_map is None:
            return
        lead = np.asarray(target[0], dtype=float) - z
        v = np.asarray(target[1], dtype=float)
        speed = float(np.linalg.norm(v))
        if speed > 1e-9:
            lead = lead - (lead @ v) * v / speed**2
        self.contact_map.contacts[contact].lead = lead

    def _release(self, contact: int, t: float) -> None:
        """Contact made: leave the transition controller and return to the plan's speed."""
        for w in self._windows:
            if w.contact == contact and not w.done:
                w.release, w.done = min(w.release, t), True
        self._stall_used = True  # this contact's stall is no evidence for the others
        if contact in self._hits:
            return
        self._hits[contact] = t
        if any(i == contact for i, *_ in self._slow) and self._retimed is not None:
            self._replan(t)  # keep the clock so far; later spans only (this one is made)
