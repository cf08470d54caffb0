"""The paper floor (issue #20): how far each sweep of the last ``make reproduce-paper`` is
from the engines' own cost.

For every run directory of the paper run (``<paper_dir>/<sweep>/**/summary.json``) the work
it did comes from its own files, never from typed-in counts (:func:`run_work`):

* **physics steps**: ``run_info.json``'s ``sim_time_s`` / ``sim.dt`` for trial experiments
  (the runner's simulated time, re-timed trials included); for the analyses, trials ×
  duration / ``sim.dt`` from the run's composed config (``.hydra/config.yaml``): H3's
  collection (:func:`ccm.analyses.h3.collection_plan`), ``gp_contact_models``' demonstrations
  (one summary row each, ``gp_contact.duration_s``); ``mpc_convexity`` simulates nothing;
* **resets**: one per trial (each reloads the Panda in PyBullet);
* **mpc**: GP-MPC runs record their solves per trial (``mpc_solves`` in ``summary.json``)
  and the median CPU time of a solve per condition (``run_info.json``'s ``mpc_cpu_rate_hz``);
  solves × median stands for the solver's CPU time;
* **fits**: H3 records the time of its model fits and predictions (``*_train_s``,
  ``*_predict_s``), wall time: an upper bound of their CPU time on a loaded machine.

The engine's cost per physics step and per reset is measured now, in this process, on each
distinct scene of the run's config (:func:`ccm.bench.engines.raw_cpu_per_step`,
:func:`ccm.bench.engines.raw_reset_cpu`; CPU time). A condition that overrides the scene
(stiffer walls, other frictions) and ``gp_contact_models``, which builds its own compliant
wall, are costed on the run's base scene: the raw loop of one pymunk body or one Panda barely
depends on those values. Left out, because they are not the engines' cost: process start,
config composition, metrics, figures and files, and the controllers' own arithmetic.

The floor of a sweep is steps × µs/step + resets × reset + mpc + fits; :func:`print_floor`
sets it beside the sweep's recorded CPU time (``paper_timing.json``). The wall-clock floor on
``cores`` cores is the larger of the total over the cores and the longest single run (a run
is one process).
"""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ccm.core.errors import to_plain
from ccm.core.records import read_json_object


@dataclass(frozen=True)
class RunWork:
    """What one run of a paper sweep asked of the engine, the MPC and the model fits."""

    run: str
    scene: str  #: key of the run's scene (:func:`scene_key`)
    physics_steps: int
    resets: int
    mpc_s: float  #: recorded MPC solve CPU time [s]
    fits_s: float  #: recorded model fit and prediction time (H3; wall time) [s]
    #: the run's CPU seconds per part (``run_info.json``'s ``cpu_s``: plan, trials, figures);
    #: empty for the analyses and for runs recorded before it existed
    cpu_parts: Mapping[str, float] = field(default_factory=dict)


def scene_key(cfg: Mapping[str, Any]) -> str:
    """The simulator, scene and start of a composed config, as a JSON key: runs with the same
    key run the same raw engine loop."""
    task = cfg["task"]
    parts = {k: task.get(k) for k in ("name", "scene", "start", "orientation")}
    return json.dumps({"sim": cfg["sim"], **parts}, sort_keys=True, default=str)


def run_work(run_dir: Path) -> RunWork:
    """The :class:`RunWork` of one run directory, from its ``.hydra/config.yaml``,
    ``summary.json`` and ``run_info.json`` (module docstring)."""
    from omegaconf import OmegaConf

    cfg = OmegaConf.load(run_dir / ".hydra" / "config.yaml")
    plain = to_plain(cfg)
    summary = json.loads((run_dir / "summary.json").read_text(encoding="utf-8"))
    info = json.loads((run_dir / "run_info.json").read_text(encoding="utf-8"))
    dt = float(plain["sim"]["dt"])
    kind = plain["experiment"].get("kind", "trials")
    trials, fits = summary.get("trials", []), 0.0
    if kind == "trials":
        steps, resets = round(float(info["sim_time_s"]) / dt), len(trials)
    elif kind == "h3":
        from ccm.analyses.h3 import collection_plan
        from ccm.tasks.task import load_task

        control_dt = dt * int(plain["sim"]["control_decimation"])
        n, seconds = collection_plan(cfg, load_task(cfg.task, control_dt).duration)
        steps, resets = n * round(seconds / dt), n
        fits = sum(v for k, v in info.items() if k.endswith(("_train_s", "_predict_s")))
    elif kind == "gp_contact_models":
        steps = len(trials) * round(float(plain["gp_contact"]["duration_s"]) / dt)
        resets = len(trials)
    else:  # mpc_convexity: solves alone, no simulation
        steps, resets = 0, 0
    parts = {k: float(v) for k, v in (info.get("cpu_s") or {}).items()}
    mpc = _mpc_s(summary, info)
    return RunWork(run_dir.name, scene_key(plain), steps, resets, mpc, fits, parts)


