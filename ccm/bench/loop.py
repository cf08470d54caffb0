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

from ccm.bench.components import components as _components
from ccm.bench.dynamics import bench_torques
from ccm.core.records import read_json_object

TASKS = ("smoke", "multi_spring", "porridge_stirring", "slide_surfaces_2d")
#: × real time targets per (task, controller): issue #20 (multi_spring; issue #2 had 50 for
#: fixed impedance) and issue #4 (changing_surface)
TARGETS = {
    ("multi_spring", "fixed_impedance"): 80.0,
    ("multi_spring", "avic"): 50.0,
    ("changing_surface", "avic_modes"): 5.0,
}


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
        "target_us": 15.0,  # issue #20 (issue #3: 25)
    }


def bench_task(
    task: str,
    repeats: int,
    controller: str = "fixed_impedance",
    sim: str | None = None,
    fresh: bool = False,
) -> dict[str, Any]:
    """Median timing of one trial of ``task`` with ``controller`` (see the module docstring),
    each trial followed by the engine's raw loop for as many control steps on the same
    simulator (:func:`ccm.bench.engines.raw_loop`); ``ratio_vs_raw`` is the median over the
    repeats of ccm's wall time over the raw loop's. ``ceiling_x_realtime``: the × real time of
    the raw loop plus ccm's per-step interface alone (:mod:`ccm.bench.interface`, timed after
    the raw loop in each repeat; the median over the repeats), the most any control law
    behind that interface can reach on this scene."""
    from ccm.bench.engines import raw_loop
    from ccm.bench.interface import interface_cost
    from ccm.experiment.trial import run_trial

    comp = _components(task, controller, sim)
    sim_time = comp.task.pattern.duration
    walls, raws, ifaces, objects = [], [], [], []
    for r in range(repeats):
        if fresh and r > 0:
            comp.sim.close()
            comp = _components(task, controller, sim)
        t0 = time.perf_counter()
        rec = run_trial(comp, seed=r, duration_s=sim_time)
        walls.append(time.perf_counter() - t0)
        raws.append(raw_loop(comp.sim, comp.task.pattern, len(rec), seed=r))
        ifaces.append(interface_cost(comp.sim, comp.controller, len(rec), repeats=1))
        objects.append(interface_cost(comp.sim, comp.controller, len(rec), 1, record=False))
    comp.sim.close()
    steps = len(rec)
    wall, raw, interface = (statistics.median(x) for x in (walls, raws, ifaces))
    return {
        "raw_us_per_control_step": 1e6 * raw / steps,
        "raw_x_realtime": sim_time / raw,
        "ratio_vs_raw": statistics.median(w / r for w, r in zip(walls, raws, strict=True)),
        "interface_us_per_control_step": 1e6 * interface / steps,
        "objects_us_per_control_step": 1e6 * statistics.median(objects) / steps,
        "raw_s_per_repeat": raws,
        "interface_s_per_repeat": ifaces,
        "ceiling_x_realtime": statistics.median(
            sim_time / (r + i) for r, i in zip(raws, ifaces, strict=True)
        ),
        "task": task,
        "controller": controller,
        "sim": sim or "pymunk2d",
        "fresh_controller": fresh,
        "sim_time_s": sim_time,
        "control_steps": steps,
        "median_wall_s": wall,
        "us_per_control_step": 1e6 * wall / steps,
        "x_realtime": sim_time / wall,
        "target_x_realtime": TARGETS.get((task, controller)),
    }


def print_loop_rows(rows: Sequence[dict[str, Any]]) -> None:
    """The loop table: ccm's µs per control step and × real time, the raw engine loop's µs
    per step on the same scene, and the ratio ccm / raw (timed in turn, one process); then
    the µs of ccm's per-step interface alone and the ceiling × real time of raw + interface
    (:mod:`ccm.bench.interface`)."""
    print(
        f"{'task':<23}{'controller':<23}{'sim [s]':>8}{'steps':>7}{'µs/step':>9}"
        f"{'× real time':>12}{'target':>7}{'raw µs':>8}{'ccm/raw':>8}{'iface µs':>9}"
        f"{'obj µs':>7}{'ceiling ×':>10}"
    )
    for r in rows:
        tgt = f"≥{r['target_x_realtime']:.0f}" if r["target_x_realtime"] else ""
        engine = {"pybullet3d": " (PB)", "mujoco3d": " (MJ)"}.get(r.get("sim") or "", "")
        print(
            f"{r['task'] + engine:<23}{r['controller']:<23}{r['sim_time_s']:>8.2f}"
            f"{r['control_steps']:>7d}{r['us_per_control_step']:>9.1f}"
            f"{r['x_realtime']:>12.1f}{tgt:>7}{r['raw_us_per_control_step']:>8.1f}"
            f"{r['ratio_vs_raw']:>8.2f}{r['interface_us_per_control_step']:>9.1f}"
            f"{r['objects_us_per_control_step']:>7.1f}{r['ceiling_x_realtime']:>10.1f}"
        )
    print(
        "iface: ccm's per-step interface alone (target, observation and truth updated in place,"
        " a command made, recorded and assembled); obj: the objects without the recorder;"
        " ceiling: raw + iface, the most a controller behind this interface can reach;"
        " (PB) PyBullet, (MJ) MuJoCo"
    )


def paper_cpu(paper_dir: Path) -> dict[str, Any] | None:
    """Wall and CPU time per experiment of the last ``make reproduce-paper`` into
    ``paper_dir`` (its ``paper_timing.json``; CPU recorded since issue #20), or None."""
    timing = read_json_object(paper_dir / "paper_timing.json")
    if timing is None:
        return None
    return {
        "paper_dir": str(paper_dir),
        "wall_s": timing.get("wall_s"),
        "quick": timing.get("quick"),
        "sweeps_s": timing.get("sweeps_s", {}),
        "sweeps_cpu_s": timing.get("sweeps_cpu_s", {}),
    }


