"""Target motion patterns: min-jerk segments, continuity, analytic derivatives, validation."""

from __future__ import annotations

import copy
import math
from typing import Any

import numpy as np
import pytest

from ccm.core.errors import ConfigError
from ccm.core.types import TargetSample
from ccm.tasks.motion_pattern import MotionPattern
from ccm.tasks.segments import ArcSegment, HoldSegment, LineSegment, min_jerk
from ccm.tasks.trajectory import build_pattern

EXACT = 1e-12
# Central differences with step H: truncation error ~ H² · (third derivative) and rounding
# error ~ eps · |x| / H. For these patterns (|x| <= 1.2 m, |jerk| < 10 m/s³, durations >= 0.5 s)
# both stay far below FD_TOL.
H = 1e-5
FD_TOL = 1e-7  # observed worst case ≈ 1e-8

SPEC_2D: list[dict[str, Any]] = [
    {"type": "line", "to": [0.3, 0.1], "duration": 1.0},
    {"type": "arc", "center": [0.3, 0.0], "sweep_deg": 270, "duration": 2.0},
    {"type": "hold", "duration": 0.5, "force": {"direction": [0, -2], "magnitude": 5.0}},
    {"type": "line", "to": [0.0, -0.1], "steps": 700, "name": "back"},
    {"type": "arc", "center": [0.0, 0.0], "sweep_deg": -400, "duration": 3.0},
]
SPEC_3D: list[dict[str, Any]] = [
    {"type": "line", "to": [0.4, 0.1, 0.3], "duration": 1.2},
    {
        "type": "arc",
        "center": [0.4, 0.1, 0.2],
        "sweep_deg": 180,
        "normal": [1, 1, 0],
        "duration": 2,
    },
    {"type": "hold", "duration": 0.5},
    {"type": "arc", "center": [0.5, 0.1, 0.1], "sweep_deg": 90, "duration": 1.5},
]
QUAT_DOWN = [1.0, 0.0, 0.0, 0.0]


def pattern_2d() -> MotionPattern:
    return build_pattern(SPEC_2D, [0.0, 0.0], control_dt=0.001)


def pattern_3d() -> MotionPattern:
    return build_pattern(SPEC_3D, [0.4, 0.1, 0.1], control_dt=0.001, orientation=QUAT_DOWN)


@pytest.fixture(params=["2d", "3d"])
def pattern(request: pytest.FixtureRequest) -> MotionPattern:
    return pattern_2d() if request.param == "2d" else pattern_3d()


# --- minimum-jerk timing -------------------------------------------------------------------


def kept(pattern, t: float) -> TargetSample:  # noqa: ANN001
    """A copy of ``pattern.sample(t)``: the pattern reuses its sample (issue #40)."""
    return copy.deepcopy(pattern.sample(t))


def test_min_jerk_boundary_values() -> None:
    for tau, s_expect in ((0.0, 0.0), (1.0, 1.0)):
        s, sd, sdd = min_jerk(tau, 2.0)
        assert s == s_expect
        assert sd == 0.0
        assert sdd == 0.0
    assert min_jerk(0.5, 1.0)[0] == pytest.approx(0.5, abs=EXACT)


def test_min_jerk_peak_speed_is_1_875_times_mean() -> None:
    seg = LineSegment([0.0, 0.0], [0.3, -0.4], duration=2.0)
    ts = np.linspace(0.0, 2.0, 20001)
    speed = np.linalg.norm(seg.sample_many(ts)[:, 1], axis=1)
    mean_speed = 0.5 / 2.0
    assert speed.max() == pytest.approx(1.875 * mean_speed, rel=1e-9)
    assert np.argmax(speed) == 10000  # at mid-segment


# --- segments ------------------------------------------------------------------------------


def test_line_endpoints_exact_and_at_rest() -> None:
    start, end = np.array([0.1, 0.2, 0.3]), np.array([-0.7, 0.05, 1.1])
    seg = LineSegment(start, end, duration=0.7)
    for t, p in ((0.0, start), (0.7, end)):
        pos, vel, acc = seg.sample(t)
        np.testing.assert_allclose(pos, p, rtol=0, atol=EXACT)
        np.testing.assert_array_equal(vel, 0.0)
        np.testing.assert_array_equal(acc, 0.0)
    np.testing.assert_array_equal(seg.start, start)
    np.testing.assert_array_equal(seg.end, end)
    # times outside the segment are clipped
    np.testing.assert_allclose(seg.sample(-1.0)[0], start, atol=EXACT)
    np.testing.assert_allclose(seg.sample(5.0)[0], end, atol=EXACT)


