"""Mechanics of the contact-anticipating controller (seed A §3.3-3.5): re-timing to the
approach velocity at p_c, the Eq. 10 blend, release on contact. Its H4 results are not
validated yet (issue #5)."""

from __future__ import annotations

import copy

import numpy as np
import pytest

from ccm.control.adaptive.anticipation import AnticipatoryAVIC
from ccm.control.adaptive.avic import AVIC
from ccm.control.adaptive.contact_events import TransitionWindow
from ccm.control.adaptive.contact_regions import region_mask
from ccm.control.adaptive.logistic import check_calibrate
from ccm.core.errors import ConfigError
from ccm.core.types import Observation, TargetSample

CONTACT = [{"name": "mid", "position": [0.0, 0.08], "kind": "collision"}]  # on the approach


def make(**anticipation) -> AnticipatoryAVIC:
    settings = {"init_noise_std": 1e-9, "init_std": 0.01, "sigma_scale": 2.0, **anticipation}
    c = AnticipatoryAVIC(anticipation=settings, k_free=300.0, k_max=3000.0)
    c.reset(2, 0.001)
    return c


@pytest.fixture
def pattern(composer):
    from ccm.tasks.task import load_task

    return load_task(composer(["task=slide_surfaces_2d"]).task, 0.001).pattern


def test_speed_reaches_the_approach_velocity_at_p_c(pattern) -> None:
    c = make()
    retimed = c.prepare(pattern, CONTACT, np.random.default_rng(0))
    (w,) = c._windows  # noqa: SLF001 - the one anticipated collision
    t_c = w.t1  # wall time at which the path reaches p_c
    s = copy.deepcopy(retimed.sample(t_c))  # the pattern reuses its sample (issue #40)
    # inside C the target never moves faster than v_a (v_safe, 0.05 m/s), and reaches it
    speeds = [np.linalg.norm(retimed.sample(t).velocity) for t in np.linspace(t_c, w.release, 500)]
    assert max(speeds) <= 0.05 + 1e-9
    assert max(speeds) == pytest.approx(0.05, rel=0.01)
    belief = c.contact_map.contacts[
        0
    ].belief  # C: 2 sigma of P + R (ccm.control.adaptive.contact_regions)
    assert region_mask(belief, s.position[None, :], 2.0)[0]  # p_c is on the region's boundary
    before = retimed.warp.inverse(retimed.warp.phi(t_c) - c.cfg.path_dt)  # the plan sample before
    assert not region_mask(belief, retimed.sample(before).position[None, :], 2.0)[0]
    assert retimed.duration > pattern.duration  # slower through C
    assert w.alpha(w.t0, c.cfg.blend_s) == 0.0 and w.alpha(t_c, c.cfg.blend_s) == 1.0  # Eq. 10 ramp


def test_contact_made_releases_the_transition_and_the_speed(pattern) -> None:
    c = make()
    retimed = c.prepare(pattern, CONTACT, np.random.default_rng(0))
    (w,) = c._windows  # noqa: SLF001
    t_hit = w.t1 + 0.05
    phi_before = retimed.warp.phi(t_hit)
    c._release(0, t_hit)  # noqa: SLF001 - as a detected collision at the expected contact
    assert retimed.warp.phi(t_hit) == pytest.approx(phi_before, abs=1e-12)  # φ continuous
    assert retimed.warp.rate(t_hit + c.cfg.blend_s + 1e-6) == pytest.approx(1.0)  # plan speed
    assert w.alpha(t_hit + c.cfg.blend_s, c.cfg.blend_s) == pytest.approx(
        0.0, abs=1e-12
    )  # base again


def test_bad_settings_name_the_key() -> None:
    with pytest.raises(ConfigError, match="controller.anticipation.bogus"):
        AnticipatoryAVIC(anticipation={"bogus": 1})
    with pytest.raises(ConfigError, match="controller.anticipation.use_kinds"):
        AnticipatoryAVIC(anticipation={"use_kinds": ["vision"]})
    with pytest.raises(ConfigError) as err:  # anticipation builds on Algorithm 1's modes
        AnticipatoryAVIC(base=AVIC())
    assert str(err.value) == "controller.modes: the base AVIC needs Algorithm 1's modes"
    with pytest.raises(ConfigError) as err:
        check_calibrate(3, "controller.modes.calibrate")
    assert str(err.value) == (
        "controller.modes.calibrate: must be a mapping {trials, quantile, shape} or null, got 3"
    )


# ----------------------------------------------------------------- H4 mechanics (issue #5)

THREE = [
    {"name": "a", "position": [0.0, 0.00], "kind": "collision"},
    {"name": "b", "position": [0.0, 0.05], "kind": "collision"},
    {"name": "c", "position": [0.0, 0.10], "kind": "collision"},
]