def print_paper_cpu(res: dict[str, Any] | None, paper_dir: Path) -> None:
    """The CPU-minutes table of :func:`paper_cpu`."""
    if res is None:
        print(f"\nno {paper_dir / 'paper_timing.json'}: run make reproduce-paper for CPU-minutes")
        return
    cpu = res["sweeps_cpu_s"]
    quick = " (--quick)" if res["quick"] else ""
    print(f"\nmake reproduce-paper{quick} in {paper_dir}: wall {res['wall_s'] / 60:.1f} min")
    print(f"{'experiment':<24}{'wall [min]':>11}{'CPU [min]':>11}")
    for name, wall in sorted(res["sweeps_s"].items(), key=lambda kv: -kv[1]):
        c = f"{cpu[name] / 60:>11.1f}" if name in cpu else f"{'—':>11}"
        print(f"{name:<24}{wall / 60:>11.1f}{c}")
    if cpu:
        print(f"{'total':<24}{sum(res['sweeps_s'].values()) / 60:>11.1f}"
              f"{sum(cpu.values()) / 60:>11.1f}")  # fmt: skip
    else:
        print("(CPU time not recorded by that run: it predates issue #20)")


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path("bench.json"))
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument(
        "--long-steps", type=int, default=3_600_000,
        help="steps of the IGMM flat-cost run (issue #3: 3.6 million)",
    )  # fmt: skip
    parser.add_argument("--no-loops", action="store_true", help="skip the loop rows")
    parser.add_argument(
        "--no-h3", action="store_true", help="skip the whole-experiment H3 row (~4 min)"
    )
    parser.add_argument(
        "--no-mpc", action="store_true",
        help="skip the GP-MPC solve-rate rows (~1 min, + a one-time compile per problem)",
    )  # fmt: skip
    parser.add_argument(
        "--paper-dir", type=Path, default=Path("outputs/paper"),
        help="the make reproduce-paper output whose paper_timing.json gives CPU-minutes",
    )  # fmt: skip
    parser.add_argument(
        "--no-floor", action="store_true",
        help="skip the paper floor (the raw engine loop on each paper scene, ~1 min)",
    )  # fmt: skip
    return parser


def loop_rows(repeats: int) -> list[dict[str, Any]]:
    """Every loop row: the 2D tasks with fixed impedance, multi_spring (issue #20) and porridge
    with AVIC, (issue #4) the PyBullet changing-surface task with the full mode-detection
    stack, and the PyBullet loop H3 records its 88 trials per seed with (table_wall, fixed
    medium impedance: the largest part of ``make reproduce-paper``); both 3-D rows on
    PyBullet and on MuJoCo (issue #42)."""
    rows = [bench_task(t, repeats) for t in TASKS]
    rows.append(bench_task("multi_spring", repeats, controller="avic"))
    rows.append(bench_task("porridge_stirring", repeats, controller="avic"))
    for sim in ("pybullet3d", "mujoco3d"):  # issue #42: the same rows on both 3-D engines
        rows.append(bench_task("changing_surface", repeats, "avic_modes", sim=sim, fresh=True))
        rows.append(bench_task("table_wall", repeats, "fixed_impedance_medium", sim=sim))
    return rows


def print_torques(res: dict[str, Any]) -> None:
    """The PyBullet torque-law row of :func:`ccm.bench.dynamics.bench_torques`."""
    us = res["us_per_call_median"]
    print(
        f"\nPyBullet torque law per physics step ({res['task']}): "
        + ", ".join(f"sim.dynamics={d} {v:.1f} µs" for d, v in us.items())
    )


def main(argv: list[str] | None = None) -> int:
    """``make bench``: every section, printed as it finishes, then ``--out`` as JSON."""
    from ccm.bench.floor import paper_floor, print_floor
    from ccm.bench.h3 import bench_h3, print_h3
    from ccm.bench.igmm import bench_learning, print_learning
    from ccm.bench.mpc import bench_mpc, print_mpc

    args = _parser().parse_args(argv)
    result: dict[str, Any] = {
        "benchmark": "ccm make bench",
        "repeats": args.repeats,
        "statistic": "median",
        "machine": {"python": platform.python_version(), "processor": platform.machine()},
    }
    if not args.no_loops:
        result["rows"] = loop_rows(args.repeats)
        print_loop_rows(result["rows"])
        result["pybullet_torques"] = bench_torques()
        print_torques(result["pybullet_torques"])
    result["avic_step"] = bench_avic_step()
    result |= bench_learning(args.long_steps)
    print_learning(result["avic_step"], result["igmm_step"], result["igmm_long"])
    result["gp_mpc"] = None if args.no_mpc else bench_mpc()
    if result["gp_mpc"] is not None:
        print_mpc(result["gp_mpc"])
    result["h3_long_horizon"] = None if args.no_h3 else bench_h3()
    if result["h3_long_horizon"] is not None:
        print_h3(result["h3_long_horizon"])
    result["paper"] = paper_cpu(args.paper_dir)
    print_paper_cpu(result["paper"], args.paper_dir)
    result["paper_floor"] = None if args.no_floor else paper_floor(args.paper_dir)
    if not args.no_floor:
        print_floor(result["paper_floor"], args.paper_dir)
    args.out.write_text(json.dumps(result, indent=2, default=str) + "\n", encoding="utf-8")
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
