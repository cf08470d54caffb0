"""Experiment runner: conditions × trials, seeded; writes the run directory.

A condition is a list of Hydra overrides applied on top of the run's own overrides (e.g.
``[controller=fixed_impedance_high]``), so every condition is a fully composed config.
The runner never changes the working directory; ``summary.json`` is written last.
"""

from __future__ import annotations

import gc
import math
import re
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from omegaconf import DictConfig, OmegaConf

from ccm.control.base import Controller
from ccm.control.registry import make_controller
from ccm.errors import (
    ConfigError,
    SimulationDiverged,
    check_int_positive,
    check_nonneg,
    check_positive,
)
from ccm.metrics import aggregate, check_extra_metrics, compute_extra_metrics, trial_metrics
from ccm.records import TrialRecorder, write_json_atomic
from ccm.sim import make_sim
from ccm.sim.base import Simulator, check_state_finite
from ccm.tasks.task import Task, load_task
from ccm.types import Observation, StepInfo

#: compose(extra_overrides) -> config; provided by the CLI (Hydra compose API)
ComposeFn = Callable[[Sequence[str]], DictConfig]

_NAME_RE = re.compile(r"^[A-Za-z0-9_.\-]+$")


@dataclass
class Condition:
    """One experimental condition: a name, its overrides and its fully composed config."""

    name: str
    cfg: DictConfig
    overrides: list[str]


@dataclass
class Phase:
    """A block of trials within a condition, e.g. ``train`` then ``test`` (seed A §4.1).

    The controller (and what it has learned) carries over from phase to phase; the phase's
    overrides rebuild the simulator and task (e.g. a different viscosity ramp).
    """

    name: str
    trials: int
    overrides: list[str]


@dataclass
class Components:
    """Validated objects built from one condition's config."""

    sim: Simulator
    task: Task
    controller: Controller


def plain(node: Any) -> Any:
    """OmegaConf node -> plain Python containers (interpolations resolved)."""
    if isinstance(node, DictConfig) or OmegaConf.is_config(node):
        return OmegaConf.to_container(node, resolve=True)
    return node


def resolve_conditions(cfg: DictConfig, compose: ComposeFn) -> list[Condition]:
    """Expand ``experiment.conditions`` into composed configs (or the run config alone)."""
    spec = cfg.experiment.get("conditions") or {}
    if not spec:
        return [Condition(name=str(cfg.controller.get("type", "default")), cfg=cfg, overrides=[])]
    out = []
    for name, overrides in plain(spec).items():
        key = f"experiment.conditions.{name}"
        if not _NAME_RE.match(str(name)):
            raise ConfigError(key, "condition names may use letters, digits, '_', '-', '.'")
        if not isinstance(overrides, list) or not all(isinstance(o, str) for o in overrides):
            raise ConfigError(key, "must be a list of override strings, e.g. [controller=x]")
        out.append(Condition(name=str(name), cfg=compose(list(overrides)), overrides=overrides))
    return out


def resolve_phases(cfg: DictConfig, trials: int) -> list[Phase]:
    """``experiment.phases`` (list of {name, trials, overrides}) or one phase of ``trials``."""
    spec = plain(cfg.experiment.get("phases")) or []
    if not spec:
        return [Phase(name="main", trials=trials, overrides=[])]
    if not isinstance(spec, list):
        raise ConfigError("experiment.phases", "must be a list of {name, trials, overrides}")
    phases = []
    for i, ph in enumerate(spec):
        key = f"experiment.phases[{i}]"
        if not isinstance(ph, dict) or set(ph) - {"name", "trials", "overrides"}:
            raise ConfigError(key, "must be a mapping with keys name, trials, overrides")
        name = str(ph.get("name", f"phase{i}"))
        if not _NAME_RE.match(name):
            raise ConfigError(f"{key}.name", "may use letters, digits, '_', '-', '.'")
        overrides = ph.get("overrides") or []
        if not isinstance(overrides, list) or not all(isinstance(o, str) for o in overrides):
            raise ConfigError(f"{key}.overrides", "must be a list of override strings")
        n = check_int_positive(f"{key}.trials", ph.get("trials", 1))
        phases.append(Phase(name=name, trials=n, overrides=overrides))
    return phases


def plan_experiment(
    cfg: DictConfig, compose: ComposeFn, trials: int
) -> list[tuple[Condition, list[tuple[Phase, Components]]]]:
    """Compose and build every condition × phase up front, so bad input fails before a run."""
    plan = []
    phases = resolve_phases(cfg, trials)
    for cond in resolve_conditions(cfg, compose):
        built = []
        for ph in phases:
            pcfg = compose([*cond.overrides, *ph.overrides]) if ph.overrides else cond.cfg
            built.append((ph, build_components(pcfg)))
        plan.append((cond, built))
    return plan


