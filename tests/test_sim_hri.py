"""Seed B's physical-HRI scene elements in the pymunk backend: compliant walls, human, vibration.

Every assertion states its tolerance. Scenes are top-down (gravity 0) unless said otherwise;
the EE is the default 1 kg, 0.05 m box.
"""

from __future__ import annotations

import copy
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from omegaconf import OmegaConf

from ccm.core.errors import ConfigError
from ccm.core.types import Command, Observation, StepInfo
from ccm.sim.pymunk.backend import Pymunk2D
from ccm.sim.pymunk.hri import HumanSpec
from ccm.sim.pymunk.hri_forces import HumanHand
from ccm.sim.pymunk.scene import SceneSpec

ZERO_T = np.zeros(1)
DT = 0.001
BASE_EXTRA = {"viscosity_Nspm", "surface_friction", "contact"}
TASK_DIR = Path(__file__).resolve().parents[1] / "configs" / "task"

# a wall whose surface is the line x = 0.3, occupying x > 0.3 (normal points to -x)
WALL_X = 0.3


def make_sim(scene: dict[str, Any], start: list[float], **sim: Any) -> Pymunk2D:
    return Pymunk2D.from_config(sim, scene, start)


def run(
    sim: Pymunk2D, force: Any, n: int, seed: int = 0
) -> tuple[tuple[Observation, StepInfo], list[tuple[Observation, StepInfo]]]:
    """Reset, then apply ``force`` (an array, or ``obs -> array``) for ``n`` control steps."""
    first = copy.deepcopy(sim.reset(seed))  # the simulator reuses its objects (issue #40)
    obs = first[0]
    out = []
    for _ in range(n):
        f = force(obs) if callable(force) else force
        obs, info = sim.step(Command(np.asarray(f, dtype=float), ZERO_T))
        out.append(copy.deepcopy((obs, info)))
    return first, out


def wall(k: float, c: float = 0.0, jitter: float = 0.0) -> dict[str, Any]:
    return {
        "point": [WALL_X, 0.0],
        "normal": [-1.0, 0.0],
        "stiffness": k,
        "damping": c,
        "position_jitter_m": jitter,
    }


# --------------------------------------------------------------------------- compliant walls


@pytest.mark.parametrize("k", [15e3, 45e3, 126e3])  # seed B §5.3: 15, 45, 126 N/mm
def test_wall_settles_at_f_over_k(k: float) -> None:
    push = 10.0
    c = 2.0 * 0.7 * math.sqrt(k * 1.0)  # damping ratio 0.7 for the 1 kg EE
    sim = make_sim({"compliant_walls": [wall(k, c)]}, [WALL_X - 0.02, 0.0])
    _, steps = run(sim, [push, 0.0], 1500)
    obs, info = steps[-1]
    depth = obs.position[0] - WALL_X
    assert depth == pytest.approx(push / k, rel=0.02), "penetration F/k (2 %)"
    assert abs(obs.lin_vel[0]) < 1e-6, "at rest (1e-6 m/s)"
    assert obs.force == pytest.approx([-push, 0.0], rel=1e-4, abs=1e-9), "reads -F (1e-4)"
    assert np.array_equal(info.contact_force, info.true_force), "all of it is contact"
    assert info.n_contacts == 1 and info.extra["contact"] == 1.0
    assert info.extra["surface_friction"] == 0.0, "a compliant wall is frictionless"
    assert info.extra["wall_offset_m"] == 0.0, "no jitter, no offset"
    assert obs.torque[0] == 0.0, "acts on the centre: no torque"
    # contact is judged at the start of each physics step: allow a step of lag at the surface
    free = [i for o, i in steps if o.position[0] < WALL_X - 1e-3]
    assert free and all(i.n_contacts == 0 and i.extra["contact"] == 0.0 for i in free)


