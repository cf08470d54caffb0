"""Physics checks of the pymunk 2D backend: springs, drag, friction, sensor sign and noise.

The end-effector is driven by small PD / velocity loops written here (ccm.control is not
used). Every assertion states its tolerance.
"""

from __future__ import annotations

import copy
from collections.abc import Callable
from typing import Any

import numpy as np
import pytest
from omegaconf import OmegaConf

from ccm.core.errors import ConfigError, SimulationDiverged
from ccm.core.types import Command, Observation, StepInfo
from ccm.sim.pymunk.backend import Pymunk2D
from ccm.sim.pymunk.config import Pymunk2DConfig
from ccm.sim.pymunk.scene import SceneSpec
from ccm.sim.sensor import FTSensor, SensorConfig

ZERO_T = np.zeros(1)
EE_HALF = 0.025  # half size of the default 0.05 m end-effector box
FLOOR_REST_Y = EE_HALF + 0.002  # EE centre when resting on a floor segment of radius 2 mm


def make_sim(scene: dict[str, Any], start: list[float], **sim: Any) -> Pymunk2D:
    return Pymunk2D.from_config(sim, scene, start)


def run(
    sim: Pymunk2D,
    law: Callable[[Observation], np.ndarray],
    n: int,
    seed: int = 0,
) -> list[tuple[Observation, StepInfo]]:
    """Reset, then apply ``law(obs) -> force`` for ``n`` control steps; return a copy of
    every step (the simulator reuses its objects: issue #40)."""
    obs, info = sim.reset(seed)
    out = []
    for _ in range(n):
        obs, info = sim.step(Command(law(obs), ZERO_T))
        out.append(copy.deepcopy((obs, info)))
    return out


def hold(target: list[float], kp: float = 5000.0, ki: float = 50000.0, m: float = 1.0) -> Callable:
    """A stiff PID (critically damped PD plus integral) that holds the EE at ``target``."""
    kd = 2.0 * np.sqrt(kp * m)
    p_d = np.asarray(target, dtype=float)
    integral = np.zeros(2)

    def law(o: Observation) -> np.ndarray:
        integral[:] += (p_d - o.position) * 0.001
        return kp * (p_d - o.position) - kd * o.lin_vel + ki * integral

    return law


def velocity(
    v_d: list[float], kv: float = 200.0, ki: float = 2000.0, extra: list[float] | None = None
) -> Callable:
    """A PI velocity loop plus a constant extra force (e.g. a commanded normal force)."""
    vd = np.asarray(v_d, dtype=float)
    ex = np.zeros(2) if extra is None else np.asarray(extra, dtype=float)
    integral = np.zeros(2)

    def law(o: Observation) -> np.ndarray:
        integral[:] += (vd - o.lin_vel) * 0.001
        return kv * (vd - o.lin_vel) + ki * integral + ex

    return law


# --------------------------------------------------------------------------- 1. springs


def test_static_spring_force_matches_hooke() -> None:
    k = 300.0
    sim = make_sim({"springs": [{"anchor": [0.0, 0.0], "stiffness": k}]}, [0.1, 0.05])
    obs, info = run(sim, hold([0.1, 0.05]), 2000)[-1]
    expected = -k * obs.position  # anchor at the origin, rest length 0
    assert np.linalg.norm(obs.lin_vel) < 1e-6, "EE should have settled (|v| < 1e-6 m/s)"
    assert np.allclose(obs.force, expected, rtol=0.01), f"{obs.force} vs {expected} (1 %)"
    assert np.allclose(obs.force, [-30.0, -15.0], rtol=0.01), "-k dx at the held offset (1 %)"
    assert info.n_contacts == 0 and info.extra["contact"] == 0.0


def test_spring_with_rest_length_and_three_springs() -> None:
    springs = [
        {"anchor": [0.0, 0.0], "stiffness": 100.0, "rest_length": 0.05},
        {"anchor": [0.3, 0.0], "stiffness": 50.0},
        {"anchor": [0.1, 0.2], "stiffness": 20.0, "rest_length": 0.1},
    ]
    sim = make_sim({"springs": springs}, [0.1, 0.0])
    obs, _ = run(sim, hold([0.1, 0.0]), 2000)[-1]
    expected = np.zeros(2)
    for s in springs:
        d = obs.position - np.asarray(s["anchor"])
        r = np.linalg.norm(d)
        expected += -s["stiffness"] * (r - s.get("rest_length", 0.0)) * d / r
    assert np.allclose(obs.force, expected, rtol=0.01, atol=1e-9), "sum of springs (1 %)"