def obs_at(t: float, pos=(0.0, 0.0), vel=(0.0, 0.0), force=(0.0, 0.0)) -> Observation:
    z = np.zeros(1)
    return Observation(t, np.array(pos, float), z, np.array(vel, float), z.copy(),
                       np.array(force, float), z.copy())  # fmt: skip


def test_collisions_are_associated_in_plan_order(pattern) -> None:
    """Beliefs 2 cm wide and contacts 5 cm apart: a collision goes to the next contact in plan
    order if it is within the association gate of it, a repeat to the contact already made,
    and one beyond the gate of the next contact to no contact (nearest or new)."""
    c = make(init_std=0.02, association_gate=5.0)
    c.prepare(pattern, THREE, np.random.default_rng(0))
    cm = c.contact_map
    z = np.array([0.0, 0.04])  # nearer b, but a comes first and gates it (2.0 sigma)
    assert c._in_sequence(z) == 0  # noqa: SLF001
    cm.observe(z, "collision", expected=0)
    assert c._in_sequence(np.array([0.0, 0.041])) == 0  # noqa: SLF001 - a repeat of a
    assert c._in_sequence(np.array([0.0, 0.08])) == 1  # noqa: SLF001 - next: b
    assert c._in_sequence(np.array([0.3, 0.3])) is None  # noqa: SLF001 - far from b


def test_spike_across_the_commanded_motion_is_no_collision(pattern) -> None:
    """A force jump while the tool moves across the planned motion (stick-slip along a wall)
    or a force that does not act against the motion is not a collision ahead."""
    from ccm.learn.contact.collisions import CollisionEvent

    c = make()
    c.prepare(pattern, CONTACT, np.random.default_rng(0))
    c._vel_hist.append((0.0, np.array([0.0, 0.05])))  # noqa: SLF001 - planned: along +y

    def event(v_pre, f_m):
        z2 = np.zeros(2)
        return CollisionEvent(0.0, 0.0, 0.0, z2, np.array(v_pre, float), z2, f_m, f_m, f_m,
                              0.0, 1.0)  # fmt: skip

    assert c._approaching(event((0.0, 0.04), 8.0))  # noqa: SLF001
    assert not c._approaching(event((0.04, 0.0), 8.0))  # noqa: SLF001 - across the motion
    assert not c._approaching(event((0.0, 0.04), 1.0))  # noqa: SLF001 - below the jump


def test_collision_and_impactless_weights_sum_to_at_most_one(pattern) -> None:
    """Eq. 10 with two transition controllers: the collision weight takes precedence and the
    stiffness blends continuously (no jump from K_max to K* when windows overlap)."""
    c = make()
    c.prepare(pattern, CONTACT, np.random.default_rng(0))
    c._windows = [  # noqa: SLF001
        TransitionWindow(0, "impactless", 0.0, 0.1, 10.0),
        TransitionWindow(0, "collision", 0.2, 0.4, 10.0),
    ]
    tgt = pattern.sample(0.0)
    k_prev = None
    for t in np.arange(0.05, 0.5, 0.001):
        c.step(obs_at(float(t), pos=tgt.position), tgt)
        s = c.signals()
        assert s["transition_alpha"] <= 1.0 + 1e-12
        k = s["stiffness_Npm"]
        if k_prev is not None and 0.2 < t < 0.4:
            assert abs(k - k_prev) < 0.01 * (c.base.k_max - c.k_collision)  # no jump
        k_prev = k
    assert k_prev == pytest.approx(c.k_collision)  # collision window fully on


def test_quasi_static_contact_needs_a_stall_and_a_force_rise(pattern) -> None:
    """In an open collision window, a tool that stops while the plan moves on, with the force
    against the motion up by the jump threshold, has made the contact; once per stall."""
    c = make()
    c.prepare(pattern, CONTACT, np.random.default_rng(0))
    c._windows = [TransitionWindow(0, "collision", 0.0, 0.0, 10.0)]  # noqa: SLF001
    moving = TargetSample(0.0, np.zeros(2), np.array([0.0, 0.03]), np.zeros(2), np.zeros(1))
    fired = []
    for k in range(400):
        t = k * 0.001
        stalled = t >= 0.1
        force = (0.0, -6.0) if t >= 0.12 else (0.0, 0.0)  # pushes back once stalled
        o = obs_at(t, vel=(0.0, 0.0 if stalled else 0.03), force=force)
        c._vel_hist.append((t, moving.velocity))  # noqa: SLF001
        c._force_hist.append((t, o.force.copy()))  # noqa: SLF001
        if c._pressed(o, moving):  # noqa: SLF001
            fired.append(t)
            c._release(0, t)  # noqa: SLF001
    assert len(fired) == 1
    assert fired[0] == pytest.approx(0.1 + 2 * c.detector.peak_window_s, abs=0.002)


