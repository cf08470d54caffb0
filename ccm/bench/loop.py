"""``make bench``: speed of the closed loop per task, controller and simulator.

For each row, the closed loop (target sampling, control law, recording, physics, divergence
check) of one full trial is timed ``repeats`` times; the table reports the median wall time
and × real time = simulated time / wall time. Writing files and figures is not timed.
Rows with ``fresh=True`` build new components (simulator and an untrained controller) before
each timed trial, so a learning controller starts from nothing every time, as in the first
trial of an experiment; building them (URDF loading, imports) is not timed.
"""

from __future__ import annotations

import argparse
import json
import platform
import statistics
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

TASKS = ("smoke", "multi_spring", "porridge_stirring", "slide_surfaces_2d")
#: issue #2 target for multi_spring
TARGETS = {"multi_spring": 50.0, "changing_surface": 5.0}  # issues #2 and #4


def _components(
    task: str, controller: str, sim: str | None = None, extra: Sequence[str] = ()
) -> Any:
    """Task, controller and simulator as ``ccm run`` builds them (``extra``: more overrides)."""
    from hydra import compose, initialize_config_dir

    from ccm.cli import config_dir
    from ccm.runner import build_components

    with initialize_config_dir(str(config_dir()), version_base="1.3", job_name="bench"):
        overrides = [f"task={task}", f"controller={controller}"]
        overrides += ([f"sim={sim}"] if sim else []) + list(extra)
        cfg = compose("config", overrides=overrides)
    return build_components(cfg)


def bench_avic_step(task: str = "porridge_stirring", trials: int = 3) -> dict[str, Any]:
    """Median cost of one AVIC ``step`` (features, IGMM update, GMR predict, Eq. 4a-4c) in the
    closed loop of ``task``; each control step is timed on its own with perf_counter_ns."""
    comp = _components(task, "avic")
    sim, pattern, ctrl = comp.sim, comp.task.pattern, comp.controller
    ns: list[int] = []
    ctrl.reset(comp.task.dim, sim.control_dt)
    for trial in range(trials):  # the model carries over, as in a repeated-trial experiment
        obs, _ = sim.reset(seed=trial)
        ctrl.reset(comp.task.dim, sim.control_dt)
        for _ in range(int(pattern.duration / sim.control_dt)):
            target = pattern.sample(obs.t)
            t0 = time.perf_counter_ns()
            cmd = ctrl.step(obs, target)
            ns.append(time.perf_counter_ns() - t0)
            obs, _ = sim.step(cmd)
        ctrl.end_trial()
    return {
        "benchmark": "avic_step",
        "task": task,
        "steps": len(ns),
        "us_per_step_median": statistics.median(ns[1000:]) / 1e3,  # after numba warm-up
        "n_components_end": ctrl.signals()["n_components"],
        "target_us": 25.0,
    }


def bench_task(
    task: str,
    repeats: int,
    controller: str = "fixed_impedance",
    sim: str | None = None,
    fresh: bool = False,
) -> dict[str, Any]:
    """Median timing of one trial of ``task`` with ``controller`` (see the module docstring)."""
    from ccm.runner import run_trial

    comp = _components(task, controller, sim)
    sim_time = comp.task.pattern.duration
    walls = []
    for r in range(repeats):
        if fresh and r > 0:
            comp.sim.close()
            comp = _components(task, controller, sim)
        t0 = time.perf_counter()
        rec = run_trial(comp, seed=r, duration_s=sim_time)
        walls.append(time.perf_counter() - t0)
    comp.sim.close()
    wall = statistics.median(walls)
    steps = len(rec)
    return {
        "task": task,
        "controller": controller,
        "sim": sim or "pymunk2d",
        "fresh_controller": fresh,
        "sim_time_s": sim_time,
        "control_steps": steps,
        "median_wall_s": wall,
        "us_per_control_step": 1e6 * wall / steps,
        "x_realtime": sim_time / wall,
        "target_x_realtime": TARGETS.get(task),
    }


