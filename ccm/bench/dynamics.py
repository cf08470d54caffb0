"""Cost of the PyBullet backend's torque law per physics step, by where its model terms come
from (``sim.dynamics``, issue #20): Pinocchio in one call, or PyBullet's queries.

``PyBullet3D._torques`` (joint state, J, h, J̇ q̇, M⁻¹ Jᵀ, Λ, the law itself) is called
``calls`` times on a simulator reset to the start of ``task``, the arm at rest (the cost
does not depend on the state). The two settings are timed in turn, ``repeats`` rounds, so
a drift in the machine's load reaches both; the statistic is the median over rounds of the
mean per call. ``python -m ccm.bench.dynamics`` prints the row.
"""

from __future__ import annotations

import statistics
import time
from typing import Any

import numpy as np

from ccm.bench.components import components as _components
from ccm.sim.pybullet.scene import DYNAMICS


def bench_torques(
    task: str = "changing_surface", calls: int = 2000, repeats: int = 5
) -> dict[str, Any]:
    """Median µs per ``_torques`` call for each ``sim.dynamics`` (module docstring)."""
    sims = {
        d: _components(task, "fixed_impedance", "pybullet3d", [f"sim.dynamics={d}"]).sim
        for d in DYNAMICS
    }
    wrench = np.zeros(6)
    us: dict[str, list[float]] = {d: [] for d in DYNAMICS}
    try:
        for sim in sims.values():
            sim.reset(seed=0)
        for _ in range(repeats):
            for d, sim in sims.items():
                torques = sim._torques  # noqa: SLF001 - the robot's own loop, timed alone
                t0 = time.perf_counter()
                for _ in range(calls):
                    torques(wrench)
                us[d].append(1e6 * (time.perf_counter() - t0) / calls)
    finally:
        for sim in sims.values():
            sim.close()
    return {
        "benchmark": "pybullet_torques",
        "task": task,
        "calls": calls,
        "repeats": repeats,
        "us_per_call_median": {d: statistics.median(v) for d, v in us.items()},
        "us_per_call_all": us,
    }


if __name__ == "__main__":
    print(bench_torques())
