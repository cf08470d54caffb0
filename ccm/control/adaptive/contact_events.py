"""Contact events of the anticipating controller (seed A §3.3): transition windows, which
detector spikes are collisions, quasi-static contacts and association in plan order.

:class:`ContactEvents` is a mixin of :class:`ccm.control.adaptive.anticipation.AnticipatoryAVIC`; it
reads the controller's ``_windows`` (:class:`TransitionWindow`), ``detector``
(:class:`ccm.learn.contact.collisions.CollisionDetector`), ``contact_map``
(:class:`ccm.learn.contact.contacts.ContactMap`), the histories ``_vel_hist`` (planned velocity) and
``_force_hist`` (measured force), the stall state ``_stall_since`` / ``_stall_used`` and the
settings ``stall_fraction``, ``stall_lookback_s``, ``stall_travel_m``, ``order_gate`` and
``blend_s``.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass
from typing import Any

import numpy as np

from ccm.core.types import Observation, TargetSample


@dataclass
class TransitionWindow:
    """One anticipated transition in wall time: the Eq. 10 weight rises over [t0, t1] (t1 is
    when the path reaches p_c), stays 1, and falls over ``blend_s`` from ``release``."""

    contact: int
    kind: str
    t0: float
    t1: float
    release: float  # planned: where the path leaves C; moved earlier when the contact is made
    done: bool = False

    def alpha(self, t: float, blend_s: float) -> float:
        if t < self.t0:
            return 0.0
        if t < self.t1:
            return (t - self.t0) / (self.t1 - self.t0)  # Eq. 10: α = t / T
        if t < self.release:
            return 1.0
        return max(0.0, 1.0 - (t - self.release) / blend_s)


class ContactEvents:
    """Event interpretation for :class:`ccm.control.adaptive.anticipation.AnticipatoryAVIC`."""

    _windows: list[TransitionWindow]
    detector: Any
    contact_map: Any
    _vel_hist: deque[tuple[float, np.ndarray]]
    _force_hist: deque[tuple[float, np.ndarray]]
    _stall_since: float
    _stall_used: bool
    cfg: Any  # AnticipationSettings
    k_collision: float
    control_dt: float
    _stall_u: np.ndarray
    _slide_resist: float
    _slide_u: np.ndarray | None
    _resist_hist: deque[tuple[float, float]]
    _stall_speed: float
    _stall_peak: float

    def _pressed(self, obs: Observation, target: TargetSample) -> bool:
        """Whether a collision was made *quasi-statically* in an open window, past p_c.

        A stall begins when the tool's speed along the commanded motion u falls below
        ``stall_fraction`` of the commanded speed; it ends when the tool moves on along u, or
        when the plan moves on in another direction (cos < ``approach_cos_min`` with u: a
        stall at a wall that ended in a contact would otherwise last through the slide along
        it and block the next contact's test, as it did in trial 1 of h4_collisions, whose
        regions overlap, on 7 of 20 seeds).
        After twice the detector's peak window (a collision the detector will report is left
        to it) the contact is declared if, since the stall began, either the force against u
        has risen by the detector's jump threshold (over its level ``stall_lookback_s``
        before the stall), or the target has run so far ahead of the tool along u that the
        transition controller's pull K* · lag exceeds the resistance the tool met while it
        last slid along u in this window (``_slide_resist``) by K* · ``stall_travel_m``:
        lag >= resistance / K* + ``stall_travel_m``. Friction alone cannot hold the tool
        against that pull (Coulomb: it resists at most what it resisted while sliding).

        The lag test is needed because a tool sliding into an obstacle trades its sliding
        friction for the obstacle's reaction: the force against u hardly changes (3.5 ->
        4.4 N at the obstacle of ``h4_contact_learning``, measured). It is measured from the
        sliding resistance, not from where the stall began, because a tool stalls by friction
        whenever its lag is below resistance / K*: after the slow-down to v_a the stiffness
        falls from K_max to K*, the lag must grow from ~5 mm to ~1.1 cm, and the tool sticks
        meanwhile (seed 5 of ``h4_contact_learning``, trials 2, 4 and 5: such a stall 2-2.7 cm
        short of the obstacle passed a 3 mm travel test, the cap was released, and the
        obstacle was met at the plan's speed, 21-60 N). At a slow approach a contact may show
        neither the spike nor the sudden loss of speed of a collision (seed A §6: "difficult
        to isolate the impact force from the force due to surface friction"); without this
        rule the slow phase would last to the region's end. The stall's commanded speed
        (``_stall_speed``) and the largest force against u during it (``_stall_peak``) are
        its Eq. 9 measurement: an impact too small to detect.

        The commanded motion u is the position-controlled part of the plan's velocity
        (:meth:`_position_motion`): along a force direction that the collision transition keeps
        under its force loop, the target's motion commands nothing.
        """
        active = any(w.kind == "collision" and not w.done and obs.t >= w.t1 for w in self._windows)
        velocity = self._position_motion(target)
        speed = math.sqrt(float(velocity @ velocity))
        moving = speed >= self.detector.min_approach_speed
        if not active or (moving and self._turned(velocity / speed)):
            self._new_direction(velocity / speed if active else None)
        if not active:
            return False
        if self._stall_since == math.inf:
            if moving:
                self._stall_begins(obs, velocity / speed, speed)
            return False  # not approaching anything, or the stall has just begun
        return self._stall_is_contact(obs, target, speed)

    def _position_motion(self, target: TargetSample) -> np.ndarray:
        """The planned velocity without its part along ``target.force_dir`` d when the
        collision transition keeps the force loop there (Eq. 1's hybrid law, Eq. 8: d across
        the motion, |cos| <= ``force_along_cos``; along the motion it drops the loop and the
        target's motion is position-controlled). Along such a d the force loop presses with
        the configured force and the tool does not follow the target's position, so neither
        the target's motion nor the surface's reaction to the press belongs to a stall test.
        Seed 237 of h4_collisions (issue #38 part 7): sliding up the blue wall (d = +y, the
        target's y moving 1.5 cm in -y, |cos| 0.49) the wall's 5 N reaction, counted along u,
        cancelled the 2 N of friction, the sliding resistance read 0, a friction stall 3 mm
        behind the target passed the lag test (>= 0 / K* + 1 mm), was taken for the red top
        (1.8σ from its belief, inside C), released its cap, and the red top was met at the
        plan's 0.08 m/s (154 N)."""
        v = target.velocity
        d = target.force_dir
        if d is None:
            return v
        along = float(v @ d)
        if abs(along) > self.cfg.force_along_cos * math.sqrt(float(v @ v)):
            return v  # the transition controller drops this force loop: position-controlled
        return v - along * d

    def _stall_begins(self, obs: Observation, u: np.ndarray, speed: float) -> None:
        """Track the sliding resistance along u while the tool slides; start a stall when it
        stops sliding (not from rest: a tool that never slid along u has not stalled)."""
        if float(obs.lin_vel @ u) > self.cfg.stall_fraction * speed:  # sliding along u
            self._track_resistance(obs.t, max(0.0, -float(obs.force @ u)))
        elif not math.isnan(self._slide_resist):
            self._stall_since, self._stall_u, self._stall_speed = obs.t, u, speed
            self._stall_peak = -float(obs.force @ u)

    def _stall_is_contact(self, obs: Observation, target: TargetSample, speed: float) -> bool:
        """During a stall: the force rise and lag tests of :meth:`_pressed`."""
        u = self._stall_u
        floor = max(speed, self.detector.min_approach_speed)
        if float(obs.lin_vel @ u) > self.cfg.stall_fraction * floor:  # the tool moves on
            self._stall_since, self._stall_used = math.inf, False
            return False
        self._stall_peak = max(self._stall_peak, -float(obs.force @ u))
        if self._stall_used or obs.t - self._stall_since < 2.0 * self.detector.peak_window_s:
            return False
        t_ref = self._stall_since - self.cfg.stall_lookback_s
        before = self._history(self._force_hist, t_ref)
        rise = -float((obs.force - before) @ u)
        # the resistance while sliding, stall_lookback_s before the stall (the last samples
        # before it hold the contact's own force rise)
        resist = float(self._history(self._resist_hist, t_ref))
        lag = float((target.position - obs.position) @ u)
        return (
            rise >= self.detector.jump_threshold_N
            or lag >= resist / self.k_collision + self.cfg.stall_travel_m
        )

    def _turned(self, u: np.ndarray) -> bool:
        """Whether the plan now moves in another direction than the one the sliding
        resistance was measured along (cos < ``approach_cos_min``)."""
        return self._slide_u is None or float(u @ self._slide_u) < self.cfg.approach_cos_min

    def _new_direction(self, u: np.ndarray | None) -> None:
        """The plan turned (or no collision window is open): the sliding resistance is
        measured afresh along u, and a stall along the old direction is over."""
        self._slide_u = u
        self._slide_resist = math.nan
        self._resist_hist.clear()
        self._stall_since, self._stall_used = math.inf, False

    def _track_resistance(self, t: float, force: float) -> None:
        """Average the force against the motion while the tool slides along it over
        ~``stall_lookback_s`` (first-order; the F/T noise) and keep its history."""
        r, tau = self._slide_resist, self.cfg.stall_lookback_s
        a = min(1.0, self.control_dt / tau) if tau > 0.0 else 1.0
        self._slide_resist = force if math.isnan(r) else r + a * (force - r)
        self._resist_hist.append((t, self._slide_resist))

    @staticmethod
    def _history(hist: deque[tuple[float, Any]], t: float) -> Any:
        """The last sample of a (t, vector) history at or before time t (the oldest if none)."""
        v = hist[0][1]
        for ti, vi in hist:
            if ti > t + 1e-12:
                break
            v = vi
        return v

    def _commanded_velocity(self, t: float) -> np.ndarray:
        """The planned (re-timed) velocity at time t (the last sample at or before it) [m/s]."""
        return self._history(self._vel_hist, t)

    def _anticipated(self, t: float) -> bool:
        """Whether a collision's transition-phase controller (Eq. 8) was blended in at time
        ``t`` (Eq. 10 weight > 0): an impact met without it was made by the base controller at
        the plan's speed, not by the approach that Eq. 9 and its linear model describe (seed A
        §3.4.1: the transition-phase controller's "relationship between impact force and
        approach velocity")."""
        blend = self.cfg.blend_s
        return any(w.kind == "collision" and w.alpha(t, blend) > 0.0 for w in self._windows)

    def _approaching(self, event: Any) -> bool:
        """Whether a detected spike is a collision *ahead*: the force acted against the motion
        (F_m >= the jump threshold) and the tool was moving along the commanded motion
        (cos >= ``approach_cos_min`` between v_pre and the planned velocity at the onset).
        Stick-slip while
        sliding along a wall also stops the tool with a force jump, across the motion
        (measured in h4_collisions: cos 0.16 at 8 mm/s)."""
        if event.impact_force_N < self.detector.jump_threshold_N:
            return False
        v_cmd = self._commanded_velocity(event.onset_time)
        v_pre = np.asarray(event.approach_velocity, dtype=float)
        den = float(np.linalg.norm(v_cmd) * np.linalg.norm(v_pre))
        return den > 0.0 and float(v_cmd @ v_pre) / den >= self.cfg.approach_cos_min

    def _in_sequence(self, z: np.ndarray, gate: float | None = None) -> int | None:
        """The collision contact a collision at z belongs to, by the plan's order (§3.3):
        one already made this trial, if z is within the map's gate of it (a repeat), else the
        first one in plan order not yet made, if z is within ``gate`` (default
        ``association_gate``) of it (Mahalanobis, with measurement noise), else None
        (nearest within the gate, or new).
        The task lists its contacts in the order the pattern meets them; early beliefs are
        wide (0.06 m per axis) and contacts 0.15-0.2 m apart, so nearest-belief association
        mixed them up in trial 1 (measured)."""
        assert self.contact_map is not None
        cm = self.contact_map

        def dist(c: Any) -> float:
            return float(c.belief.mahalanobis(z, c.belief.cov + c.belief.R))

        for i, c in enumerate(cm.contacts):
            if c.kind == "collision" and c.updated_this_trial and dist(c) <= cm.gate:
                return i
        for i, c in enumerate(cm.contacts):
            if c.kind == "collision" and c.source == "config" and not c.updated_this_trial:
                return (
                    i if dist(c) <= (self.cfg.association_gate if gate is None else gate) else None
                )
        return None

    def _expected(self, t: float, kind: str) -> int | None:
        """Of the contacts whose transition window of ``kind`` is open at time t, the first in
        plan order: the task lists its contacts
        in the order the pattern meets them, and contacts first seen later come after them.
        Early regions are large and overlap, so several windows can be open at once, and
        beliefs 0.1 m off cannot tell two contacts 8 cm apart by distance."""
        open_ = [
            w.contact for w in self._windows
            if w.kind == kind and not w.done and w.t0 <= t <= w.release + self.cfg.blend_s
        ]  # fmt: skip
        return min(open_) if open_ else None
