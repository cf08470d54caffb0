"""Tasks: every shipped YAML loads, and load_task validates its input."""

from __future__ import annotations

import copy
import math
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from omegaconf import DictConfig, OmegaConf

from ccm.core.errors import ConfigError
from ccm.tasks.task import Task, load_task

TASK_DIR = Path(__file__).resolve().parents[1] / "configs" / "task"
TASK_FILES = sorted(TASK_DIR.glob("*.yaml"))
CONTROL_DT = 0.001


def compose(path: Path) -> DictConfig:
    """The task file placed under ``task`` (its Hydra package) so interpolations resolve; a
    task that extends another (a ``defaults`` list, e.g. h4_contact_learning_demo) is
    composed by Hydra."""
    node = OmegaConf.load(path)
    if "defaults" in node:
        from hydra import compose as hydra_compose
        from hydra import initialize_config_dir

        with initialize_config_dir(str(TASK_DIR.parent), version_base="1.3", job_name="test"):
            return hydra_compose("config", overrides=[f"task={path.stem}"]).task
    root = OmegaConf.create({"task": node})
    assert isinstance(root, DictConfig)
    return root.task


def load(name: str) -> Task:
    return load_task(compose(TASK_DIR / f"{name}.yaml"), CONTROL_DT)


def _scene_points(scene: dict[str, Any]) -> list[tuple[str, Any]]:
    """Every position/size vector in a scene, with a readable label."""
    out: list[tuple[str, Any]] = [("ee.size", scene["ee"]["size"])]
    for i, s in enumerate(scene.get("surfaces") or []):
        out += [(f"surfaces[{i}].a", s["a"]), (f"surfaces[{i}].b", s["b"])]
    for i, b in enumerate(scene.get("boxes") or []):
        out += [(f"boxes[{i}].center", b["center"]), (f"boxes[{i}].size", b["size"])]
    for i, s in enumerate(scene.get("springs") or []):
        out.append((f"springs[{i}].anchor", s["anchor"]))
    for i, v in enumerate(scene.get("viscous") or []):
        if v.get("region"):
            out += [(f"viscous[{i}].center", v["region"]["center"])]
            out += [(f"viscous[{i}].half_extents", v["region"]["half_extents"])]
    return out


def test_expected_tasks_exist() -> None:
    names = {p.stem for p in TASK_FILES}
    assert {"porridge_stirring", "multi_spring", "slide_surfaces_2d", "smoke"} <= names


@pytest.mark.parametrize("path", TASK_FILES, ids=lambda p: p.stem)
def test_every_task_yaml_loads(path: Path) -> None:
    task = load_task(compose(path), CONTROL_DT)
    assert task.name == path.stem
    assert task.description
    assert task.dim in (2, 3)
    assert task.start.shape == (task.dim,)
    assert task.pattern.dim == task.dim
    np.testing.assert_allclose(task.pattern.start, task.start, rtol=0, atol=1e-12)
    assert task.duration > 0
    assert all(seg.duration > 0 for seg in task.pattern.segments)
    assert task.pattern.sample(0.0).orientation.shape == ((1,) if task.dim == 2 else (4,))
    if task.dim == 2:
        for label, vec in _scene_points(task.scene):
            assert len(vec) == 2, f"{path.name}: scene.{label} must have 2 entries"
    # the composed config is plain data (no unresolved interpolations left)
    assert "${" not in str(task.scene) and "${" not in str(task.params)


def test_porridge_stirring_matches_seed_a() -> None:
    task = load("porridge_stirring")
    ramp = task.params["ramp"]
    assert (ramp["train_end"], ramp["test_end"]) == (80.0, 150.0)
    (field,) = task.scene["viscous"]
    sched = field["schedule"]
    assert field["region"] is None
    assert sched["kind"] == "ramp_per_step"
    assert (sched["start"], sched["end"]) == (0.0, ramp["test_end"])  # interpolation resolved
    # the ramp reaches its end exactly when the circle ends (1 ms physics steps)
    assert sched["rate"] * ramp["physics_steps"] == pytest.approx(sched["end"])
    assert ramp["physics_steps"] * 1e-3 == pytest.approx(task.duration)
    # start on the circle, one full turn, peak speed ≈ 0.2 m/s
    (arc,) = task.pattern.segments
    assert arc.radius == pytest.approx(0.1)
    assert arc.sweep == pytest.approx(2 * math.pi)
    np.testing.assert_allclose(task.pattern.end, task.start, atol=1e-12)
    many = task.pattern.sample_many(np.linspace(0, task.duration, 6001))
    peak = np.linalg.norm(many["velocity"], axis=1).max()
    assert peak == pytest.approx(0.2, abs=0.01)
    assert task.scene["gravity"] == 0.0


def test_multi_spring_has_three_different_springs() -> None:
    task = load("multi_spring")
    springs = task.scene["springs"]
    assert len(springs) == 3
    assert len({s["stiffness"] for s in springs}) == 3
    for s in springs:
        assert np.linalg.norm(s["anchor"]) == pytest.approx(0.3, abs=1e-4)


