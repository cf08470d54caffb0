"""``make bench``: speed of the pymunk tasks with the fixed impedance controller.

For each task, the closed loop (target sampling, control law, recording, physics, divergence
check) of one full trial is timed ``repeats`` times; the table reports the median wall time
and × real time = simulated time / wall time. Writing files and figures is not timed.
"""

from __future__ import annotations

import argparse
import json
import platform
import statistics
import time
from pathlib import Path
from typing import Any

TASKS = ("smoke", "multi_spring", "porridge_stirring", "slide_surfaces_2d")
#: issue #2 target for multi_spring
TARGETS = {"multi_spring": 50.0}


def bench_task(task: str, repeats: int) -> dict[str, Any]:
    """Median timing of one fixed-impedance trial of ``task``."""
    from hydra import compose, initialize_config_dir

    from ccm.cli import config_dir
    from ccm.runner import build_components, run_trial

    with initialize_config_dir(str(config_dir()), version_base="1.3", job_name="bench"):
        cfg = compose("config", overrides=[f"task={task}", "controller=fixed_impedance"])
    comp = build_components(cfg)
    sim_time = comp.task.pattern.duration
    walls = []
    for r in range(repeats):
        t0 = time.perf_counter()
        rec = run_trial(comp, seed=r, duration_s=sim_time)
        walls.append(time.perf_counter() - t0)
    wall = statistics.median(walls)
    steps = len(rec)
    return {
        "task": task,
        "sim_time_s": sim_time,
        "control_steps": steps,
        "median_wall_s": wall,
        "us_per_control_step": 1e6 * wall / steps,
        "x_realtime": sim_time / wall,
        "target_x_realtime": TARGETS.get(task),
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path("bench.json"))
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args(argv)
    rows = [bench_task(t, args.repeats) for t in TASKS]
    print(
        f"{'task':<20}{'sim [s]':>9}{'steps':>8}{'wall [ms]':>11}{'µs/step':>9}"
        f"{'× real time':>13}{'target':>8}"
    )
    for r in rows:
        tgt = f"≥{r['target_x_realtime']:.0f}" if r["target_x_realtime"] else ""
        print(
            f"{r['task']:<20}{r['sim_time_s']:>9.2f}{r['control_steps']:>8d}"
            f"{1e3 * r['median_wall_s']:>11.1f}{r['us_per_control_step']:>9.1f}"
            f"{r['x_realtime']:>13.1f}{tgt:>8}"
        )
    result = {
        "benchmark": "pymunk2d tasks, fixed_impedance, one trial each",
        "repeats": args.repeats,
        "statistic": "median",
        "machine": {"python": platform.python_version(), "processor": platform.machine()},
        "rows": rows,
    }
    args.out.write_text(json.dumps(result, indent=2) + "\n", encoding="utf-8")
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