def test_wall_never_pulls() -> None:
    k, c = 45e3, 400.0
    sim = make_sim({"compliant_walls": [wall(k, c)]}, [WALL_X - 0.01, 0.0])
    # press for 0.5 s, then yank out at 50 N
    _, steps = run(sim, lambda o: [20.0, 0.0] if o.t < 0.5 else [-50.0, 0.0], 800)
    fx = np.array([o.force[0] for o, _ in steps])
    touching = np.array([i.n_contacts for _, i in steps]) == 1
    assert np.all(fx <= 0.0), "the wall only pushes along its normal (-x)"
    leaving = touching & (np.array([o.t for o, _ in steps]) > 0.5)
    assert np.any(leaving & (fx == 0.0)), "damping would pull while leaving: clipped to 0"
    assert steps[-1][0].position[0] < WALL_X and steps[-1][1].n_contacts == 0


def test_wall_with_static_contact_and_start_inside() -> None:
    # EE starts 1 mm inside a 15 N/mm wall: the reset observation already reads it
    sim = make_sim({"compliant_walls": [wall(15e3)]}, [WALL_X + 0.001, 0.0])
    obs, info = sim.reset(0)
    assert obs.force == pytest.approx([-15.0, 0.0]), "k d at reset"
    assert info.n_contacts == 1 and info.extra["contact"] == 1.0
    # a floor plus a wall: both count, the floor's friction is reported
    scene = {
        "gravity": 9.81,
        "surfaces": [{"a": [-1.0, 0.0], "b": [1.0, 0.0], "friction": 0.3}],
        "compliant_walls": [wall(15e3, 300.0)],
    }
    sim = make_sim(scene, [WALL_X - 0.01, 0.027], gravity_compensation=False)
    _, steps = run(sim, [5.0, 0.0], 1500)
    obs, info = steps[-1]
    assert info.n_contacts == 2 + 1, "two floor points and the wall"
    assert info.extra["surface_friction"] == pytest.approx(0.3)
    assert obs.force == pytest.approx([-5.0, 9.81], rel=0.01), "wall -F, floor +m g (1 %)"


def test_wall_jitter_range_and_seeding() -> None:
    j = 0.01  # seed B §6.1: ±1 cm
    sim = make_sim({"compliant_walls": [wall(45e3, 400.0, jitter=j)]}, [0.2, 0.0])
    offsets = [sim.reset(s)[1].extra["wall_offset_m"] for s in range(60)]
    assert all(-j <= o <= j for o in offsets), "offsets in [-j, j]"
    assert len(set(offsets)) == 60, "not all equal"
    assert max(offsets) > 0.5 * j and min(offsets) < -0.5 * j, "spread over the interval"
    assert offsets == [sim.reset(s)[1].extra["wall_offset_m"] for s in range(60)], "per seed"
    # the physics uses the shifted wall: surface at x = 0.3 - offset (normal -x)
    _, steps = run(sim, [10.0, 0.0], 1500, seed=5)
    obs, info = steps[-1]
    assert info.extra["wall_offset_m"] == offsets[5], "constant through the episode"
    expected = WALL_X - offsets[5] + 10.0 / 45e3
    assert obs.position[0] == pytest.approx(expected, abs=2e-6), "shifted wall (2 um)"
    no_jitter = make_sim({"compliant_walls": [wall(45e3)]}, [0.2, 0.0])
    assert all(no_jitter.reset(s)[1].extra["wall_offset_m"] == 0.0 for s in range(5))


def test_wall_normal_is_normalised() -> None:
    scene = SceneSpec.from_mapping(
        {"compliant_walls": [{"point": [0, 0], "normal": [0.0, 3.0], "stiffness": 1.0}]}
    )
    assert scene.compliant_walls[0].normal == (0.0, 1.0)


# --------------------------------------------------------------------------- human


def human(**kw: Any) -> dict[str, Any]:
    base = {"goals": [[0.1, 0.05]], "stiffness": 200.0, "damping": 28.0, "max_force": 5.0}
    return {**base, **kw}