def press_step(
    c: AnticipatoryAVIC, t: float, target: TargetSample, o: Observation, fired: list[float]
) -> None:
    """One step of the quasi-static contact rule on hand-made histories: record the target's
    velocity and the force, and on a detected contact note ``t`` and release the window."""
    c._vel_hist.append((t, target.velocity))  # noqa: SLF001
    c._force_hist.append((t, o.force.copy()))  # noqa: SLF001
    if c._pressed(o, target):  # noqa: SLF001
        fired.append(t)
        c._release(0, t)  # noqa: SLF001


def _stall_run(c: AnticipatoryAVIC, breakaway_lag: float | None) -> list[float]:
    """Slide along +y at 0.03 m/s against 3 N of friction with a 5 mm lag, stall at 0.1 s
    while the target moves on (friction holding: the force stays at 3 N); with
    ``breakaway_lag`` the tool slides again once its lag reaches it. Times the rule fired."""
    c._windows = [TransitionWindow(0, "collision", 0.0, 0.0, 10.0)]  # noqa: SLF001
    fired, y_stop, sliding = [], None, True
    for k in range(600):
        t = k * 0.001
        y_target = 0.005 + 0.03 * t
        if sliding and t >= 0.1 and y_stop is None:
            y_stop, sliding = 0.03 * t, False
        if not sliding and breakaway_lag is not None and y_target - y_stop >= breakaway_lag:
            sliding = True
        y = 0.03 * t if y_stop is None else (y_stop if not sliding else y_target - breakaway_lag)
        target = TargetSample(t, np.array([0.0, y_target]), np.array([0.0, 0.03]), np.zeros(2),
                              np.zeros(1))  # fmt: skip
        o = obs_at(t, pos=(0.0, y), vel=(0.0, 0.03 if sliding else 0.0), force=(0.0, -3.0))
        press_step(c, t, target, o, fired)
    return fired


def test_quasi_static_contact_from_the_lag_beyond_the_sliding_resistance(pattern) -> None:
    """A stall with no force rise is a contact only once the pull K*·lag exceeds the
    resistance the tool slid against by K*·stall_travel_m: lag >= 3 N / 300 N/m + 1 mm =
    1.1 cm, reached 0.2 s after the stall (the lag grows from 5 mm at 0.03 m/s), not 3 mm of
    target travel after it. A friction stall that breaks away at a 9.5 mm lag is no contact
    (seed 5 of h4_contact_learning: such stalls were taken for the obstacle)."""
    c = make(stall_travel_m=0.001)
    c.prepare(pattern, CONTACT, np.random.default_rng(0))
    assert c.k_collision == pytest.approx(300.0)
    fired = _stall_run(c, breakaway_lag=None)
    assert len(fired) == 1 and fired[0] == pytest.approx(0.3, abs=0.003)
    c.reset(2, 0.001)
    c.prepare(pattern, CONTACT, np.random.default_rng(0))
    assert _stall_run(c, breakaway_lag=0.0095) == []


def test_a_stall_ends_when_the_plan_turns(pattern) -> None:
    """A stall at a wall that ended in a contact does not outlast the plan's turn: the slide
    along the wall (+x after a stall along +y) stalls anew at the next contact and fires,
    while the windows of both contacts stay open (trial 1's overlapping regions)."""
    c = make(stall_travel_m=0.001)
    c.prepare(pattern, CONTACT, np.random.default_rng(0))
    c._windows = [TransitionWindow(i, "collision", 0.0, 0.0, 10.0) for i in (0, 1)]  # noqa: SLF001
    fired, wall_y, stop_x = [], 0.003, 0.03 * 0.4
    for k in range(1400):
        t = k * 0.001
        if t < 0.5:  # into the wall along +y, 5 mm behind the target: stalls at 0.1 s
            y = min(0.03 * t, wall_y)
            tp, tv = (0.0, 0.005 + 0.03 * t), (0.0, 0.03)
            pos, vel = (0.0, y), (0.0, 0.0 if y >= wall_y else 0.03)
        else:  # along the wall (+x) with 3 N of friction, 5 mm behind, into a stop at stop_x
            x_t = 0.005 + 0.03 * (t - 0.5)
            x = min(x_t - 0.005, stop_x)
            tp, tv = (x_t, 0.0), (0.03, 0.0)
            pos, vel = (x, wall_y), (0.0 if x >= stop_x else 0.03, 0.0)
        target = TargetSample(t, np.array(tp), np.array(tv), np.zeros(2), np.zeros(1))
        force = (-3.0, 0.0) if t >= 0.5 else (0.0, -3.0)
        o = obs_at(t, pos=pos, vel=vel, force=force)
        c._vel_hist.append((t, target.velocity))  # noqa: SLF001
        c._force_hist.append((t, o.force.copy()))  # noqa: SLF001
        if c._pressed(o, target):  # noqa: SLF001
            fired.append(t)
            c._release(len(fired) - 1, t)  # noqa: SLF001
    assert len(fired) == 2 and fired[0] < 0.5 < fired[1]