def test_spring_attaches_and_detaches_on_schedule() -> None:
    """A spring with attach_s / detach_s pulls only inside [attach_s, detach_s); the truth
    column ``springs_attached`` counts the attached springs."""
    k = 100.0
    spring = {"anchor": [0.0, 0.0], "stiffness": k, "attach_s": 0.2, "detach_s": 0.5}
    sim = make_sim({"springs": [spring]}, [0.1, 0.0])
    steps = run(sim, hold([0.1, 0.0]), 700)
    for obs, info in steps:
        on = 0.2 + 1e-9 < obs.t <= 0.5 + 1e-9  # the force of the step that ended at obs.t
        f = np.linalg.norm(info.true_force)
        if on:
            assert f == pytest.approx(k * np.linalg.norm(obs.position), rel=0.05)
        else:
            assert f < 1e-6, f"no pull at t={obs.t:.3f} s"
    attached = [info.extra["springs_attached"] for _, info in steps]
    assert set(attached) == {0.0, 1.0}
    with pytest.raises(ConfigError, match=r"springs\[0\]\.detach_s"):
        make_sim({"springs": [{**spring, "detach_s": 0.1}]}, [0.1, 0.0])


# --------------------------------------------------------------------------- 2. viscosity


def test_viscous_drag_constant_field() -> None:
    c = 5.0
    scene = {"viscous": [{"region": None, "schedule": {"kind": "constant", "value": c}}]}
    sim = make_sim(scene, [0.0, 0.0])
    obs, info = run(sim, velocity([0.2, -0.1]), 1000)[-1]
    assert np.allclose(obs.force, -c * obs.lin_vel, rtol=0.01), "F = -c v (1 %)"
    assert np.allclose(obs.lin_vel, [0.2, -0.1], rtol=0.05), "moving near v_d (5 %)"
    assert info.extra["viscosity_Nspm"] == pytest.approx(c, rel=1e-12)


def test_viscous_region_only_inside() -> None:
    region = {"center": [0.5, 0.0], "half_extents": [0.1, 0.1]}
    scene = {"viscous": [{"region": region, "schedule": {"kind": "constant", "value": 3.0}}]}
    sim = make_sim(scene, [0.0, 0.0])
    for obs, info in run(sim, velocity([0.5, 0.0]), 2000):
        inside = abs(obs.position[0] - 0.5) <= 0.1
        assert info.extra["viscosity_Nspm"] == (3.0 if inside else 0.0)
        if abs(obs.position[0] - 0.5) > 0.11:  # away from the edge (one-step lag)
            assert np.linalg.norm(obs.force) < 1e-9, "no drag outside the region (1e-9 N)"


@pytest.mark.parametrize(
    ("start", "end", "rate", "n", "expected"),
    [
        (0.0, 10.0, 0.01, 500, 5.0),
        (0.0, 10.0, 0.01, 1500, 10.0),  # clipped at end
        (10.0, 2.0, -0.01, 500, 5.0),  # ramp down
        (10.0, 2.0, -0.01, 1500, 2.0),  # clipped at end on the way down
    ],
)
def test_viscosity_ramp_per_step(
    start: float, end: float, rate: float, n: int, expected: float
) -> None:
    sched = {"kind": "ramp_per_step", "start": start, "end": end, "rate": rate}
    sim = make_sim({"viscous": [{"schedule": sched}]}, [0.0, 0.0])
    _, info = run(sim, lambda o: np.zeros(2), n)[-1]
    assert info.extra["viscosity_Nspm"] == pytest.approx(expected, abs=1e-9), "c(N) (1e-9)"