def test_human_moves_ee_to_goal_with_bounded_force() -> None:
    sim = make_sim({"human": human()}, [0.0, 0.0])
    first, steps = run(sim, [0.0, 0.0], 3000)
    assert first[1].extra["human_fx_N"] == 0.0, "no hand force applied before the first step"
    obs, info = steps[-1]
    assert obs.position == pytest.approx([0.1, 0.05], abs=1e-4), "reaches the goal (0.1 mm)"
    hand = np.array([[i.extra["human_fx_N"], i.extra["human_fy_N"]] for _, i in steps])
    norms = np.linalg.norm(hand, axis=1)
    assert np.all(norms <= 5.0 + 1e-9), "|F| <= max_force"
    assert np.sum(np.isclose(norms, 5.0, rtol=1e-12)) > 10, "saturated while far away"
    forces = np.array([o.force for o, _ in steps])
    assert np.allclose(forces, hand, atol=1e-12), "the F/T sensor measures the hand force"
    assert all(i.n_contacts == 0 and not i.contact_force.any() for _, i in steps)
    assert info.extra["human_goal"] == 0.0


def test_human_under_compensated_gravity_and_decimation() -> None:
    # gravity on, compensated by the robot: the hand still brings the EE to the goal
    scene = {"gravity": 9.81, "human": human(goals=[[0.0, 0.1]])}
    sim = make_sim(scene, [0.0, 0.0], control_decimation=5)
    _, steps = run(sim, [0.0, 0.0], 600)
    obs, info = steps[-1]
    assert obs.position == pytest.approx([0.0, 0.1], abs=1e-4), "goal reached (0.1 mm)"
    for o, i in steps:  # extras are means over the control period, like the wrench
        assert o.force == pytest.approx([i.extra["human_fx_N"], i.extra["human_fy_N"]], abs=1e-12)


def test_human_random_goal_per_seed() -> None:
    goals = [[0.1, 0.0], [0.0, 0.1], [-0.1, 0.0], [0.0, -0.1]]
    sim = make_sim({"human": human(goals=goals, goal_index=-1)}, [0.0, 0.0])
    drawn = [sim.reset(s)[1].extra["human_goal"] for s in range(20)]
    assert len(set(drawn)) > 1, "different seeds draw different goals"
    assert set(drawn) <= {0.0, 1.0, 2.0, 3.0}
    assert drawn == [sim.reset(s)[1].extra["human_goal"] for s in range(20)], "per seed"
    for s in range(20):  # the truth names the drawn goal's position too (metrics, issue #18)
        extra = sim.reset(s)[1].extra
        assert [extra["human_goal_x_m"], extra["human_goal_y_m"]] == goals[int(extra["human_goal"])]
    seed = drawn.index(2.0)
    _, steps = run(sim, [0.0, 0.0], 3000, seed=seed)
    assert steps[-1][0].position == pytest.approx([-0.1, 0.0], abs=1e-4), "the drawn goal"
    fixed = make_sim({"human": human(goals=goals, goal_index=3)}, [0.0, 0.0])
    assert {fixed.reset(s)[1].extra["human_goal"] for s in range(5)} == {3.0}


def test_human_active_after() -> None:
    sim = make_sim({"human": human(active_after_s=0.1)}, [0.0, 0.0])
    _, steps = run(sim, [0.0, 0.0], 200)
    for o, i in steps:
        if o.t < 0.1 - 1e-9:  # the step ending at t started at t - dt < 0.1
            assert i.extra["human_fx_N"] == 0.0 and np.array_equal(o.position, [0.0, 0.0])
        elif o.t > 0.1 + 1e-9:
            assert i.extra["human_fx_N"] > 0.0