def test_arc_2d_counter_clockwise_and_constant_radius() -> None:
    seg = ArcSegment([0.3, 0.2], [0.2, 0.2], math.pi / 2, duration=1.0)
    np.testing.assert_allclose(seg.end, [0.2, 0.3], atol=EXACT)
    pos, vel, _ = seg.sample(0.5)
    np.testing.assert_allclose(
        pos, [0.2 + 0.1 / math.sqrt(2), 0.2 + 0.1 / math.sqrt(2)], atol=EXACT
    )
    assert vel[0] < 0 < vel[1]  # moving counter-clockwise
    pva = seg.sample_many(np.linspace(0, 1, 1001))
    radius = np.linalg.norm(pva[:, 0] - [0.2, 0.2], axis=1)
    np.testing.assert_allclose(radius, 0.1, rtol=0, atol=EXACT)
    # velocity stays tangent to the circle
    np.testing.assert_allclose(np.sum((pva[:, 0] - [0.2, 0.2]) * pva[:, 1], axis=1), 0, atol=EXACT)


def test_arc_clockwise_full_circle_returns_to_start() -> None:
    seg = ArcSegment([0.1, 0.0], [0.0, 0.0], -2 * math.pi, duration=6.0)
    np.testing.assert_allclose(seg.end, [0.1, 0.0], atol=EXACT)
    assert seg.sample(0.1)[1][1] < 0  # clockwise: starts moving towards -y


def test_arc_3d_right_hand_rule_and_constant_radius() -> None:
    seg = ArcSegment([0.0, 0.1, 0.0], [0.0, 0.0, 0.0], math.pi / 2, 1.0, normal=[2.0, 0, 0])
    np.testing.assert_allclose(seg.end, [0.0, 0.0, 0.1], atol=EXACT)  # y rotates towards z
    np.testing.assert_allclose(seg.normal, [1.0, 0.0, 0.0])
    pva = seg.sample_many(np.linspace(0, 1, 501))
    np.testing.assert_allclose(np.linalg.norm(pva[:, 0], axis=1), 0.1, rtol=0, atol=EXACT)
    np.testing.assert_allclose(pva[:, 0, 0], 0.0, atol=EXACT)  # stays in the plane x = 0
    # default normal in 3D is +z
    seg_z = ArcSegment([0.1, 0.0, 0.5], [0.0, 0.0, 0.5], math.pi / 2, 1.0)
    np.testing.assert_allclose(seg_z.end, [0.0, 0.1, 0.5], atol=EXACT)


def test_arc_centripetal_acceleration_at_peak_speed() -> None:
    seg = ArcSegment([0.1, 0.0], [0.0, 0.0], 2 * math.pi, duration=6.0)
    pos, vel, acc = seg.sample(3.0)  # mid-segment: tangential acceleration is zero
    speed = float(np.linalg.norm(vel))
    assert speed == pytest.approx(1.875 * 2 * math.pi * 0.1 / 6.0, rel=1e-12)
    np.testing.assert_allclose(acc, -(speed**2 / 0.1) * pos / 0.1, atol=EXACT)


def test_hold_segment() -> None:
    seg = HoldSegment([0.1, 0.2], 0.5, force_dir=[0.0, -3.0], force_mag=2.0)
    pos, vel, acc = seg.sample(0.25)
    np.testing.assert_array_equal(pos, [0.1, 0.2])
    np.testing.assert_array_equal(vel, 0.0)
    np.testing.assert_array_equal(acc, 0.0)
    assert seg.force_dir is not None
    np.testing.assert_array_equal(seg.force_dir, [0.0, -1.0])


# --- patterns ------------------------------------------------------------------------------