def main(argv: list[str] | None = None) -> int:
    from ccm.bench.h3 import bench_h3, print_h3
    from ccm.bench.igmm import bench_igmm_long, bench_igmm_step
    from ccm.bench.mpc import bench_mpc, print_mpc

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path("bench.json"))
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument(
        "--long-steps",
        type=int,
        default=3_600_000,
        help="steps of the IGMM flat-cost run (issue #3: 3.6 million)",
    )
    parser.add_argument(
        "--no-h3", action="store_true", help="skip the whole-experiment H3 row (~4 min)"
    )
    parser.add_argument(
        "--no-mpc",
        action="store_true",
        help="skip the GP-MPC solve-rate rows (~1 min, + a one-time compile per problem)",
    )
    args = parser.parse_args(argv)
    rows = [bench_task(t, args.repeats) for t in TASKS]
    rows.append(bench_task("porridge_stirring", args.repeats, controller="avic"))
    # issue #4: the PyBullet changing-surface task with the full mode-detection stack
    rows.append(
        bench_task("changing_surface", args.repeats, "avic_modes", sim="pybullet3d", fresh=True)
    )
    print(
        f"{'task':<20}{'controller':<17}{'sim [s]':>8}{'steps':>7}{'wall [ms]':>10}"
        f"{'µs/step':>9}{'× real time':>13}{'target':>8}"
    )
    for r in rows:
        tgt = f"≥{r['target_x_realtime']:.0f}" if r["target_x_realtime"] else ""
        print(
            f"{r['task']:<20}{r['controller']:<17}{r['sim_time_s']:>8.2f}"
            f"{r['control_steps']:>7d}{1e3 * r['median_wall_s']:>10.1f}"
            f"{r['us_per_control_step']:>9.1f}{r['x_realtime']:>13.1f}{tgt:>8}"
        )
    avic = bench_avic_step()
    step = bench_igmm_step()
    long = bench_igmm_long(n_steps=args.long_steps)
    print()
    print(f"{'per-step cost (median)':<58}{'µs':>8}{'target':>10}")
    print(
        f"{'AVIC step: IGMM update + GMR predict + Eq. 4a-4c (loop)':<58}"
        f"{avic['us_per_step_median']:>8.1f}{'≤25':>10}"
    )
    print(
        f"{'IGMM partial_fit(1 point) + GMR predict (synthetic stream)':<58}"
        f"{step['us_per_step']:>8.1f}{'':>10}"
    )
    print(
        f"IGMM over {long['steps']:,} steps: {long['us_first']:.1f} µs (first "
        f"{long['window']:,}) -> {long['us_last']:.1f} µs (last {long['window']:,}), "
        f"ratio {long['ratio']:.2f} (target ≤1.2)"
    )
    print(
        f"  robust: median of the first vs last 10 windows {long['us_first_10_windows']:.1f} -> "
        f"{long['us_last_10_windows']:.1f} µs, ratio {long['ratio_10_windows']:.2f}"
    )
    print(
        f"  model memory {long['model_bytes_start']} -> {long['model_bytes_end']} B; "
        f"tracemalloc net per window {long['tracemalloc_net_bytes_early_window']} -> "
        f"{long['tracemalloc_net_bytes_late_window']} B"
    )
    mpc = None if args.no_mpc else bench_mpc()
    if mpc is not None:
        print_mpc(mpc)
    h3 = None if args.no_h3 else bench_h3()
    if h3 is not None:
        print_h3(h3)
    result = {
        "benchmark": "ccm make bench",
        "repeats": args.repeats,
        "statistic": "median",
        "machine": {"python": platform.python_version(), "processor": platform.machine()},
        "rows": rows,
        "avic_step": avic,
        "igmm_step": step,
        "igmm_long": long,
        "gp_mpc": mpc,
        "h3_long_horizon": h3,
    }
    args.out.write_text(json.dumps(result, indent=2, default=str) + "\n", encoding="utf-8")
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