def test_human_noise_is_low_pass() -> None:
    sigma, fc = 2.0, 5.0
    spec = HumanSpec(goals=((0.0, 0.0),), stiffness=1.0, max_force=1e6, noise_std=sigma,
                     noise_cutoff_hz=fc)  # fmt: skip
    hand = HumanHand(spec, DT)
    hand.reset(np.random.default_rng(0))
    n = np.array([hand.force(0.0, 0.0, 0.0, 0.0, k * DT) for k in range(40000)])
    assert np.allclose(n.std(axis=0), sigma, rtol=0.15), f"stationary std {n.std(axis=0)} (15 %)"
    diff = np.diff(n, axis=0).std(axis=0)
    # first-order low-pass: diff std = sigma sqrt(2 (1 - a)) ~ 0.25 sigma; white: 1.41 sigma
    assert np.all(diff < 0.35 * sigma), f"sample-to-sample std {diff} << {sigma}"
    a = math.exp(-2 * math.pi * fc * DT)
    lag1 = [np.corrcoef(n[:-1, i], n[1:, i])[0, 1] for i in range(2)]
    assert np.allclose(lag1, a, atol=0.01), f"lag-1 correlation {lag1} vs {a:.3f}"


def test_human_noise_in_the_sim_is_seeded() -> None:
    sim = make_sim({"human": human(noise_std=1.0)}, [0.0, 0.0])

    def traj(seed: int) -> np.ndarray:
        _, steps = run(sim, [0.0, 0.0], 300, seed=seed)
        return np.array([np.r_[o.position, o.force] for o, _ in steps])

    a = traj(4)
    assert np.array_equal(a, traj(4)), "same seed, identical trajectory"
    assert not np.allclose(a, traj(5)), "different seeds differ"


# --------------------------------------------------------------------------- vibration


def test_vibration_spectrum_peaks_at_frequency() -> None:
    f0, amp = 40.0, [2.0, 1.0]
    sim = make_sim({"vibration": {"amplitude": amp, "frequency_hz": f0}}, [0.0, 0.0])
    _, steps = run(sim, [0.0, 0.0], 2000)
    fx = np.array([o.force[0] for o, _ in steps])
    fy = np.array([o.force[1] for o, _ in steps])
    freqs = np.fft.rfftfreq(fx.size, DT)
    for sig, a in ((fx, amp[0]), (fy, amp[1])):
        spec = np.abs(np.fft.rfft(sig)) * 2.0 / sig.size
        assert freqs[np.argmax(spec)] == pytest.approx(f0), "peak at frequency_hz"
        assert spec.max() == pytest.approx(a, rel=0.02), "peak height = amplitude (2 %)"
    assert [i.extra["disturbance_fx_N"] for _, i in steps] == pytest.approx(fx.tolist())
    assert all(i.n_contacts == 0 and not i.contact_force.any() for _, i in steps)


def test_vibration_phases_and_noise_are_seeded() -> None:
    cfg = {"amplitude": [1.0, 1.0], "frequency_hz": 25.0, "noise_std": 0.5}
    sim = make_sim({"vibration": cfg}, [0.0, 0.0])

    def forces(seed: int) -> np.ndarray:
        return np.array([o.force for o, _ in run(sim, [0.0, 0.0], 200, seed=seed)[1]])

    a = forces(1)
    assert np.array_equal(a, forces(1)) and not np.allclose(a, forces(2))
    assert not np.allclose(a[:, 0], a[:, 1]), "independent phases per axis"


def test_vibration_only_inside_region() -> None:
    region = {"center": [0.5, 0.0], "half_extents": [0.1, 0.1]}
    vib = {"vibration": {"amplitude": [3.0, 3.0], "frequency_hz": 50.0, "region": region}}
    _, outside = run(make_sim(vib, [0.0, 0.0]), [0.0, 0.0], 300)
    assert all(not o.force.any() and i.extra["disturbance_fx_N"] == 0.0 for o, i in outside)
    _, inside = run(make_sim(vib, [0.5, 0.0]), [0.0, 0.0], 300)
    assert np.abs([o.force for o, _ in inside]).max() > 2.5, "acts inside (amplitude 3 N)"


def test_vibration_above_nyquist_is_rejected() -> None:
    with pytest.raises(ConfigError) as err:
        make_sim({"vibration": {"amplitude": [1, 1], "frequency_hz": 500.0}}, [0.0, 0.0])
    assert err.value.key == "task.scene.vibration.frequency_hz"


# --------------------------------------------------------------------------- all together