def _mpc_s(summary: Mapping[str, Any], info: Mapping[str, Any]) -> float:
    """Σ over trials of ``mpc_solves`` × the condition's median CPU time per solve."""
    rate = info.get("mpc_cpu_rate_hz") or {}
    return sum(
        float(tr.get("mpc_solves") or 0.0) / float(rate[tr["condition"]])
        for tr in summary.get("trials", [])
        if tr.get("condition") in rate
    )


def sweep_runs(paper_dir: Path, sweep: str) -> list[Path]:
    """The run directories of ``sweep`` in the paper run (those with a ``summary.json``)."""
    return sorted(p.parent for p in (paper_dir / sweep).glob("**/summary.json"))


def floor_rows(
    work: Mapping[str, Sequence[RunWork]],
    costs: Mapping[str, tuple[float, float]],
    cpu_s: Mapping[str, float],
) -> list[dict[str, Any]]:
    """Per sweep: steps, resets, the floor's parts (engine, reset, MPC solves, model fits)
    and their sum [s], the recorded CPU seconds and their ratio. ``costs``: scene key ->
    (CPU s per physics step, CPU s per reset), for every scene a run simulates in; ``cpu_s``:
    the sweeps' recorded CPU seconds (paper_timing.json)."""
    rows = []
    for sweep, runs in work.items():
        per_run = [_run_floor(w, costs[w.scene] if w.physics_steps else (0.0, 0.0)) for w in runs]
        floor = sum(sum(f) for f in per_run)
        measured = cpu_s.get(sweep)
        rows.append({
            "sweep": sweep,
            "runs": len(runs),
            "physics_steps": sum(w.physics_steps for w in runs),
            "resets": sum(w.resets for w in runs),
            "engine_s": sum(f[0] for f in per_run),
            "reset_s": sum(f[1] for f in per_run),
            "mpc_s": sum(f[2] for f in per_run),
            "fits_s": sum(f[3] for f in per_run),
            "floor_s": floor,
            "longest_run_floor_s": max((sum(f) for f in per_run), default=0.0),
            "measured_cpu_s": measured,
            "ratio": measured / floor if measured is not None and floor > 0 else None,
            "cpu_parts_s": _parts(runs),
        })  # fmt: skip
    return rows


def _parts(runs: Sequence[RunWork]) -> dict[str, float]:
    """Σ over the runs that recorded them of their CPU seconds per part, and how many did."""
    out: dict[str, float] = {"runs": float(sum(1 for w in runs if w.cpu_parts))}
    for w in runs:
        for k, v in w.cpu_parts.items():
            out[k] = out.get(k, 0.0) + v
    return out


def _run_floor(w: RunWork, cost: tuple[float, float]) -> tuple[float, float, float, float]:
    step_s, reset_s = cost
    return w.physics_steps * step_s, w.resets * reset_s, w.mpc_s, w.fits_s


#: issue #20: ``make reproduce-paper`` in at most 20 min wall on 2 cores
TARGET_WALL_S = 20 * 60.0