def test_pattern_endpoints_exact(pattern: MotionPattern) -> None:
    first = pattern.sample(0.0)
    np.testing.assert_allclose(first.position, pattern.start, rtol=0, atol=EXACT)
    end = pattern.sample(pattern.duration)
    np.testing.assert_allclose(end.position, pattern.end, rtol=0, atol=EXACT)
    for i, seg in enumerate(pattern.segments):
        t0 = pattern.start_times[i]
        np.testing.assert_allclose(seg.sample(0.0)[0], seg.start, rtol=0, atol=EXACT)
        np.testing.assert_allclose(seg.sample(seg.duration)[0], seg.end, rtol=0, atol=EXACT)
        np.testing.assert_allclose(pattern.sample(t0).position, seg.start, rtol=0, atol=EXACT)
        if i > 0:
            np.testing.assert_allclose(seg.start, pattern.segments[i - 1].end, rtol=0, atol=EXACT)


def test_pattern_continuity_across_boundaries(pattern: MotionPattern) -> None:
    eps = 1e-9
    for i in range(1, len(pattern)):
        tb = pattern.start_times[i]
        before, after = kept(pattern, tb - eps), kept(pattern, tb + eps)
        assert (before.segment, after.segment) == (i - 1, i)
        np.testing.assert_allclose(after.position, before.position, rtol=0, atol=1e-12)
        np.testing.assert_allclose(after.velocity, before.velocity, rtol=0, atol=1e-12)
        # acceleration may differ by at most 2·eps·|jerk| (jerk is finite, < 100 m/s³ here)
        np.testing.assert_allclose(after.acceleration, before.acceleration, rtol=0, atol=2e-7)
        # exactly at the boundary both segments agree: at rest, same point
        prev = pattern.segments[i - 1].sample(pattern.segments[i - 1].duration)
        nxt = pattern.segments[i].sample(0.0)
        for a, b in zip(prev, nxt, strict=True):
            np.testing.assert_allclose(a, b, rtol=0, atol=EXACT)
        np.testing.assert_array_equal(nxt[1], 0.0)
        np.testing.assert_array_equal(nxt[2], 0.0)


def test_analytic_derivatives_match_central_differences(pattern: MotionPattern) -> None:
    ts = np.linspace(H, pattern.duration - H, 2003)
    for t in ts:
        lo, mid, hi = kept(pattern, t - H), kept(pattern, t), kept(pattern, t + H)
        if not lo.segment == mid.segment == hi.segment:
            continue  # the FD stencil straddles a boundary; continuity is tested separately
        fd_vel = (hi.position - lo.position) / (2 * H)
        fd_acc = (hi.velocity - lo.velocity) / (2 * H)
        np.testing.assert_allclose(mid.velocity, fd_vel, rtol=0, atol=FD_TOL)
        np.testing.assert_allclose(mid.acceleration, fd_acc, rtol=0, atol=FD_TOL)


def test_sample_many_matches_sample(pattern: MotionPattern) -> None:
    ts = np.concatenate([[-1.0], np.linspace(0, pattern.duration, 777), [pattern.duration + 2]])
    many = pattern.sample_many(ts)
    for j, t in enumerate(ts):
        s = pattern.sample(float(t))
        np.testing.assert_allclose(many["position"][j], s.position, rtol=0, atol=EXACT)
        np.testing.assert_allclose(many["velocity"][j], s.velocity, rtol=0, atol=EXACT)
        np.testing.assert_allclose(many["acceleration"][j], s.acceleration, rtol=0, atol=EXACT)
        assert many["segment"][j] == s.segment
        assert many["done"][j] == s.done
        assert many["force_active"][j] == (s.force_dir is not None)
        assert many["force_mag"][j] == s.force_mag


def test_sample_before_start_and_after_end() -> None:
    pat = pattern_2d()
    early = kept(pat, -0.5)
    np.testing.assert_allclose(early.position, pat.start, atol=EXACT)
    assert early.segment == 0 and not early.done
    late = pat.sample(pat.duration + 1.0)
    assert late.done and late.segment == len(pat) - 1
    np.testing.assert_array_equal(late.position, pat.end)
    np.testing.assert_array_equal(late.velocity, 0.0)
    np.testing.assert_array_equal(late.acceleration, 0.0)
    assert late.t == pat.duration + 1.0
    with pytest.raises(ValueError, match="read-only"):  # one sample, updated in place (#40)
        late.position[0] = 99.0
    assert pat.sample(0.0) is late and late.t == 0.0 and not late.done
    np.testing.assert_array_equal(late.orientation, [0.0])
    assert not pat.sample(pat.duration - 1e-6).done
    with pytest.raises(ValueError, match="number"):
        pat.sample(float("nan"))