def full_scene() -> dict[str, Any]:
    return {
        "compliant_walls": [wall(45e3, 300.0, jitter=0.01)],
        "human": human(goals=[[0.4, 0.0], [0.2, 0.1]], goal_index=-1, noise_std=0.5),
        "vibration": {"amplitude": [0.5, 0.5], "frequency_hz": 80.0, "noise_std": 0.1},
    }


def test_same_seed_same_trajectory_and_extra_keys() -> None:
    sim = make_sim(full_scene(), [0.25, 0.0], sensor={"force_noise_std": 0.2})

    def traj(seed: int) -> tuple[np.ndarray, list[set[str]]]:
        first, steps = run(sim, lambda o: -20.0 * o.lin_vel, 1000, seed=seed)
        rows = [np.r_[o.position, o.lin_vel, o.force, i.true_force, list(i.extra.values())]
                for o, i in steps]  # fmt: skip
        return np.array(rows), [set(first[1].extra)] + [set(i.extra) for _, i in steps]

    a, keys = traj(3)
    b, _ = traj(3)
    assert np.array_equal(a, b), "same seed, identical trajectory"
    assert not np.allclose(a, traj(4)[0]), "different seeds differ"
    expected = BASE_EXTRA | {
        "wall_offset_m", "human_goal", "human_goal_x_m", "human_goal_y_m", "human_fx_N",
        "human_fy_N", "disturbance_fx_N", "disturbance_fy_N",
    }  # fmt: skip
    assert all(k == expected for k in keys), "the same extra keys on every step"


def test_hri_stream_leaves_sensor_noise_unchanged() -> None:
    sensor = {"force_noise_std": 0.3}
    plain = make_sim({}, [0.0, 0.0], sensor=sensor)
    with_hri = make_sim({"human": human(noise_std=1.0)}, [0.0, 0.0], sensor=sensor)

    def noise(sim: Pymunk2D) -> np.ndarray:
        _, steps = run(sim, [0.0, 0.0], 200, seed=11)
        return np.array([o.force - i.true_force for o, i in steps])

    a, b = noise(plain), noise(with_hri)
    assert np.allclose(a, b, rtol=0.0, atol=1e-12), "the sensor's stream is untouched"
    assert np.abs(a).max() > 0.1, "there is noise to compare"


# --------------------------------------------------------------------------- existing scenes


def test_existing_scene_unchanged(monkeypatch: pytest.MonkeyPatch) -> None:
    task = OmegaConf.create({"task": OmegaConf.load(TASK_DIR / "smoke.yaml")}).task
    sim = Pymunk2D.from_config({"sensor": {"force_noise_std": 0.3}}, task.scene, task.start)
    assert not sim.scene.has_hri and sim._hri is None  # noqa: SLF001 - the fast path
    made = []
    real = np.random.default_rng
    monkeypatch.setattr(np.random, "default_rng", lambda *a: made.append(a) or real(*a))
    obs, info = sim.reset(3)
    assert made == [(3,)], "only the sensor's generator"
    assert set(info.extra) == BASE_EXTRA
    for _ in range(20):
        obs, info = sim.step(Command(np.array([2.0, -1.0]), ZERO_T))
    assert set(info.extra) == BASE_EXTRA
    # values computed with the code before the HRI elements existed (git 7ad09c0)
    assert obs.position == pytest.approx([0.0003798064293265646, 0.0005694188522508782], 1e-9)
    assert obs.force == pytest.approx([0.07611438109653221, 4.1896679362548666], 1e-9)
    assert info.true_force == pytest.approx([-0.006819346759767682, 3.9795044706500495], 1e-9)


# --------------------------------------------------------------------------- validation


