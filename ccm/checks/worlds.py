"""The small worlds the contract kit runs a controller in: one per backend, each with a change
of contact inside a few hundred control steps (issue #41).

* ``pymunk2d``: a spring pulls on the block while it moves 4 cm toward a wall, presses on it
  with 5 N, then slides along it (the springs and the wall of ``configs/task/smoke.yaml`` and
  ``slide_surfaces_2d.yaml``, shortened).
* ``pybullet3d`` and ``mujoco3d``: the Panda's tool comes down onto the table, presses with
  10 N and slides (``configs/task/press_slide_3d.yaml``, shortened); the same task on both
  3-D engines.

:func:`world` builds them from plain mappings with the backends' defaults (1 kHz physics),
so the kit needs no config files; ``faults=True`` turns on the F/T sensor's spikes and
dropouts (``ccm.sim.sensor.SensorConfig``).
"""

from __future__ import annotations

import functools
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

from ccm.core.errors import check_choice
from ccm.sim import make_sim
from ccm.sim.base import Simulator
from ccm.tasks.task import Task, load_task

#: chosen: spikes of 50 N in 2 % of the samples and 20-sample dropouts in 1 %, far more than a
#: real sensor shows, so that a few hundred steps meet several
FAULTS: dict[str, Any] = {"spike_prob": 0.02, "spike_N": 50.0, "dropout_prob": 0.01,
                          "dropout_steps": 20}  # fmt: skip

_PRESS_2D = {"direction": [0.0, 1.0], "magnitude": 5.0}  # N, into the wall above the block
_PRESS_3D = {"direction": [0.0, 0.0, -1.0], "magnitude": 10.0}  # N, into the table

TASKS: dict[str, dict[str, Any]] = {
    "pymunk2d": {
        "name": "check_wall_2d",
        "description": "a spring pulls while the block reaches a wall, presses on it and slides",
        "dim": 2,
        "start": [0.0, 0.0],
        "orientation": [0.0],
        "scene": {
            "gravity": 0.0,
            "ee": {"size": [0.05, 0.05], "mass": 1.0, "rotate": False},
            "surfaces": [],
            "boxes": [{"center": [0.0, 0.085], "size": [0.6, 0.05], "friction": 0.4}],
            "springs": [{"anchor": [-0.2, 0.0], "stiffness": 40.0, "rest_length": 0.1}],
            "viscous": [],
        },
        "pattern": [
            {"type": "line", "name": "approach", "to": [0.0, 0.04], "duration": 0.15},
            {"type": "line", "name": "press", "to": [0.0, 0.05], "duration": 0.1,
             "force": _PRESS_2D},
            {"type": "line", "name": "slide", "to": [0.05, 0.05], "duration": 0.15,
             "force": _PRESS_2D},
        ],
    },
    "pybullet3d": {
        "name": "check_table_3d",
        "description": "the tool comes down onto the table, presses with 10 N and slides",
        "dim": 3,
        "start": [0.45, 0.0, 0.15],
        "orientation": [1.0, 0.0, 0.0, 0.0],
        "scene": {"table": {"height": 0.1, "friction": 0.3}},
        "pattern": [
            {"type": "line", "name": "approach", "to": [0.45, 0.0, 0.11], "duration": 0.15},
            {"type": "line", "name": "press", "to": [0.45, 0.0, 0.09], "duration": 0.1,
             "force": _PRESS_3D},
            {"type": "line", "name": "slide", "to": [0.5, 0.0, 0.09], "duration": 0.15,
             "force": _PRESS_3D},
        ],
    },
}  # fmt: skip
TASKS["mujoco3d"] = TASKS["pybullet3d"]  # the same Panda, scene and task on the second engine


@dataclass(frozen=True)
class World:
    """Where a check runs: a factory of fresh simulators, their control period [s] and the
    task they share."""

    backend: str
    make_sim: Callable[[], Simulator]
    control_dt: float
    task: Task


def world(backend: str = "pymunk2d", faults: bool = False,
          sim: Mapping[str, Any] | None = None) -> World:  # fmt: skip
    """The check world of ``backend`` (module docstring); ``sim``: more ``sim`` settings.
    Without them the world is built once per (backend, faults) and shared (it is immutable:
    each ``make_sim()`` is a new simulator)."""
    if sim is None:
        return _shared(backend, faults)
    return _build(backend, faults, sim)


@functools.cache
def _shared(backend: str, faults: bool) -> World:
    return _build(backend, faults, None)


def _build(backend: str, faults: bool, sim: Mapping[str, Any] | None) -> World:
    check_choice("backend", backend, TASKS)
    spec = TASKS[backend]
    sim_cfg: dict[str, Any] = {"name": backend, **(sim or {})}
    if faults:
        sim_cfg["sensor"] = {**dict(sim_cfg.get("sensor") or {}), **FAULTS}
    start = list(spec["start"]) + (list(spec["orientation"]) if spec["dim"] == 3 else [])

    def make() -> Simulator:
        return make_sim(sim_cfg, spec["scene"], start)

    probe = make()
    try:
        task = load_task(spec, probe.control_dt, key=f"check world {backend}")
    finally:
        probe.close()
    return World(backend=backend, make_sim=make, control_dt=probe.control_dt, task=task)
