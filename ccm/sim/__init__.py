"""Physics backends. :func:`make_sim` builds one from the ``sim`` and ``task.scene`` configs."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

from ccm.core.errors import check_choice
from ccm.sim.base import Simulator

#: backend name -> "module:Class", imported lazily (importing PyBullet costs ~80 ms, measured)
BACKENDS: dict[str, str] = {
    "pymunk2d": "ccm.sim.pymunk.backend:Pymunk2D",
    "pybullet3d": "ccm.sim.pybullet.backend:PyBullet3D",
}


def backend(name: Any) -> type[Simulator]:
    """The simulator class of backend ``name`` (``sim.name``); its ``dim`` is 2 or 3."""
    import importlib

    module, cls_name = BACKENDS[check_choice("sim.name", name, BACKENDS)].split(":")
    return getattr(importlib.import_module(module), cls_name)


def make_sim(
    sim_cfg: Mapping[str, Any], scene_cfg: Mapping[str, Any], start: Sequence[float]
) -> Simulator:
    """Build the simulator named by ``sim_cfg['name']`` for a task's scene and start position."""
    return backend(sim_cfg.get("name")).from_config(sim_cfg, scene_cfg, start)