def test_starting_from_rest_is_no_stall(pattern) -> None:
    """A tool held by static friction while its target pulls away from rest (the start of a
    slide along a wall) has never slid along the motion: no stall, however far the lag grows
    before it breaks away (seed 53 of h4_collisions: such a start, measured against the
    resistance of the previous direction, was taken for the next contact)."""
    c = make(stall_travel_m=0.001)
    c.prepare(pattern, CONTACT, np.random.default_rng(0))
    c._windows = [TransitionWindow(0, "collision", 0.0, 0.0, 10.0)]  # noqa: SLF001
    for k in range(600):
        t = k * 0.001
        lag = 0.03 * t
        y = max(0.0, lag - 0.012)  # breaks away at a 1.2 cm lag (3.6 N at 300 N/m)
        target = TargetSample(t, np.array([0.0, 0.03 * t]), np.array([0.0, 0.03]),
                              np.zeros(2), np.zeros(1))  # fmt: skip
        o = obs_at(t, pos=(0.0, y), vel=(0.0, 0.03 if y > 0 else 0.0), force=(0.0, -3.0))
        c._vel_hist.append((t, target.velocity))  # noqa: SLF001
        c._force_hist.append((t, o.force.copy()))  # noqa: SLF001
        assert not c._pressed(o, target)  # noqa: SLF001


def test_retimed_plan_with_overlapping_regions_is_smooth(pattern) -> None:
    """Wide, overlapping regions (trial 1) merge into one slow span: the re-timed target's
    rate, and so its velocity, acceleration and jerk (Eq. 11, Fig. 3), stay continuous at
    every rate change, the pattern's end is reached exactly, and the target never exceeds
    v_a inside any region."""
    c = make(init_std=0.03)
    retimed = c.prepare(pattern, THREE, np.random.default_rng(1))
    warp = retimed.warp
    assert len(c._changes) >= 2  # noqa: SLF001 - a slow-down and a speed-up at least
    for t_s, t_e, _ in c._changes:  # noqa: SLF001
        for t in (t_s, t_e):
            before, after = warp.evaluate(t - 1e-7), warp.evaluate(t + 1e-7)
            for d in range(1, 4):  # rate, its first and second derivatives
                assert float(after[d]) == pytest.approx(float(before[d]), abs=1e-4)
    end = retimed.sample(retimed.duration)
    np.testing.assert_allclose(end.position, pattern.sample(pattern.duration).position, atol=1e-9)
    for w in c._windows:  # noqa: SLF001
        ts = np.linspace(w.t1, w.release, 200)
        assert max(np.linalg.norm(retimed.sample(t).velocity) for t in ts) <= 0.05 + 1e-6


def test_collision_transition_keeps_the_press_across_the_motion(pattern) -> None:
    """Sliding into a wall while pressing on the table: the collision transition controller
    keeps the hybrid law's force loop along the press (across the motion) but position-
    controls a force direction that lies along the motion (there the re-timed target, not
    a force loop, must set the approach speed)."""
    c = make()
    c.prepare(pattern, CONTACT, np.random.default_rng(0))
    c._windows = [TransitionWindow(0, "collision", 0.0, 0.0, 10.0)]  # noqa: SLF001 - alpha = 1
    press = np.array([0.0, -1.0])

    def command(velocity) -> float:
        tgt = TargetSample(0.0, np.zeros(2), np.array(velocity, float), np.zeros(2),
                           np.zeros(1), press, 10.0)  # fmt: skip
        c.reset(2, 0.001)
        c._windows = [TransitionWindow(0, "collision", 0.0, 0.0, 10.0)]  # noqa: SLF001
        return float(c.step(obs_at(0.0), tgt).force @ press)

    # across the motion: ~F_d (1 + k_fp) pressed down; along it: only K* x 0 + D* x v
    assert command((0.05, 0.0)) == pytest.approx(10.0 * (1 + c.base.loop.force_kp), rel=0.05)
    assert abs(command((0.0, -0.05))) < 10.0


def test_detected_contact_position_carries_the_stated_noise(pattern) -> None:
    """``detection_noise_std`` (off in the paper configs since issue #38 item 3) adds that
    noise per axis to a detection's measured position; seeded, so reproducible."""
    exact = make()
    exact.prepare(pattern, CONTACT, np.random.default_rng(0))
    p = np.array([0.01, 0.08])
    assert np.array_equal(exact._measured(p), p)  # noqa: SLF001 - default: no noise
    draws = []
    for _ in range(2):
        c = make(detection_noise_std=0.005)
        c.prepare(pattern, CONTACT, np.random.default_rng(3))
        draws.append(np.array([c._measured(p) for _ in range(2000)]))  # noqa: SLF001
    assert np.array_equal(draws[0], draws[1])  # same seed, same measurements
    err = draws[0] - p
    assert np.all(np.abs(err.mean(axis=0)) < 0.0005)  # unbiased (5 sigma of the mean: 0.56 mm)
    assert np.allclose(err.std(axis=0), 0.005, rtol=0.08)  # the stated 5 mm per axis
    with pytest.raises(ConfigError, match="controller.anticipation.detection_noise_std"):
        make(detection_noise_std=-1.0)