@pytest.mark.parametrize(
    ("scene", "key"),
    [
        ({"compliant_walls": [wall(-1.0)]}, "task.scene.compliant_walls[0].stiffness"),
        (
            {"compliant_walls": [{**wall(1.0), "normal": [0.0, 0.0]}]},
            "task.scene.compliant_walls[0].normal",
        ),
        ({"compliant_walls": [wall(1.0, c=-2.0)]}, "task.scene.compliant_walls[0].damping"),
        (
            {"compliant_walls": [wall(1.0), wall(1.0, jitter=-0.1)]},
            "task.scene.compliant_walls[1].position_jitter_m",
        ),
        (
            {"compliant_walls": [{"point": [0, 0], "normal": [1, 0]}]},
            "task.scene.compliant_walls[0].stiffness",
        ),
        ({"human": human(goals=[])}, "task.scene.human.goals"),
        ({"human": human(goals=[[0, 0], [1, 2, 3]])}, "task.scene.human.goals[1]"),
        ({"human": human(goals=[[0, 0], [1, 1]], goal_index=2)}, "task.scene.human.goal_index"),
        ({"human": human(goal_index=-2)}, "task.scene.human.goal_index"),
        ({"human": human(goal_index=True)}, "task.scene.human.goal_index"),
        ({"human": human(max_force=0.0)}, "task.scene.human.max_force"),
        ({"human": human(noise_cutoff_hz=0.0)}, "task.scene.human.noise_cutoff_hz"),
        ({"human": human(stifness=3.0)}, "task.scene.human.stifness"),
        ({"human": [1, 2]}, "task.scene.human"),
        (
            {"vibration": {"amplitude": [float("nan"), 1.0], "frequency_hz": 10}},
            "task.scene.vibration.amplitude",
        ),
        (
            {"vibration": {"amplitude": [1.0, -1.0], "frequency_hz": 10}},
            "task.scene.vibration.amplitude[1]",
        ),
        ({"vibration": {"amplitude": [1.0, 1.0]}}, "task.scene.vibration.frequency_hz"),
        (
            {"vibration": {"amplitude": [1, 1], "frequency_hz": 10, "harmonics": [20]}},
            "task.scene.vibration.harmonics",
        ),
        (
            {
                "vibration": {
                    "amplitude": [1, 1],
                    "frequency_hz": 10,
                    "region": {"center": [0, 0], "half_extents": [-1, 1]},
                }
            },
            "task.scene.vibration.region.half_extents[0]",
        ),
        ({"walls": []}, "task.scene.walls"),
    ],
)
def test_bad_hri_config_names_the_key(scene: dict[str, Any], key: str) -> None:
    with pytest.raises(ConfigError) as err:
        make_sim(scene, [0.0, 0.0])
    assert err.value.key == key
    assert key in str(err.value) and "\n" not in str(err.value)


def test_dictconfig_scene_parses() -> None:
    cfg = OmegaConf.create({"task": {"scene": full_scene()}})
    scene = SceneSpec.from_mapping(cfg.task.scene)
    assert scene.has_hri and scene.human is not None and scene.human.goal_index == -1
    assert scene.vibration is not None and scene.vibration.amplitude == (0.5, 0.5)


def test_human_ramp_raises_the_force_smoothly() -> None:
    """ramp_s: raised-cosine onset after active_after_s (0 at its start, half way at its middle,
    full and still saturated afterwards); ramp_s = 0 is the step."""
    spec = HumanSpec(goals=((1.0, 0.0),), stiffness=100.0, max_force=0.3, active_after_s=0.1,
                     ramp_s=0.2)  # fmt: skip
    hand = HumanHand(spec, DT)
    hand.reset(np.random.default_rng(0))
    fx = [hand.force(0.0, 0.0, 0.0, 0.0, t)[0] for t in (0.05, 0.1, 0.2, 0.3, 0.5)]
    assert fx == pytest.approx([0.0, 0.0, 0.15, 0.3, 0.3])
    step = HumanHand(HumanSpec(goals=((1.0, 0.0),), stiffness=100.0, max_force=0.3), DT)
    step.reset(np.random.default_rng(0))
    assert step.force(0.0, 0.0, 0.0, 0.0, 0.0)[0] == pytest.approx(0.3)
    with pytest.raises(ConfigError, match="human.ramp_s"):
        HumanSpec.from_mapping({"goals": [[1.0, 0.0]], "stiffness": 1.0, "max_force": 1.0,
                                "ramp_s": -1.0}, "human")  # fmt: skip