def totals(
    rows: Sequence[dict[str, Any]],
    cores: int,
    target_wall_s: float = TARGET_WALL_S,
    figures_after_s: float = 0.0,
) -> dict[str, Any]:
    """The whole paper's floor, its engine-only part (engine + resets) and the recorded CPU
    time [s]; the wall-clock floor on ``cores`` cores: max(floor / cores, the longest run's
    floor). The budget: ``target_wall_s`` on ``cores`` cores is at most target × cores CPU
    seconds, of which what the floor leaves is all ccm may spend on its own work (process
    start, configs, controllers, recording, metrics, figures), also per physics step.
    ``figures_after_s``: the CPU of the figures ``ccm paper`` drew after the sweeps
    (``paper_timing.json``'s ``figures_cpu_s``), counted in the measured time and its parts."""
    floor = sum(r["floor_s"] for r in rows)
    measured = sum(r["measured_cpu_s"] or 0.0 for r in rows) + figures_after_s
    longest = max((r["longest_run_floor_s"] for r in rows), default=0.0)
    steps = sum(r["physics_steps"] for r in rows)
    budget = target_wall_s * cores
    parts: dict[str, float] = {}
    for r in rows:
        for k, v in r.get("cpu_parts_s", {}).items():
            parts[k] = parts.get(k, 0.0) + v
    if figures_after_s:
        parts["figures"] = parts.get("figures", 0.0) + figures_after_s
    return {
        "target_wall_s": target_wall_s,
        "budget_cpu_s": budget,
        "own_budget_s": budget - floor,
        "own_budget_us_per_step": 1e6 * (budget - floor) / steps if steps else None,
        "own_measured_s": measured - floor,
        "own_measured_us_per_step": 1e6 * (measured - floor) / steps if steps else None,
        "cpu_parts_s": parts,
        "floor_cpu_s": floor,
        "engines_cpu_s": sum(r["engine_s"] + r["reset_s"] for r in rows),
        "mpc_cpu_s": sum(r["mpc_s"] for r in rows),
        "fits_s": sum(r["fits_s"] for r in rows),
        "measured_cpu_s": measured,
        "ratio": measured / floor if floor > 0 else None,
        "cores": cores,
        "wall_floor_s": max(floor / cores, longest),
        "longest_run_floor_s": longest,
    }


def scene_costs(configs: Mapping[str, Path], budget_s: float = 1.5) -> dict[str, dict[str, Any]]:
    """Per scene key: the raw engine loop's CPU seconds per physics step and per reset,
    measured now on the simulator and pattern built from the run config ``configs[key]``
    (``.hydra/config.yaml``), about ``budget_s`` CPU seconds each."""
    from omegaconf import OmegaConf

    from ccm.bench.engines import raw_cpu_per_step, raw_reset_cpu
    from ccm.experiment.components import build_sim_task

    out = {}
    for key, path in configs.items():
        sim, task = build_sim_task(OmegaConf.load(path))  # the run's controller is not needed
        try:
            step_s = raw_cpu_per_step(sim, task.pattern, budget_s)
            out[key] = {"task": json.loads(key)["name"], "sim": json.loads(key)["sim"]["name"],
                        "step_s": step_s, "reset_s": raw_reset_cpu(sim)}  # fmt: skip
        finally:
            sim.close()
    return out


def paper_floor(paper_dir: Path, cores: int = 2, budget_s: float = 1.5) -> dict[str, Any] | None:
    """The paper-floor table of the run in ``paper_dir`` (module docstring), or None without
    its ``paper_timing.json``."""
    timing = read_json_object(paper_dir / "paper_timing.json")
    if timing is None:
        return None
    cpu_s = timing.get("sweeps_cpu_s") or {}
    work: dict[str, list[RunWork]] = {}
    configs: dict[str, Path] = {}
    for sweep in timing.get("sweeps_s") or {}:
        for run in sweep_runs(paper_dir, sweep):
            w = run_work(run)
            work.setdefault(sweep, []).append(w)
            if w.physics_steps:
                configs.setdefault(w.scene, run / ".hydra" / "config.yaml")
    scenes = scene_costs(configs, budget_s)
    costs = {k: (v["step_s"], v["reset_s"]) for k, v in scenes.items()}
    rows = floor_rows(work, costs, cpu_s)
    for r in rows:
        r["scenes"] = sorted({scenes[w.scene]["task"] for w in work[r["sweep"]] if w.physics_steps})
    return {
        "paper_dir": str(paper_dir),
        "quick": timing.get("quick"),
        "measured_wall_s": timing.get("wall_s"),
        "scenes": list(scenes.values()),
        "rows": sorted(rows, key=lambda r: -(r["measured_cpu_s"] or 0.0)),
        "total": totals(rows, cores, figures_after_s=float(timing.get("figures_cpu_s") or 0.0)),
    }