def test_force_targets_per_segment() -> None:
    pat = pattern_2d()
    hold_t = pat.start_times[2] + 0.25
    s = pat.sample(hold_t)
    assert s.segment == 2
    assert s.force_dir is not None
    np.testing.assert_array_equal(s.force_dir, [0.0, -1.0])  # normalised from [0, -2]
    assert s.force_mag == 5.0
    assert pat.sample(0.5).force_dir is None
    assert pat.segments[3].name == "back"


def test_steps_equals_duration() -> None:
    by_steps = build_pattern(
        [{"type": "arc", "center": [0, 0], "sweep_deg": 360, "steps": 600}], [0.1, 0.0], 0.01
    )
    by_time = build_pattern(
        [{"type": "arc", "center": [0, 0], "sweep_deg": 360, "duration": 6.0}], [0.1, 0.0], 0.01
    )
    assert by_steps.duration == pytest.approx(6.0, abs=EXACT)
    for t in np.linspace(0, 6, 37):
        np.testing.assert_allclose(
            by_steps.sample(t).position, by_time.sample(t).position, rtol=0, atol=EXACT
        )


def test_3d_orientation_is_normalised_quaternion() -> None:
    pat = build_pattern(SPEC_3D, [0.4, 0.1, 0.1], 0.001, orientation=[0, 0, 0, 2.0])
    np.testing.assert_array_equal(pat.sample(0.1).orientation, [0, 0, 0, 1.0])


def test_sample_is_cheap() -> None:
    """Budget check only (generous, so slow CI machines pass): well under 100 µs per call."""
    import time

    pat = pattern_2d()
    ts = np.linspace(0, pat.duration, 2000).tolist()
    t0 = time.perf_counter()
    for t in ts:
        pat.sample(t)
    per_call = (time.perf_counter() - t0) / len(ts)
    assert per_call < 100e-6


# --- Python API validation -----------------------------------------------------------------


def test_pattern_rejects_gaps_and_mixed_dims() -> None:
    a = LineSegment([0, 0], [1, 0], 1.0)
    with pytest.raises(ConfigError, match=r"pattern\[1\]"):
        MotionPattern([a, LineSegment([1, 0.1], [2, 0], 1.0)], [0.0])
    with pytest.raises(ConfigError, match=r"pattern\[1\]"):
        MotionPattern([a, HoldSegment([1, 0, 0], 1.0)], [0.0])
    with pytest.raises(ConfigError, match="pattern"):
        MotionPattern([], [0.0])
    with pytest.raises(ConfigError, match="force.direction"):
        LineSegment([0, 0], [1, 0], 1.0, force_mag=3.0)


# --- YAML validation -----------------------------------------------------------------------

LINE = {"type": "line", "to": [0.1, 0.0], "duration": 1.0}


def _with(i: int, **changes: Any) -> list[dict[str, Any]]:
    spec = [dict(LINE), dict(LINE, to=[0.2, 0.0])]
    spec[i].update(changes)
    for k, v in list(spec[i].items()):
        if v is _DROP:
            del spec[i][k]
    return spec


_DROP = object()