def test_slide_surfaces_force_segments() -> None:
    task = load("slide_surfaces_2d")
    segs = task.pattern.segments
    assert [s.force_dir is not None for s in segs] == [False, True, True, True]
    for s in segs[1:]:
        assert s.force_dir is not None
        np.testing.assert_array_equal(s.force_dir, [0.0, -1.0])
        assert s.force_mag == 10.0
    np.testing.assert_allclose(task.pattern.end, [1.1, 0.02], atol=1e-12)
    floor = task.scene["surfaces"][0]
    length = float(np.linalg.norm(np.subtract(floor["b"], floor["a"])))
    for patch in floor["patches"]:
        assert 0 <= patch["from"] < patch["to"] <= length
        # every patch lies on the slide path (x from 0 to 1.1 m)
        assert 0.0 < floor["a"][0] + patch["from"] < floor["a"][0] + patch["to"] < 1.1
    # the approach ends above the resting height of the block's centre
    rest_y = task.scene["ee"]["size"][1] / 2 + floor["radius"]
    assert segs[0].end[1] > rest_y > segs[1].end[1]


def test_smoke_is_short() -> None:
    task = load("smoke")
    assert task.duration < 0.5


# --- load_task validation ------------------------------------------------------------------

BASE: dict[str, Any] = {
    "name": "t",
    "description": "test task",
    "dim": 2,
    "start": [0.0, 0.0],
    "scene": {"gravity": 0.0},
    "pattern": [{"type": "line", "to": [0.1, 0.0], "duration": 1.0}],
}


def test_load_task_accepts_plain_dict_and_defaults() -> None:
    task = load_task(BASE, CONTROL_DT)
    assert task.params == {}
    np.testing.assert_array_equal(task.pattern.orientation, [0.0])
    assert task.duration == 1.0


def test_load_task_3d_requires_and_normalises_orientation() -> None:
    cfg = dict(BASE, dim=3, start=[0.4, 0.0, 0.3])
    cfg["pattern"] = [{"type": "line", "to": [0.5, 0.0, 0.3], "steps": 500}]
    with pytest.raises(ConfigError, match=r"^task\.orientation: required"):
        load_task(cfg, CONTROL_DT)
    task = load_task(dict(cfg, orientation=[2.0, 0.0, 0.0, 0.0]), CONTROL_DT)
    np.testing.assert_array_equal(task.pattern.orientation, [1.0, 0.0, 0.0, 0.0])
    assert task.duration == pytest.approx(0.5)


def _bad(**changes: Any) -> dict[str, Any]:
    cfg = copy.deepcopy(BASE)
    for k, v in changes.items():
        if v is None:
            cfg.pop(k, None)
        else:
            cfg[k] = v
    return cfg


@pytest.mark.parametrize(
    ("cfg", "key", "fragment"),
    [
        (_bad(speed=1.0), "task.speed", "unknown key; allowed: name, description, dim"),
        (_bad(name=None), "task.name", "missing"),
        (_bad(pattern=None), "task.pattern", "missing"),
        (_bad(scene=None), "task.scene", "missing"),
        (_bad(name=""), "task.name", "non-empty"),
        (_bad(dim=4), "task.dim", "allowed: 2, 3"),
        (_bad(dim=True), "task.dim", "allowed: 2, 3"),
        (_bad(start=[0.0, 0.0, 0.0]), "task.start", "length 2"),
        (_bad(scene=[1, 2]), "task.scene", "mapping"),
        (_bad(params=[1]), "task.params", "mapping"),
        (_bad(orientation=[0.0, 1.0]), "task.orientation", "length 1"),
        (_bad(pattern=[]), "task.pattern", "at least one"),
        (
            _bad(pattern=[{"type": "hold", "duration": -1}]),
            "task.pattern[0].duration",
            "must be > 0, got -1",
        ),
        ("not a mapping", "task", "mapping"),
    ],
)
def test_load_task_errors_name_the_key(cfg: Any, key: str, fragment: str) -> None:
    with pytest.raises(ConfigError) as info:
        load_task(cfg, CONTROL_DT)
    msg = str(info.value)
    assert msg.startswith(f"{key}: "), msg
    assert fragment in msg, msg


def test_unresolvable_interpolation_is_a_config_error() -> None:
    cfg = OmegaConf.load(TASK_DIR / "porridge_stirring.yaml")  # not wrapped under `task`
    assert isinstance(cfg, DictConfig)
    with pytest.raises(ConfigError, match=r"^task: .*task\.params\.ramp\.test_end"):
        load_task(cfg, CONTROL_DT)


def test_tasks_do_not_import_sim_or_control() -> None:
    code = (
        "import sys, ccm.tasks.task, ccm.tasks.trajectory; "
        "print([m for m in sys.modules if m.startswith(('ccm.sim', 'ccm.control'))])"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"