def build_components(cfg: DictConfig) -> Components:
    """Build and validate simulator, task and controller from one composed config."""
    start = list(plain(cfg.task.get("start")) or [])
    orientation = plain(cfg.task.get("orientation"))
    if orientation and cfg.task.get("dim") == 3:  # the 3D start pose includes the tool's quaternion
        start += list(orientation)
    sim = make_sim(plain(cfg.sim), plain(cfg.task.get("scene", {})), start)
    task = load_task(cfg.task, sim.control_dt)
    if task.dim != sim.dim:
        raise ConfigError("task.dim", f"task is {task.dim}-D but sim={cfg.sim.name} is {sim.dim}-D")
    controller = make_controller(plain(cfg.controller))
    controller.reset(task.dim, sim.control_dt)  # validates dimension-dependent gains
    return Components(sim=sim, task=task, controller=controller)


def trial_seed(seed: int, trial: int) -> int:
    """Seed for trial ``trial``; the same for every condition (paired comparisons)."""
    return int(np.random.SeedSequence(entropy=seed, spawn_key=(trial,)).generate_state(1)[0])


def check_experiment(cfg: DictConfig) -> dict[str, Any]:
    """Validate the ``experiment`` and ``metrics`` groups; return the settings the loop uses."""
    exp = cfg.experiment
    fast = bool(exp.get("fast", False))
    trials = check_int_positive("experiment.trials", exp.get("trials", 1))
    max_time = exp.get("max_time_s")
    if max_time is not None:
        max_time = check_positive("experiment.max_time_s", max_time)
    if fast:
        trials = min(
            trials, check_int_positive("experiment.fast_trials", exp.get("fast_trials", 1))
        )
        fast_time = check_positive("experiment.fast_time_s", exp.get("fast_time_s", 0.5))
        max_time = fast_time if max_time is None else min(max_time, fast_time)
    if not isinstance(cfg.get("seed"), int) or isinstance(cfg.get("seed"), bool):
        raise ConfigError("seed", f"must be an integer, got {cfg.get('seed')!r}")
    return {
        "trials": trials,
        "max_time_s": max_time,
        "settle_time_s": check_nonneg("experiment.settle_time_s", exp.get("settle_time_s", 0.5)),
        "lowpass_hz": check_positive("metrics.lowpass_hz", cfg.metrics.lowpass_hz),
        "completion_tol_m": check_positive(
            "metrics.completion_tol_m", cfg.metrics.completion_tol_m
        ),
        "figures": bool(exp.get("figures", True)),
        "fast": fast,
    }


def run_trial(
    comp: Components,
    seed: int,
    duration_s: float,
    progress: Callable[[int], None] | None = None,
) -> TrialRecorder:
    """Run one trial: sample P, control, step the simulator, record. Raises on divergence."""
    obs, info = comp.sim.reset(seed=seed)
    comp.controller.reset(comp.task.dim, comp.sim.control_dt)
    planned = comp.task.pattern
    pattern = comp.controller.prepare(planned, comp.task.contacts, np.random.default_rng(seed))
    duration_s += pattern.duration - planned.duration  # a re-timed pattern may take longer
    n_steps = max(1, int(math.floor(duration_s / comp.sim.control_dt + 1e-9)))
    # The loop allocates many small acyclic objects that the recorder keeps; the cyclic
    # garbage collector would rescan them ever more often, so it is paused for the trial.
    gc_was_enabled = gc.isenabled()
    gc.disable()
    try:
        return _closed_loop(comp, pattern, obs, info, n_steps, progress)
    finally:
        if gc_was_enabled:
            gc.enable()