def test_transition_controllers_add_the_base_feedforward_when_configured(
    pattern, monkeypatch
) -> None:
    """Eq. 8's u_ff (issue #17 item 5): a transition controller listed in
    ``transition_feedforward`` subtracts the base's λ Ŵ of this step, as Eq. 4a does; the
    others do not. With the weight at 1 the command differs by exactly u_ff."""
    from ccm.control.adaptive.avic import AVIC
    from ccm.core.types import Command

    ff = np.array([1.5, -0.5])

    def base_step(self, obs, target):  # the base's Eq. 4a with a known feed-forward
        self.last_feedforward, self.loop.last_force_loop = ff, np.zeros(2)
        return Command(force=np.zeros(2), torque=np.zeros(1))

    monkeypatch.setattr(AVIC, "step", base_step)
    tgt = TargetSample(0.0, np.zeros(2), np.array([0.05, 0.0]), np.zeros(2), np.zeros(1))

    def command(kind: str, keep: list[str]) -> np.ndarray:
        c = make(transition_feedforward=keep)
        c.prepare(pattern, CONTACT, np.random.default_rng(0))
        c._windows = [TransitionWindow(0, kind, 0.0, 0.0, 10.0)]  # noqa: SLF001 - alpha = 1
        return c.step(obs_at(0.0), tgt).force

    for kind in ("collision", "impactless"):
        without = command(kind, [])
        np.testing.assert_allclose(command(kind, [kind]), without - ff, atol=1e-12)
        other = "impactless" if kind == "collision" else "collision"
        np.testing.assert_allclose(command(kind, [other]), without, atol=1e-12)
    with pytest.raises(ConfigError, match="controller.anticipation.transition_feedforward"):
        make(transition_feedforward=True)


THERE_AND_BACK = {
    "name": "there_and_back",
    "dim": 2,
    "start": [0.0, 0.0],
    "scene": {"gravity": 0.0},
    "pattern": [
        {"type": "line", "to": [0.1, 0.0], "duration": 2.0},
        {"type": "line", "to": [0.0, 0.0], "duration": 2.0},
    ],
}


def test_every_crossing_of_an_impactless_region_gets_its_window() -> None:
    """A plan that passes the impact-less contact at x = 5 cm twice (out near t = 1 s, back
    near t = 3 s): two crossings of region C (the ball of 2 σ around the belief, σ² its
    covariance plus the measurement noise R, isotropic here), each
    from the first plan sample inside C to the first outside it, and two windows rising to
    where C begins; a collision-only controller ignores the contact altogether."""
    from ccm.tasks.task import load_task

    pattern = load_task(THERE_AND_BACK, 0.001).pattern
    told = [{"name": "edge", "position": [0.05, 0.0], "kind": "impactless"}]
    c = make()
    c.prepare(pattern, told, np.random.default_rng(0))
    belief = c.contact_map.contacts[0].belief
    radius = 2.0 * np.sqrt(belief.cov[0, 0] + belief.R[0, 0])
    assert 0.01 < radius < 0.05
    ts = np.arange(0.0, 4.0 + 0.0025, 0.005)  # the plan at path_dt
    dist = np.linalg.norm(pattern.sample_many(ts)["position"] - belief.mean, axis=1)
    inside = dist <= radius
    edges = np.flatnonzero(np.diff(inside.astype(int))) + 1  # first in, first out, twice
    expected = ts[edges].reshape(2, 2)
    crossings = c._impactless  # noqa: SLF001 - the plan's crossings
    assert [i for i, *_ in crossings] == [0, 0]
    np.testing.assert_allclose([(a, b) for _, a, b in crossings], expected, atol=1e-9)
    windows = c._windows  # noqa: SLF001
    assert [w.kind for w in windows] == ["impactless", "impactless"]
    np.testing.assert_allclose([w.t1 for w in windows], expected[:, 0], atol=1e-9)
    blind = make(use_kinds=["collision"])
    blind.prepare(pattern, told, np.random.default_rng(0))
    assert blind.contact_map.contacts == [] and blind._impactless == []  # noqa: SLF001


