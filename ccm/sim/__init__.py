"""Physics backends. :func:`make_sim` builds one from the ``sim`` and ``task.scene`` configs."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

from ccm.core.plugins import resolve_class
from ccm.sim.base import Simulator

#: backend name -> "module:Class", imported lazily (importing PyBullet costs ~80 ms, measured);
#: installed packages add theirs under the ``ccm.simulators`` entry points
#: (:mod:`ccm.core.plugins`), and ``sim._target_`` names one by import path
BACKENDS: dict[str, str] = {
    "pymunk2d": "ccm.sim.pymunk.backend:Pymunk2D",
    "pybullet3d": "ccm.sim.pybullet.backend:PyBullet3D",
    "mujoco3d": "ccm.sim.mujoco.backend:MuJoCo3D",
}


def sim_class(sim_cfg: Mapping[str, Any]) -> type[Simulator]:
    """The simulator class of a ``sim`` config (its ``_target_``, or its ``name``: a built-in
    backend or an installed plugin); its ``dim`` is 2 or 3."""
    return resolve_class("sim", sim_cfg, "name", BACKENDS, "sim", Simulator)[0]


def backend(name: Any) -> type[Simulator]:
    """The simulator class of backend ``name`` (``sim.name``)."""
    return sim_class({"name": name})


def make_sim(
    sim_cfg: Mapping[str, Any], scene_cfg: Mapping[str, Any], start: Sequence[float]
) -> Simulator:
    """Build the simulator that ``sim_cfg`` names (:func:`sim_class`) for a task's scene and
    start position."""
    return sim_class(sim_cfg).from_config(sim_cfg, scene_cfg, start)