def test_viscosity_ramp_per_distance() -> None:
    sched = {"kind": "ramp_per_distance", "start": 1.0, "end": 50.0, "rate": 100.0}
    sim = make_sim({"viscous": [{"schedule": sched}]}, [0.0, 0.0])
    steps = run(sim, velocity([0.1, 0.0]), 1000)
    obs, info = steps[-1]
    travelled = obs.position[0]  # straight line along +x from the origin
    assert sim.path_length == pytest.approx(travelled, rel=1e-6), "path length (1e-6)"
    assert info.extra["viscosity_Nspm"] == pytest.approx(1.0 + 100.0 * travelled, rel=1e-9)
    assert 0.09 < travelled < 0.1, "moved about 0.1 m in 1 s"
    assert np.allclose(obs.force, -info.extra["viscosity_Nspm"] * obs.lin_vel, rtol=0.01)


# --------------------------------------------------------------------------- 3. friction


def test_steady_sliding_friction_on_two_patches() -> None:
    mu_lo, mu_hi, normal = 0.2, 0.6, 10.0
    floor = {
        "a": [-1.0, 0.0],
        "b": [1.0, 0.0],
        "friction": mu_lo,
        "patches": [{"from": 1.0, "to": 2.0, "friction": mu_hi}],  # x in [0, 1]
    }
    sim = make_sim({"surfaces": [floor]}, [-0.3, FLOOR_REST_Y])
    steps = run(sim, velocity([0.2, 0.0], extra=[0.0, -normal]), 3000)
    x = np.array([o.position[0] for o, _ in steps])
    f = np.array([o.force for o, _ in steps])
    v = np.array([o.lin_vel[0] for o, _ in steps])
    mu_seen = np.array([i.extra["surface_friction"] for _, i in steps])
    for mu, (lo, hi) in [(mu_lo, (-0.2, -0.05)), (mu_hi, (0.1, 0.25))]:
        sel = (x > lo) & (x < hi)
        assert sel.sum() > 500
        assert np.allclose(v[sel], 0.2, rtol=0.02), "steady sliding at 0.2 m/s (2 %)"
        assert np.allclose(f[sel, 0], -mu * normal, rtol=0.05), f"F_t = -mu N, mu={mu} (5 %)"
        assert np.allclose(f[sel, 1], normal, rtol=0.05), "F_n = N (5 %)"
        assert np.all(mu_seen[sel] == mu), "surface_friction reports the touched patch"


# --------------------------------------------------------------------------- 4./5. signs


def test_free_space_reads_zero() -> None:
    sim = make_sim({"gravity": 9.81}, [0.0, 1.0])
    for obs, info in run(sim, lambda o: np.array([1.0, 0.5]), 300):
        assert np.linalg.norm(obs.force) < 1e-9, "|F| < 1e-9 N in free space"
        assert abs(obs.torque[0]) < 1e-9 and info.n_contacts == 0
    assert obs.lin_vel[0] == pytest.approx(0.3, rel=1e-6), "F = m a under compensated gravity"
    assert obs.lin_vel[1] == pytest.approx(0.15, rel=1e-6)


def test_signs_push_floor_wall_and_springs() -> None:
    floor = {"surfaces": [{"a": [-1.0, 0.0], "b": [1.0, 0.0]}]}
    obs, _ = run(make_sim(floor, [0.0, FLOOR_REST_Y]), lambda o: np.array([0.0, -5.0]), 200)[-1]
    assert obs.force[1] == pytest.approx(5.0, rel=0.01), "pushing down reads +y (1 %)"
    wall = {"boxes": [{"center": [0.2, 0.0], "size": [0.1, 1.0]}]}
    obs, _ = run(make_sim(wall, [0.15 - EE_HALF, 0.0]), lambda o: np.array([4.0, 0.0]), 200)[-1]
    assert obs.force[0] == pytest.approx(-4.0, rel=0.01), "pushing +x into a wall reads -x (1 %)"
    spring = {"springs": [{"anchor": [0.0, 0.0], "stiffness": 100.0, "rest_length": 0.1}]}
    stretched, _ = run(make_sim(spring, [0.15, 0.0]), hold([0.15, 0.0]), 1500)[-1]
    compressed, _ = run(make_sim(spring, [0.05, 0.0]), hold([0.05, 0.0]), 1500)[-1]
    assert stretched.force[0] == pytest.approx(-5.0, rel=0.01), "stretched to +x reads -x"
    assert compressed.force[0] == pytest.approx(5.0, rel=0.01), "compressed reads +x (1 %)"