def test_a_stall_at_the_expected_contact_updates_its_belief_and_eq9(pattern) -> None:
    """A quasi-static contact (no impact for the detector) at the expected contact: hit 2,
    once; the map's contact 0 takes the measurement (no new contact) and its Eq. 9 model one
    (v_used, f_measured) pair, the stall's speed and peak force."""
    c = make()
    c.prepare(pattern, CONTACT, np.random.default_rng(0))
    c._windows = [TransitionWindow(0, "collision", 0.0, 0.0, 10.0)]  # noqa: SLF001
    contact = c.contact_map.contacts[0]
    cov0, n0 = np.trace(contact.belief.cov), len(contact.approach.velocities)
    moving = TargetSample(0.0, np.array([0.0, 0.09]), np.array([0.0, 0.03]), np.zeros(2),
                          np.zeros(1))  # fmt: skip
    hits = []
    for k in range(400):
        t = k * 0.001
        stalled = t >= 0.1
        force = (0.0, -6.0) if t >= 0.12 else (0.0, 0.0)
        o = obs_at(t, pos=(0.0, 0.08), vel=(0.0, 0.0 if stalled else 0.03), force=force)
        c._vel_hist.append((t, moving.velocity))  # noqa: SLF001
        c._force_hist.append((t, o.force.copy()))  # noqa: SLF001
        c._target_hist.append((t, moving.position))  # noqa: SLF001
        hits.append(c._contact_made(o, moving, None))  # noqa: SLF001
    assert sorted(set(hits)) == [0.0, 2.0] and hits.count(2.0) == 1
    assert len(c.contact_map.contacts) == 1 and contact.updated_this_trial
    assert np.trace(contact.belief.cov) < cov0  # the measurement narrowed the belief
    assert len(contact.approach.velocities) == n0 + 1


def test_a_mode_change_records_the_impactless_contact_and_closes_its_window(pattern) -> None:
    """Algorithm 1 deciding a new mode (``mode_event`` > 0, mode 0 → 1) is an impact-less
    contact event: the expected impact-less contact (its window open) takes the measurement
    where the trigger fired, and its window is released now and marked done. No decision
    (even as the contact is lost), a decision out of free space (contact made, recorded as a
    collision if at all) and one that keeps the mode record nothing."""
    told = [{"name": "edge", "position": [0.0, 0.08], "kind": "impactless"}]
    c = make()
    c.prepare(pattern, told, np.random.default_rng(0))
    window = TransitionWindow(0, "impactless", 0.0, 0.5, 10.0)
    c._windows = [window]  # noqa: SLF001
    contact = c.contact_map.contacts[0]
    cov0 = np.trace(contact.belief.cov)
    signals = {"mode_event": 0.0, "mode": 0.0}
    c.base.signal = signals.__getitem__  # Algorithm 1's outputs of this step
    c._trigger_pos = np.array([0.0, 0.081])  # noqa: SLF001 - where the trigger fired
    c._trigger_target = (np.array([0.0, 0.09]), np.array([0.0, 0.03]))  # noqa: SLF001
    c._impactless_event(obs_at(1.0))  # noqa: SLF001 - mode 0 learned, no decision
    signals.update(mode=-1.0)
    c._impactless_event(obs_at(1.2))  # noqa: SLF001 - contact lost: free space, no decision
    signals.update(mode_event=1.0, mode=0.0)
    c._impactless_event(obs_at(1.4))  # noqa: SLF001 - decided from free space: a contact
    c._impactless_event(obs_at(1.5))  # noqa: SLF001 - a decision that keeps mode 0
    assert not contact.updated_this_trial and not window.done
    signals.update(mode_event=2.0, mode=1.0)
    c._impactless_event(obs_at(2.0))  # noqa: SLF001 - mode 1: the surface changed
    assert contact.updated_this_trial and np.trace(contact.belief.cov) < cov0
    assert len(c.contact_map.contacts) == 1  # the expected contact, not a new one
    assert (window.release, window.done) == (2.0, True)


def test_crossings_are_in_the_order_the_plan_meets_them() -> None:
    """Two impact-less contacts listed far one first: the plan meets the near one (5 cm
    before the far one) first on the way out and last on the way back; the crossings and
    their windows follow the plan's order, not the list's."""
    from ccm.tasks.task import load_task

    pattern = load_task(THERE_AND_BACK, 0.001).pattern
    told = [{"name": "far", "position": [0.08, 0.0], "kind": "impactless"},
            {"name": "near", "position": [0.03, 0.0], "kind": "impactless"}]  # fmt: skip
    c = make(init_std=0.005)
    c.prepare(pattern, told, np.random.default_rng(0))
    crossings = c._impactless  # noqa: SLF001
    starts = [start for _, start, _ in crossings]
    assert starts == sorted(starts) and len(starts) >= 3
    assert crossings[0][0] == 1 and crossings[-1][0] == 1  # near: first out, last back
    assert [w.contact for w in c._windows] == [i for i, *_ in crossings]  # noqa: SLF001