def _closed_loop(
    comp: Components,
    pattern: Any,
    obs: Observation,
    info: StepInfo,
    n_steps: int,
    progress: Callable[[int], None] | None,
) -> TrialRecorder:
    """The per-step loop of :func:`run_trial`."""
    sim, ctrl = comp.sim, comp.controller
    max_speed = float(getattr(sim, "max_speed", math.inf))
    tick = max(1, n_steps // 100)
    rec = TrialRecorder(comp.task.dim, list(ctrl.signals()), sorted(info.extra))
    for k in range(n_steps):
        target = pattern.sample(obs.t)
        cmd = ctrl.step(obs, target)
        rec.record(obs, target, cmd, info, ctrl.signals())
        obs, info = sim.step(cmd)
        reason = check_state_finite(obs, max_speed)
        if reason is not None:
            raise SimulationDiverged(reason)
        if progress is not None and (k + 1) % tick == 0:
            progress(tick)
    return rec


def run_experiment(
    cfg: DictConfig,
    compose: ComposeFn,
    out_dir: Path,
    show_progress: bool = True,
) -> dict[str, Any]:
    """Run every condition × phase × trial of ``cfg.experiment``; write the run directory.

    The controller of a condition is built once and carries its learned state through all
    of the condition's phases and trials (``end_trial`` after each). ``conditions.<name>``
    in the summary averages the trials of the *last* phase; every trial is in ``trials``.
    Returns the summary dict (also written to ``out_dir/summary.json`` last).
    """
    settings = check_experiment(cfg)
    plan = plan_experiment(cfg, compose, settings["trials"])
    extra = check_extra_metrics(cfg)

    def n_trials(ph: Phase) -> int:
        return min(ph.trials, settings["trials"]) if settings["fast"] else ph.trials

    def duration(comp: Components) -> float:
        d = comp.task.pattern.duration + settings["settle_time_s"]
        return d if settings["max_time_s"] is None else min(d, settings["max_time_s"])

    total_steps = sum(
        int(duration(comp) / comp.sim.control_dt) * n_trials(ph)
        for _, phases in plan
        for ph, comp in phases
    )
    bar = _progress_bar(total_steps, cfg.experiment.name, show_progress)
    trials_out: list[dict[str, Any]] = []
    logs: dict[str, list[dict[str, np.ndarray]]] = {}
    wall0 = time.perf_counter()
    sim_time = 0.0
    try:
        for cond, phases in plan:
            controller = phases[0][1].controller
            trial = 0
            for ph, comp in phases:
                comp = Components(sim=comp.sim, task=comp.task, controller=controller)
                for _ in range(n_trials(ph)):
                    trial += 1
                    seed = trial_seed(int(cfg.seed), trial)
                    rec = run_trial(comp, seed, duration(comp), bar.update if bar else None)
                    sim_time += duration(comp)
                    rec.write_csv(out_dir / "timeseries" / cond.name / f"trial_{trial:03d}.csv")
                    arrays = rec.arrays()
                    metrics = trial_metrics(
                        arrays,
                        comp.task.dim,
                        comp.sim.control_dt,
                        comp.task.pattern.duration,
                        settings["lowpass_hz"],
                        settings["completion_tol_m"],
                    )
                    metrics.update(compute_extra_metrics(extra, arrays, comp, cfg))
                    trials_out.append(
                        {
                            "condition": cond.name,
                            "phase": ph.name,
                            "trial": trial,
                            "seed": seed,
                            **metrics,
                        }
                    )
                    kept = logs.setdefault(cond.name, [])
                    kept[1:] = []  # keep the first and the latest trial's log for figures
                    kept.append(arrays)
                    controller.end_trial()
                comp.sim.close()
    finally:
        if bar is not None:
            bar.close()
    wall = time.perf_counter() - wall0
    last_phase = {cond.name: phases[-1][0].name for cond, phases in plan}
    if settings["figures"]:
        from ccm.plots import write_figures

        write_figures(
            out_dir / "figures",
            {cond.name: phases[-1][1] for cond, phases in plan},
            logs,
            settings,
            trials_out,
        )
    summary = {
        "experiment": str(cfg.experiment.name),
        "status": "ok",
        "seed": int(cfg.seed),
        "conditions": {
            name: aggregate(
                [
                    {k: v for k, v in t.items() if k not in _TRIAL_KEYS}
                    for t in trials_out
                    if t["condition"] == name and t["phase"] == phase
                ]
            )
            for name, phase in last_phase.items()
        },
        "trials": trials_out,
    }
    # wall-clock facts vary run to run, so they live outside summary.json (determinism)
    write_json_atomic(
        out_dir / "run_info.json",
        {"wall_time_s": wall, "sim_time_s": sim_time, "realtime_factor": sim_time / wall},
    )
    write_json_atomic(out_dir / "summary.json", summary)
    return summary


_TRIAL_KEYS = ("condition", "phase", "trial", "seed")


def failed_summary(cfg: DictConfig | None, error: str) -> dict[str, Any]:
    """The summary.json of a failed run (DESIGN.md contract)."""
    name = None
    seed = None
    if cfg is not None:
        name = OmegaConf.select(cfg, "experiment.name", default=None)
        seed = OmegaConf.select(cfg, "seed", default=None)
    return {"experiment": name, "status": "failed", "seed": seed, "error": error}


def _progress_bar(total: int, desc: str, show: bool) -> Any:
    """A tqdm bar that appears only if the run lasts more than ~2 s."""
    if not show:
        return None
    from tqdm import tqdm

    return tqdm(total=total, desc=desc, unit="step", delay=2.0, mininterval=0.5, leave=False)
