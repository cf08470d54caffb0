"""A simulator plugin for ``tests/test_plugins.py``: ccm's planar backend with a heavier
end-effector, as a user might adapt a built-in backend in their own package."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

from ccm.sim.pymunk.backend import Pymunk2D


class HeavyPymunk(Pymunk2D):
    """:class:`Pymunk2D` whose end-effector mass is multiplied by ``mass_factor``."""

    @classmethod
    def from_config(
        cls, sim_cfg: Mapping[str, Any], scene_cfg: Mapping[str, Any], start: Sequence[float]
    ) -> HeavyPymunk:
        cfg = {k: v for k, v in sim_cfg.items() if k not in ("mass_factor", "name")}
        ee = dict(scene_cfg.get("ee") or {})
        ee["mass"] = float(sim_cfg.get("mass_factor", 2.0)) * float(ee.get("mass", 1.0))
        return super().from_config(cfg, {**scene_cfg, "ee": ee}, start)  # type: ignore[return-value]