def print_floor(res: dict[str, Any] | None, paper_dir: Path) -> None:
    """The paper-floor table: per sweep, the floor's parts [CPU min], the recorded CPU
    minutes and measured / floor; then the whole paper and its wall-clock floor."""
    if res is None:
        print(f"\nno {paper_dir / 'paper_timing.json'}: run make reproduce-paper for the floor")
        return
    quick = " (--quick)" if res["quick"] else ""
    print(f"\npaper floor{quick}: the engines' own cost of the work {paper_dir} recorded "
          "(raw loops timed now, CPU)")  # fmt: skip
    for s in res["scenes"]:
        reset = f", reset {1e3 * s['reset_s']:.0f} ms" if s["reset_s"] else ""
        print(f"  raw {s['sim']} {s['task']}: {1e6 * s['step_s']:.1f} µs/physics step{reset}")
    cols = ("engine", "reset", "mpc", "fits", "floor")
    print(f"{'sweep':<22}{'runs':>5}{'steps [M]':>10}" + "".join(f"{c:>7}" for c in cols)
          + f"{'measured':>9}{'meas/floor':>11}   [CPU min]")  # fmt: skip
    for r in res["rows"]:
        m = r["measured_cpu_s"]
        print(
            f"{r['sweep']:<22}{r['runs']:>5}{r['physics_steps'] / 1e6:>10.2f}"
            + "".join(f"{r[c + '_s'] / 60:>7.2f}" for c in cols)
            + f"{_num(m and m / 60, '.1f'):>9}{_num(r['ratio'], '.1f'):>11}"
        )
    t = res["total"]
    steps = sum(r["physics_steps"] for r in res["rows"]) / 1e6
    print(
        f"{'total':<22}{'':>5}{steps:>10.2f}{'':>28}{t['floor_cpu_s'] / 60:>7.2f}"
        f"{t['measured_cpu_s'] / 60:>9.1f}{_num(t['ratio'], '.1f'):>11}"
    )
    wall = res["measured_wall_s"]
    print(
        f"floor of the whole paper: {t['floor_cpu_s'] / 60:.1f} CPU-min (engines "
        f"{t['engines_cpu_s'] / 60:.1f}, MPC solves {t['mpc_cpu_s'] / 60:.1f}, H3 fits "
        f"{t['fits_s'] / 60:.1f} as wall time); wall-clock floor on {t['cores']} cores "
        f"{t['wall_floor_s'] / 60:.1f} min (max of CPU / cores and the longest run, "
        f"{t['longest_run_floor_s'] / 60:.1f} min)"
        + ("" if wall is None else f"; that run took {wall / 60:.1f} min wall")
    )
    _print_budget(t, steps)


def _print_budget(t: Mapping[str, Any], steps_m: float) -> None:
    """The target's CPU budget beside the floor, and where the run's own CPU went."""
    print(
        f"issue #20's {t['target_wall_s'] / 60:.0f} min on {t['cores']} cores = "
        f"{t['budget_cpu_s'] / 60:.1f} CPU-min: the floor leaves {t['own_budget_s'] / 60:.1f} "
        f"CPU-min for ccm's own work, {_num(t['own_budget_us_per_step'], '.0f')} µs per "
        f"physics step of the {steps_m:.2f} M; this run spent {t['own_measured_s'] / 60:.1f} "
        f"({_num(t['own_measured_us_per_step'], '.0f')} µs per step)"
    )
    parts = dict(t["cpu_parts_s"])
    n = int(parts.pop("runs", 0))
    if n:
        print(
            f"  its trial runs' CPU by part ({n} runs' run_info.json cpu_s): "
            + ", ".join(f"{k} {v / 60:.1f}" for k, v in parts.items())
            + " CPU-min"
        )


def _num(x: float | None, spec: str) -> str:
    return "—" if x is None else format(x, spec)