def test_resting_under_gravity_without_compensation() -> None:
    m, g = 2.0, 9.81
    scene = {"gravity": g, "ee": {"mass": m}, "surfaces": [{"a": [-1.0, 0.0], "b": [1.0, 0.0]}]}
    sim = make_sim(scene, [0.0, FLOOR_REST_Y], gravity_compensation=False)
    obs, info = run(sim, lambda o: np.zeros(2), 1000)[-1]
    assert obs.force[1] == pytest.approx(m * g, rel=0.01), "reads +m g (1 %)"
    assert abs(obs.force[0]) < 1e-9 and info.n_contacts == 2
    assert np.allclose(info.contact_force, obs.force), "all of it is contact"


def test_contact_torque_about_centre() -> None:
    floor = [{"a": [-1.0, 0.0], "b": [1.0, 0.0], "friction": 0.5}]
    push = np.array([2.0, 0.0])  # below the friction limit 0.5 m g: static
    for rotate, expected in [(False, -EE_HALF * 2.0), (True, 0.0)]:
        scene = {"gravity": 9.81, "ee": {"rotate": rotate}, "surfaces": floor}
        sim = make_sim(scene, [0.0, FLOOR_REST_Y], gravity_compensation=False)
        obs, info = run(sim, lambda o, p=push: p, 1000)[-1]
        assert obs.force[0] == pytest.approx(-2.0, rel=0.01), "static friction balances (1 %)"
        # locked: friction at the bottom face, r_y = -h/2; free: contacts balance the box
        assert obs.torque[0] == pytest.approx(expected, abs=1e-3), f"rotate={rotate} (1e-3 N m)"


# --------------------------------------------------------------------------- 6. sensor noise


def test_sensor_noise_bias_and_seeding() -> None:
    sigma, bias = 0.5, [1.0, -2.0]
    sensor = {"force_noise_std": sigma, "torque_noise_std": 0.1, "force_bias": bias}
    sim = make_sim({}, [0.0, 0.0], sensor=sensor)

    def readings(seed: int) -> np.ndarray:
        return np.array([o.force for o, _ in run(sim, lambda o: np.zeros(2), 4000, seed)])

    a = readings(1)
    assert np.allclose(a.std(axis=0), sigma, rtol=0.10), f"std {a.std(axis=0)} vs {sigma} (10 %)"
    assert np.allclose(a.mean(axis=0), bias, atol=0.05), "bias shifts the mean (0.05 N)"
    assert np.array_equal(a, readings(1)), "same seed, identical readings"
    assert not np.allclose(a, readings(2)), "different seeds differ"
    obs, info = run(sim, lambda o: np.zeros(2), 1)[-1]
    assert np.array_equal(info.true_force, np.zeros(2)), "truth is noiseless"


def test_ft_sensor_dimension_agnostic() -> None:
    cfg = SensorConfig.from_values(force_noise_std=[0.1, 0.2, 0.3], force_dim=3, torque_dim=3)
    s = FTSensor(cfg, force_dim=3, torque_dim=3)
    s.reset(np.random.default_rng(0))
    f, t = s.measure(np.ones(3), np.zeros(3))
    assert f.shape == (3,) and t.shape == (3,) and np.array_equal(t, np.zeros(3))


# --------------------------------------------------------------------------- 7. bad config


@pytest.mark.parametrize(
    ("sim_cfg", "scene", "key"),
    [
        (
            {},
            {"springs": [{"anchor": [0, 0], "stiffness": -1.0}]},
            "task.scene.springs[0].stiffness",
        ),
        ({"dt": 0.0}, {}, "sim.dt"),
        ({}, {"springs": [{"anchor": [0, 0], "stifness": 1.0}]}, "task.scene.springs[0].stifness"),
        ({}, {"walls": []}, "task.scene.walls"),
        ({}, {"ee": {"mass": 0}}, "task.scene.ee.mass"),
        ({"sensor": {"force_noise_std": -1}}, {}, "sim.sensor.force_noise_std"),
        ({"sensor": {"force_bias": [0.0]}}, {}, "sim.sensor.force_bias"),
        (
            {},
            {
                "viscous": [
                    {"schedule": {"kind": "ramp_per_step", "start": 0, "end": 1, "rate": -1}}
                ]
            },
            "task.scene.viscous[0].schedule.rate",
        ),
        ({}, {"viscous": [{"schedule": {"kind": "cubic"}}]}, "task.scene.viscous[0].schedule.kind"),
        (
            {},
            {
                "surfaces": [
                    {"a": [0, 0], "b": [1, 0], "patches": [{"from": 0.5, "to": 2.0, "friction": 1}]}
                ]
            },
            "task.scene.surfaces[0].patches[0].to",
        ),
    ],
)
def test_bad_config_names_the_key(sim_cfg: dict, scene: dict, key: str) -> None:
    with pytest.raises(ConfigError) as err:
        Pymunk2D.from_config(sim_cfg, scene, [0.0, 0.0])
    assert err.value.key == key
    assert key in str(err.value) and "\n" not in str(err.value)