@pytest.mark.parametrize(
    ("spec", "key", "fragment"),
    [
        ([], "task.pattern", "at least one segment"),
        ("line", "task.pattern", "list"),
        ([3], "task.pattern[0]", "mapping"),
        (_with(1, type="spiral"), "task.pattern[1].type", "allowed: line, arc, hold"),
        (_with(0, type=_DROP), "task.pattern[0].type", "missing"),
        (_with(1, speed=2), "task.pattern[1].speed", "unknown key; allowed: type, duration"),
        (_with(0, center=[0, 0]), "task.pattern[0].center", "unknown key"),
        (_with(0, to=[0.1, 0.0, 0.0]), "task.pattern[0].to", "length 2"),
        (_with(0, to=_DROP), "task.pattern[0].to", "missing"),
        (_with(1, duration=-1), "task.pattern[1].duration", "must be > 0, got -1"),
        (_with(1, duration=0.0), "task.pattern[1].duration", "must be > 0"),
        (_with(0, duration=float("nan")), "task.pattern[0].duration", "finite"),
        (_with(0, duration="abc"), "task.pattern[0].duration", "number"),
        (_with(0, duration=_DROP, steps=0), "task.pattern[0].steps", "integer >= 1"),
        (_with(0, duration=_DROP, steps=-5), "task.pattern[0].steps", "integer >= 1"),
        (_with(0, duration=_DROP, steps=2.5), "task.pattern[0].steps", "integer >= 1"),
        (_with(0, duration=_DROP, steps=float("nan")), "task.pattern[0].steps", "integer"),
        (_with(1, steps=10), "task.pattern[1]", "exactly one of 'duration'"),
        (_with(1, duration=_DROP), "task.pattern[1]", "exactly one of 'duration'"),
        (
            _with(0, force={"direction": [0, -1], "magnitude": -2.0}),
            "task.pattern[0].force.magnitude",
            ">= 0",
        ),
        (
            _with(0, force={"direction": [0, 0], "magnitude": 2.0}),
            "task.pattern[0].force.direction",
            "non-zero",
        ),
        (
            _with(0, force={"direction": [0, 0, 1], "magnitude": 2.0}),
            "task.pattern[0].force.direction",
            "length 2",
        ),
        (_with(0, force={"direction": [0, 1]}), "task.pattern[0].force.magnitude", "missing"),
        (
            _with(0, force={"direction": [0, 1], "magnitude": 1, "gain": 2}),
            "task.pattern[0].force.gain",
            "unknown key; allowed: direction, magnitude",
        ),
        (_with(0, force=5.0), "task.pattern[0].force", "mapping"),
        (
            [{"type": "arc", "center": [0.0, 0.0], "sweep_deg": 90, "duration": 1}],
            "task.pattern[0].center",
            "zero-radius",
        ),
        (
            [{"type": "arc", "center": [0.1, 0.0, 0.0], "sweep_deg": 90, "duration": 1}],
            "task.pattern[0].center",
            "length 2",
        ),
        (
            [{"type": "arc", "center": [0.1, 0.0], "sweep_deg": 0, "duration": 1}],
            "task.pattern[0].sweep_deg",
            "non-zero",
        ),
        (
            [
                {
                    "type": "arc",
                    "center": [0.1, 0.0],
                    "sweep_deg": 90,
                    "duration": 1,
                    "normal": [0, 0, 1],
                }
            ],
            "task.pattern[0].normal",
            "3D",
        ),
        (
            [{"type": "arc", "center": [0.1, 0.0], "duration": 1}],
            "task.pattern[0].sweep_deg",
            "missing",
        ),
    ],
)
def test_build_pattern_errors_name_the_key(spec: Any, key: str, fragment: str) -> None:
    with pytest.raises(ConfigError) as info:
        build_pattern(spec, [0.0, 0.0], control_dt=0.001)
    msg = str(info.value)
    assert msg.startswith(f"{key}: "), msg
    assert fragment in msg, msg
    assert "\n" not in msg


def test_build_pattern_3d_errors() -> None:
    arc = {"type": "arc", "center": [0.0, 0.0, 0.0], "sweep_deg": 90, "duration": 1}
    with pytest.raises(ConfigError, match=r"^task\.orientation: required"):
        build_pattern([arc], [0.1, 0, 0], 0.001)
    with pytest.raises(ConfigError, match=r"^task\.pattern\[0\]\.center: .*perpendicular"):
        build_pattern([arc], [0.1, 0, 0.05], 0.001, orientation=QUAT_DOWN)
    with pytest.raises(ConfigError, match=r"^task\.pattern\[0\]\.normal: .*non-zero"):
        build_pattern([dict(arc, normal=[0, 0, 0])], [0.1, 0, 0], 0.001, orientation=QUAT_DOWN)
    with pytest.raises(ConfigError, match=r"^task\.orientation: .*non-zero"):
        build_pattern([arc], [0.1, 0, 0], 0.001, orientation=[0, 0, 0, 0])
    with pytest.raises(ConfigError, match=r"^task\.start: "):
        build_pattern([arc], [0.1], 0.001)
    with pytest.raises(ConfigError, match=r"^control_dt: must be > 0"):
        build_pattern([LINE], [0.0, 0.0], 0.0)