def test_no_quasi_static_contact_without_an_open_collision_window(pattern) -> None:
    """The stall-and-rise of the first test, with only a closed (done) collision window and
    an impact-less one: no contact is declared."""
    c = make()
    c.prepare(pattern, CONTACT, np.random.default_rng(0))
    c._windows = [TransitionWindow(0, "collision", 0.0, 0.0, 10.0, done=True),  # noqa: SLF001
                  TransitionWindow(1, "impactless", 0.0, 0.0, 10.0)]  # fmt: skip
    moving = TargetSample(0.0, np.zeros(2), np.array([0.0, 0.03]), np.zeros(2), np.zeros(1))
    fired: list[float] = []
    for k in range(400):
        t = k * 0.001
        force = (0.0, -6.0) if t >= 0.12 else (0.0, 0.0)
        press_step(c, t, moving, obs_at(t, vel=(0.0, 0.0 if t >= 0.1 else 0.03), force=force),
                   fired)  # fmt: skip
    assert fired == []


def test_from_config_builds_the_base_from_the_rest_of_the_block() -> None:
    c = AnticipatoryAVIC.from_config({"k_free": 123.0, "k_max": 2500.0, "anticipation": {}})
    assert (c.base.k_free, c.base.k_max, c.k_collision) == (123.0, 2500.0, 123.0)


def test_a_contact_made_during_the_slow_down_keeps_the_change_under_way(pattern) -> None:
    """A collision detected halfway through the Eq. 11 slow-down: the re-plan keeps that
    rate change (it began before the contact; φ and its rate stay continuous), adds the
    speed-up back to the plan's speed where the slow-down ends, and keeps the windows of
    the impact-less crossing already passed, once."""
    told = [{"name": "edge", "position": [0.0, 0.13], "kind": "impactless"}, *CONTACT]
    c = make(init_std=0.005)
    retimed = c.prepare(pattern, told, np.random.default_rng(0))
    slow, _ = c._changes  # noqa: SLF001 - the slow-down to v_a and the speed-up after C
    t_s, t_e, rho = slow
    assert rho < 1.0 and t_e < 1.0  # the contact is made well inside the first second
    windows = [(w.contact, w.kind) for w in c._windows]  # noqa: SLF001
    assert sorted(windows) == [(0, "impactless"), (1, "collision")]
    t_hit = 0.5 * (t_s + t_e)
    phi, rate = retimed.warp.phi(t_hit), retimed.warp.rate(t_hit)
    c._release(1, t_hit)  # noqa: SLF001 - as a detected collision at the expected contact
    assert c._changes == [slow, (t_e, t_e + c.cfg.blend_s, 1.0)]  # noqa: SLF001
    assert retimed.warp.phi(t_hit) == pytest.approx(phi, abs=1e-12)
    assert retimed.warp.rate(t_hit) == pytest.approx(rate, abs=1e-12)
    assert retimed.warp.rate(t_e + c.cfg.blend_s + 1e-6) == pytest.approx(1.0)
    assert sorted((w.contact, w.kind) for w in c._windows) == sorted(windows)  # noqa: SLF001


def _pressed_command(c: AnticipatoryAVIC, kind: str, velocity: tuple[float, float]) -> float:
    """The command along a 10 N press down with one transition window of ``kind`` at α = 1
    and the target moving at ``velocity``."""
    press = np.array([0.0, -1.0])
    tgt = TargetSample(0.0, np.zeros(2), np.array(velocity, float), np.zeros(2), np.zeros(1),
                       press, 10.0)  # fmt: skip
    c.reset(2, 0.001)
    c._windows = [TransitionWindow(0, kind, 0.0, 0.0, 10.0)]  # noqa: SLF001 - alpha = 1
    return float(c.step(obs_at(0.0), tgt).force @ press)


def test_impactless_transition_keeps_the_force_loop_along_the_motion_too(pattern) -> None:
    """Eq. 8 around an impact-less transition (K* = K_max) keeps the hybrid law's force loop
    whatever the direction of motion: ~F_d (1 + k_fp) pressed along the press, also where the
    target moves along it (only the collision controller drops the loop there)."""
    c = make()
    c.prepare(pattern, CONTACT, np.random.default_rng(0))
    pressed = 10.0 * (1 + c.base.loop.force_kp)
    assert _pressed_command(c, "impactless", (0.05, 0.0)) == pytest.approx(pressed, rel=0.05)
    assert _pressed_command(c, "impactless", (0.0, -0.05)) == pytest.approx(pressed, rel=0.05)
    assert abs(_pressed_command(c, "collision", (0.0, -0.05))) < 10.0