def test_unknown_key_lists_allowed_keys() -> None:
    with pytest.raises(ConfigError, match="allowed: anchor, stiffness, rest_length"):
        SceneSpec.from_mapping({"springs": [{"anchor": [0, 0], "k": 1.0}]})


def test_dictconfig_input_and_nonfinite_command() -> None:
    cfg = OmegaConf.create(
        {
            "sim": {"name": "pymunk2d", "dt": 0.001, "sensor": {"force_bias": [0.0, 0.0]}},
            "task": {
                "scene": {"springs": [{"anchor": [0, 0], "stiffness": 10}]},
                "start": [0.1, 0],
            },
        }
    )
    sim = Pymunk2D.from_config(cfg.sim, cfg.task.scene, cfg.task.start)
    obs, info = sim.reset(0)
    assert obs.t == 0.0 and np.allclose(info.true_force, [-1.0, 0.0])
    with pytest.raises(SimulationDiverged):
        sim.step(Command(np.array([np.nan, 0.0]), ZERO_T))


# --------------------------------------------------------------------------- rates, reset


def test_control_decimation_averages_the_physics_steps() -> None:
    scene = {"springs": [{"anchor": [0.0, 0.0], "stiffness": 200.0}]}
    fine = make_sim(scene, [0.1, 0.0])
    coarse = Pymunk2D(
        SceneSpec.from_mapping(scene), [0.1, 0.0], Pymunk2DConfig(control_decimation=5)
    )
    push = np.array([1.0, 2.0])
    fine_steps = run(fine, lambda o: push, 50)
    coarse_steps = run(coarse, lambda o: push, 10)
    mean_fine = np.array([i.true_force for _, i in fine_steps]).reshape(10, 5, 2).mean(axis=1)
    coarse_f = np.array([o.force for o, _ in coarse_steps])
    assert np.allclose(coarse_f, mean_fine, rtol=1e-12, atol=1e-12), "mean over the period"
    assert coarse_steps[-1][0].t == pytest.approx(0.05) and coarse.physics_steps == 50
    assert np.array_equal(coarse_steps[-1][0].position, fine_steps[-1][0].position)


def test_reset_rebuilds_and_hands_out_read_only_step_objects() -> None:
    """A fresh start at every reset; one Observation and StepInfo per trial, updated in place
    and read-only to the receiver (valid until the next step, issue #40)."""
    sim = make_sim({"springs": [{"anchor": [0.0, 0.0], "stiffness": 50.0}]}, [0.2, 0.1])
    first = run(sim, lambda o: np.array([3.0, -1.0]), 200)
    second = run(sim, lambda o: np.array([3.0, -1.0]), 200)
    assert np.array_equal(first[-1][0].position, second[-1][0].position), "reset is a fresh start"
    obs, info = sim.reset(0)
    assert np.array_equal(obs.position, [0.2, 0.1]) and np.array_equal(obs.lin_vel, [0.0, 0.0])
    for arr in (obs.position, obs.force, obs.lin_vel, info.true_force, info.contact_force):
        with pytest.raises(ValueError, match="read-only"):
            arr[0] = 99.0
    kept = obs.lin_vel.copy()
    nxt, nxt_info = sim.step(Command(np.array([3.0, -1.0]), ZERO_T))
    assert nxt is obs and nxt_info is info and nxt.t == sim.dt * sim.control_decimation
    assert not np.array_equal(obs.lin_vel, kept), "updated in place"
    assert np.array_equal(kept, [0.0, 0.0]), "a copy keeps its values"