def test_line_arriving_at_speed() -> None:
    """``end_speed``: starts at rest, reaches ``to`` exactly, moving at end_speed along the
    line with zero acceleration, and never moves backwards (w <= 2)."""
    seg = LineSegment([0.0, 0.0, 0.15], [0.0, 0.0, 0.095], 1.0, end_speed=0.08)
    p0, v0, a0 = seg.sample(0.0)
    p1, v1, a1 = seg.sample(1.0)
    np.testing.assert_array_equal(p1, [0.0, 0.0, 0.095])
    np.testing.assert_allclose(v0, 0.0, atol=1e-15)
    np.testing.assert_allclose(a0, 0.0, atol=1e-15)
    np.testing.assert_allclose(v1, [0.0, 0.0, -0.08], atol=1e-12)
    np.testing.assert_allclose(a1, 0.0, atol=1e-12)
    ts = np.linspace(0.0, 1.0, 201)
    speed = np.array([np.linalg.norm(seg.sample(t)[1]) for t in ts])
    direction = np.array([seg.sample(t)[1][2] for t in ts])
    assert np.all(direction <= 1e-15), "always moving towards -z"
    assert speed.max() < 0.12
    # derivatives are consistent (central differences)
    h = 1e-6
    for t in (0.2, 0.5, 0.9):
        dp = (seg.sample(t + h)[0] - seg.sample(t - h)[0]) / (2 * h)
        np.testing.assert_allclose(dp, seg.sample(t)[1], atol=1e-7)
    with pytest.raises(ConfigError, match="end_speed"):
        LineSegment([0.0, 0.0], [0.1, 0.0], 1.0, end_speed=0.5, key="task.pattern[0]")


@pytest.mark.parametrize(
    "seg",
    [
        ArcSegment([0.3, 0.2], [0.2, 0.2], math.pi / 2, duration=1.0),
        ArcSegment([0.1, 0.0], [0.0, 0.0], -2 * math.pi, duration=6.0),
        ArcSegment([0.0, 0.1, 0.0], [0.0, 0.0, 0.0], math.pi / 2, 1.0, normal=[2.0, 0, 0]),
        ArcSegment([0.1, 0.02, 0.5], [0.0, 0.0, 0.5], -1.3, 2.0, normal=[0.2, -1.0, 0.3]),
    ],
)
def test_arc_kernel_is_bit_identical_to_the_readable_product(seg: ArcSegment) -> None:
    """The compiled arc sample (the control loop's path) equals C(t) @ B: bit for bit with an
    FMA-accumulating BLAS (OpenBLAS on x86-64, checked end to end by the summary pins),
    within one ulp otherwise."""
    for t in np.linspace(0.0, seg.duration, 997):
        readable = np.array(seg._coeffs(float(t))) @ seg._basis
        np.testing.assert_array_max_ulp(seg._eval(float(t)), readable, maxulp=1)


@pytest.mark.parametrize(
    "seg",
    [
        LineSegment([0.3, 0.2], [-0.2, 0.45], duration=1.0),
        LineSegment([0.0, 0.1], [0.8, 0.02], duration=6.0, force_dir=[0.0, -1.0], force_mag=10.0),
        LineSegment([0.45, -0.1, 0.3], [0.6, 0.2, 0.031], duration=2.5),
        LineSegment([0.4, 0.0, 0.2], [0.4, 0.0, 0.1], duration=1.0, end_speed=0.1),
    ],
)
def test_line_kernel_is_bit_identical_to_the_readable_product(seg: LineSegment) -> None:
    """The compiled min-jerk line sample equals C(t) @ B (as the arc kernel; a line that
    arrives at speed keeps the readable product)."""
    for t in np.linspace(0.0, seg.duration, 997):
        readable = np.array(seg._coeffs(float(t))) @ seg._basis
        np.testing.assert_array_max_ulp(seg._eval(float(t)), readable, maxulp=1)