def test_the_step_keeps_where_algorithm_1_triggered(pattern, monkeypatch) -> None:
    """The position (and target) of the step whose ``mode_trigger`` is 1 is where the next
    impact-less contact is measured; steps without a trigger leave it."""
    c = make()
    c.prepare(pattern, CONTACT, np.random.default_rng(0))
    trigger = [0.0]  # Algorithm 1's mode_trigger this step
    real = c.base.signal
    monkeypatch.setattr(
        c.base, "signal", lambda name: trigger[0] if name == "mode_trigger" else real(name)
    )
    for t, y, fired in ((0.0, 0.10, 0.0), (0.001, 0.09, 1.0), (0.002, 0.08, 0.0)):
        trigger[0] = fired
        tgt = TargetSample(t, np.array([0.0, y - 0.01]), np.array([0.0, -0.03]), np.zeros(2),
                           np.zeros(1))  # fmt: skip
        c.step(obs_at(t, pos=(0.0, y)), tgt)
    np.testing.assert_array_equal(c._trigger_pos, [0.0, 0.09])  # noqa: SLF001
    np.testing.assert_array_equal(c._trigger_target[0], [0.0, 0.08])  # noqa: SLF001
    np.testing.assert_array_equal(c._trigger_target[1], [0.0, -0.03])  # noqa: SLF001


def test_a_measurement_without_a_target_keeps_the_lead(pattern) -> None:
    """``_record`` keeps z; the lead (target − z across the motion) changes only when the
    target of the measurement is known."""
    c = make()
    c.prepare(pattern, CONTACT, np.random.default_rng(0))
    contact = c.contact_map.contacts[0]
    assert c.report()["contacts"][0]["measured"] == []
    c._record(0, np.array([0.0, 0.08]), (np.array([0.01, 0.07]), np.array([0.0, -0.03])))  # noqa: SLF001
    np.testing.assert_allclose(contact.lead, [0.01, 0.0], atol=1e-15)  # along the motion: out
    c._record(0, np.array([0.0, 0.079]), None)  # noqa: SLF001
    np.testing.assert_allclose(contact.lead, [0.01, 0.0], atol=1e-15)
    assert c.report()["contacts"][0]["measured"] == [[0.0, 0.08], [0.0, 0.079]]


def test_an_impactless_event_goes_to_the_contact_whose_window_is_open(pattern) -> None:
    """Two impact-less contacts with wide beliefs: a mode change measured nearer the first
    (1 cm from it, 3 cm from the second) while only the second's window is open
    updates the second, the one the robot was anticipating (§3.3), not the nearest."""
    told = [{"name": "a", "position": [0.0, 0.13], "kind": "impactless"},
            {"name": "b", "position": [0.0, 0.09], "kind": "impactless"}]  # fmt: skip
    c = make(init_std=0.03)
    c.prepare(pattern, told, np.random.default_rng(0))
    c._windows = [TransitionWindow(1, "impactless", 0.0, 0.5, 10.0)]  # noqa: SLF001
    signals = {"mode_event": 0.0, "mode": 0.0}
    c.base.signal = signals.__getitem__
    c._trigger_pos = np.array([0.0, 0.12])  # noqa: SLF001
    c._trigger_target = (np.array([0.0, 0.11]), np.array([0.0, -0.03]))  # noqa: SLF001
    c._impactless_event(obs_at(1.0))  # noqa: SLF001 - mode 0 known
    signals.update(mode_event=2.0, mode=1.0)
    c._impactless_event(obs_at(1.1))  # noqa: SLF001 - mode 1 decided
    a, b = c.contact_map.contacts
    assert b.updated_this_trial and not a.updated_this_trial


def test_report_lists_each_contact_before_and_after_the_trial(pattern) -> None:
    """``report()``'s per-contact record: the belief now and before the trial (std = the
    largest per-axis σ, region_m = sigma_scale × the largest semi-axis of P + R), the
    measurements z, and a made collision's Eq. 9 speed and force."""
    c = make()
    c.prepare(pattern, CONTACT, np.random.default_rng(0))
    contact = c.contact_map.contacts[0]
    mean0 = contact.belief.mean.tolist()
    std0 = float(np.sqrt(np.max(np.diag(contact.belief.cov))))
    (rec,) = c.report()["contacts"]
    assert rec == {
        "name": "mid", "kind": "collision", "source": "config", "mean": mean0, "std": std0,
        "region_m": pytest.approx(2.0 * np.sqrt(np.max(np.linalg.eigvalsh(
            contact.belief.cov + contact.belief.R)))),
        "prior_mean": mean0, "prior_std": std0, "approach_velocity": None,
        "impact_force": None, "measured": [],
    }  # fmt: skip
    c.contact_map.observe([0.0, 0.079], "collision", v_used=0.04, f_measured=11.0)
    c._record(0, np.array([0.0, 0.079]), None)  # noqa: SLF001
    (rec,) = c.report()["contacts"]
    assert (rec["prior_mean"], rec["prior_std"]) == (mean0, std0)
    assert rec["mean"] != mean0 and rec["std"] < std0
    assert (rec["approach_velocity"], rec["impact_force"]) == (0.04, 11.0)
    assert rec["measured"] == [[0.0, 0.079]]
    assert {"k_free", "k_max", "eps0", "r"} <= set(c.report())
