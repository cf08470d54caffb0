"""Experiment runner: conditions × trials, seeded; writes the run directory.

A condition is a list of Hydra overrides applied on top of the run's own overrides (e.g.
``[controller=fixed_impedance_high]``), so every condition is a fully composed config.
The runner never changes the working directory; ``summary.json`` is written last.

Learned state. At the end of a run, every condition whose controller learns writes
``state/<condition>.json`` (format in :mod:`ccm.experiment.learned_state`). With ``init_from=<run
dir>`` each condition's controller is built from the config as usual and then loads
``<run dir>/state/<condition>.json`` before its first trial (settings stay the config's;
models, beliefs and counters come from the file). Trials are still numbered 1..n within the
run (and seeded accordingly).
"""

from __future__ import annotations

import gc
import math
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from omegaconf import DictConfig, OmegaConf

from ccm.control.base import Controller
from ccm.control.registry import make_controller
from ccm.core.errors import (
    ConfigError,
    SimulationDiverged,
    check_bool,
    check_file_name,
    check_int_nonneg,
    check_int_positive,
    check_nonneg,
    check_positive,
    to_plain,
)
from ccm.core.records import TrialRecorder, write_atomic, write_json_atomic
from ccm.core.timeseries import (
    FLOAT32_BITS,
    check_bits,
    check_mode,
    keep_trial,
    trial_path,
    write_timeseries,
)
from ccm.core.types import Observation, StepInfo
from ccm.experiment.config_check import check_trial_steps, trial_duration
from ccm.experiment.learned_state import load_states, save_states
from ccm.metrics.contacts import contact_table
from ccm.metrics.trial import (
    check_extra_metrics,
    compute_extra_metrics,
    condition_summary,
    trial_metrics,
)
from ccm.plots import animate
from ccm.sim import BACKENDS, backend, make_sim
from ccm.sim.base import Simulator, check_state_finite
from ccm.tasks.task import Task, load_task

#: compose(extra_overrides) -> config; provided by the CLI (Hydra compose API)
ComposeFn = Callable[[Sequence[str]], DictConfig]

#: the experiment.kind values that name an analysis (:data:`ccm.analyses.dispatch.ANALYSES`),
#: not the condition × phase × trial loop this module runs
ANALYSIS_KINDS = ("h3", "mpc_convexity", "gp_contact_models", "forward_model_horizon")


@dataclass
class Condition:
    """One experimental condition: a name, its overrides and its fully composed config."""

    name: str
    cfg: DictConfig
    overrides: list[str]
    prior_trials: int = 0  # trials learned by the state loaded through ``init_from``


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


#: conditions, each with its phases' built components (:func:`plan_experiment`)
Plan = list[tuple[Condition, list[tuple[Phase, Components]]]]


def resolve_conditions(cfg: DictConfig, compose: ComposeFn) -> list[Condition]:
    """Expand ``experiment.conditions`` into composed configs (or the run config alone).

    A condition set to null is left out: an experiment built on another (its defaults list)
    drops an inherited condition so."""
    spec = {
        k: v for k, v in (to_plain(cfg.experiment.get("conditions")) or {}).items() if v is not None
    }
    if not spec:
        return [Condition(name=str(cfg.controller.get("type", "default")), cfg=cfg, overrides=[])]
    out = []
    for name, overrides in spec.items():
        key = f"experiment.conditions.{name}"
        check_file_name(key, str(name))  # a directory of timeseries/
        if not isinstance(overrides, list) or not all(isinstance(o, str) for o in overrides):
            raise ConfigError(key, "must be a list of override strings, e.g. [controller=x]")
        out.append(Condition(name=str(name), cfg=compose(list(overrides)), overrides=overrides))
    return out


def resolve_phases(cfg: DictConfig, trials: int) -> list[Phase]:
    """``experiment.phases`` (list of {name, trials, overrides}) or one phase of ``trials``."""
    spec = to_plain(cfg.experiment.get("phases")) or []
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
        check_file_name(f"{key}.name", name)
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
    for cond in resolve_conditions(cfg, compose):
        try:
            plan.append((cond, _build_condition(cfg, cond, compose, trials)))
        except ConfigError as exc:  # name the condition whose overrides made the bad value
            if not cond.overrides:
                raise
            raise ConfigError(exc.key, f"{exc.problem} (condition {cond.name})") from None
    init_from = OmegaConf.select(cfg, "init_from", default=None)
    if init_from is not None:
        load_state_dicts(init_from, plan)
    return plan


def _build_condition(
    cfg: DictConfig, cond: Condition, compose: ComposeFn, trials: int
) -> list[tuple[Phase, Components]]:
    # a condition may set its own experiment.trials (e.g. a controller that keeps no state
    # across trials and cannot see the noise repeats identical trials: fewer suffice)
    own = cond.cfg.experiment.get("trials", 1) if cond.overrides else None
    if own is not None and own != cfg.experiment.get("trials", 1):
        trials = check_experiment(cond.cfg)["trials"]
    built = []
    for ph in resolve_phases(cond.cfg if cond.overrides else cfg, trials):
        pcfg = compose([*cond.overrides, *ph.overrides]) if ph.overrides else cond.cfg
        built.append((ph, build_components(pcfg)))
    return built


def save_learned_states(out_dir: Path, plan: Plan, trials: dict[str, int]) -> None:
    """Write ``state/<condition>.json`` for every condition whose controller learns."""
    save_states(
        out_dir / "state",
        [(c.name, ph[0][1].controller, c.prior_trials + trials.get(c.name, 0)) for c, ph in plan],
    )


def load_state_dicts(init_from: Any, plan: Plan) -> None:
    """Start each condition's controller from ``<init_from>/state/<condition>.json``."""
    prior = load_states(init_from, [(c.name, ph[0][1].controller) for c, ph in plan])
    for cond, _ in plan:
        cond.prior_trials = prior.get(cond.name, 0)


def build_components(cfg: DictConfig) -> Components:
    """Build and validate simulator, task and controller from one composed config."""
    start = list(to_plain(cfg.task.get("start")) or [])
    orientation = to_plain(cfg.task.get("orientation"))
    if orientation and cfg.task.get("dim") == 3:  # the 3D start pose includes the tool's quaternion
        start += list(orientation)
    # before the scene is parsed: a 2-D scene read as a 3-D one fails on an "unknown key"
    check_dims(cfg.task.get("dim"), backend(cfg.sim.get("name")).dim, cfg)
    sim = make_sim(to_plain(cfg.sim), to_plain(cfg.task.get("scene", {})), start)
    task = load_task(cfg.task, sim.control_dt)
    check_dims(task.dim, sim.dim, cfg)
    controller = make_controller(to_plain(cfg.controller))
    controller.reset(task.dim, sim.control_dt)  # validates dimension-dependent gains
    return Components(sim=sim, task=task, controller=controller)


def check_dims(task_dim: Any, sim_dim: int, cfg: DictConfig) -> None:
    """A task runs only on a simulator of its dimension (``task.dim``)."""
    if task_dim in (2, 3) and task_dim != sim_dim:
        other = next(n for n in BACKENDS if backend(n).dim == task_dim)
        raise ConfigError(
            "task.dim", f"task={cfg.task.get('name')} is a {task_dim}-D task, for sim={other}; "
            f"sim={cfg.sim.get('name')} simulates {sim_dim}-D tasks",
        )  # fmt: skip


def trial_seed(seed: int, trial: int) -> int:
    """Seed for trial ``trial``; the same for every condition (paired comparisons)."""
    return int(np.random.SeedSequence(entropy=seed, spawn_key=(trial,)).generate_state(1)[0])


def check_experiment(cfg: DictConfig) -> dict[str, Any]:
    """Validate the ``experiment`` and ``metrics`` groups; return the settings the loop uses."""
    exp = cfg.experiment
    kind = exp.get("kind", "trials")
    if kind != "trials" and kind not in ANALYSIS_KINDS:
        allowed = ", ".join(("trials", *ANALYSIS_KINDS))
        raise ConfigError("experiment.kind", f"must be one of {allowed}, got {kind!r}")
    fast = check_bool("experiment.fast", exp.get("fast", False))
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
    check_int_nonneg("seed", cfg.get("seed"))  # numpy's SeedSequence takes no negative seed
    check_file_name("experiment.name", exp.get("name"))  # a directory of hydra.run/sweep.dir
    return {
        "trials": trials,
        "max_time_s": max_time,
        "settle_time_s": check_nonneg("experiment.settle_time_s", exp.get("settle_time_s", 0.5)),
        "lowpass_hz": check_positive("metrics.lowpass_hz", cfg.metrics.lowpass_hz),
        "completion_tol_m": check_positive(
            "metrics.completion_tol_m", cfg.metrics.completion_tol_m
        ),
        "figures": check_bool("experiment.figures", exp.get("figures", True)),
        "fast": fast,
        "max_retime_s": check_nonneg("experiment.max_retime_s", exp.get("max_retime_s", 60.0)),
        "timeseries": check_mode(exp.get("timeseries", "first_last")),
        "timeseries_bits": check_bits(exp.get("timeseries_bits", FLOAT32_BITS)),
        "animate": animate.check_config(cfg),  # experiment.animate and the animate block
    }


def run_trial(
    comp: Components,
    seed: int,
    duration_s: float,
    progress: Callable[[int], None] | None = None,
    *,
    max_extension_s: float = math.inf,
    on_step: Callable[[Simulator], None] | None = None,
    expect: Callable[[int], None] | None = None,
) -> TrialRecorder:
    """Run one trial: sample P, control, step the simulator, record. Raises on divergence.

    ``duration_s`` is the trial length for the planned pattern. A controller may re-time it
    (:meth:`Controller.prepare`), also during the trial: the trial then lasts
    ``duration_s`` plus however much longer the re-timed pattern currently is, up to
    ``max_extension_s`` (0 = never longer). The recorder's ``pattern_duration`` is the
    pattern's final duration (for the completion time). ``on_step(sim)``, if given, is called
    once per control step right after the step is recorded (before the simulator steps), e.g. to log
    the joint encoders an offline learner needs (:mod:`ccm.analyses.h3_data`). ``expect(n)``,
    if given, gets the trial's step count once the controller has re-timed the pattern (a
    progress bar's estimate).
    """
    obs, info = comp.sim.reset(seed=seed)
    comp.controller.reset(comp.task.dim, comp.sim.control_dt)
    planned = comp.task.pattern
    pattern = comp.controller.prepare(planned, comp.task.contacts, np.random.default_rng(seed))
    dt = comp.sim.control_dt

    memo = [math.nan, 0]  # (pattern duration, steps): recomputed only when P is re-timed

    def n_steps() -> int:
        if pattern.duration != memo[0]:
            extra = min(max(pattern.duration - planned.duration, 0.0), max_extension_s)
            memo[:] = [pattern.duration, max(1, int(math.floor((duration_s + extra) / dt + 1e-9)))]
        return int(memo[1])

    if expect is not None:
        expect(n_steps())

    # The loop allocates many small acyclic objects that the recorder keeps; the cyclic
    # garbage collector would rescan them ever more often, so it is paused for the trial.
    gc_was_enabled = gc.isenabled()
    gc.disable()
    try:
        rec = _closed_loop(comp, pattern, obs, info, n_steps, progress, on_step)
    finally:
        if gc_was_enabled:
            gc.enable()
    rec.pattern_duration = float(pattern.duration)
    return rec


def _closed_loop(
    comp: Components,
    pattern: Any,
    obs: Observation,
    info: StepInfo,
    n_steps: Callable[[], int],
    progress: Callable[[int], None] | None,
    on_step: Callable[[Simulator], None] | None = None,
) -> TrialRecorder:
    """The per-step loop of :func:`run_trial`; ``n_steps()`` is re-read every step (a
    re-timing controller may change the pattern's duration during the trial)."""
    sim, ctrl = comp.sim, comp.controller
    max_speed = float(getattr(sim, "max_speed", math.inf))
    tick = max(1, n_steps() // 100)
    rec = TrialRecorder(comp.task.dim, list(ctrl.signals()), sorted(info.extra))
    k = -1
    while (k := k + 1) < n_steps():
        target = pattern.sample(obs.t)
        cmd = ctrl.step(obs, target)
        rec.record(obs, target, cmd, info, ctrl.signals())
        if on_step is not None:
            on_step(sim)
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
    finished: list[dict[str, Any]] | None = None,
) -> dict[str, Any]:
    """Run every condition × phase × trial of ``cfg.experiment``; write the run directory.

    The controller of a condition is built once and carries its learned state through all
    of the condition's phases and trials (``end_trial`` after each); at the end it is saved
    to ``state/<condition>.json`` (module docstring; ``init_from`` loads it).
    ``conditions.<name>`` in the summary averages the trials of the *last* phase; every
    trial is in ``trials``.
    Returns the summary dict (also written to ``out_dir/summary.json`` last). Each trial's
    record is appended to ``finished``, if given, as soon as the trial ends (what an
    interrupted run's summary keeps).
    """
    settings = check_experiment(cfg)  # an unknown experiment.kind is refused here
    kind = cfg.experiment.get("kind", "trials")
    if kind != "trials":
        raise ConfigError(
            "experiment.kind", f"{kind!r} is an analysis: ccm.analyses.dispatch.run runs it"
        )
    plan = plan_experiment(cfg, compose, settings["trials"])
    check_trial_steps(plan, settings)
    extra = check_extra_metrics(cfg)

    def n_trials(ph: Phase) -> int:
        return min(ph.trials, settings["trials"]) if settings["fast"] else ph.trials

    def duration(comp: Components) -> float:
        return trial_duration(comp.task.pattern.duration, settings)

    # a truncated trial (max_time_s, fast) is never lengthened by re-timing
    extension = 0.0 if settings["max_time_s"] is not None else settings["max_retime_s"]
    total_steps = sum(
        int(duration(comp) / comp.sim.control_dt) * n_trials(ph)
        for _, phases in plan
        for ph, comp in phases
    )
    bar = _progress_bar(total_steps, cfg.experiment.name, show_progress)
    trials_out: list[dict[str, Any]] = [] if finished is None else finished
    logs: dict[str, list[dict[str, np.ndarray]]] = {}
    wall0 = time.perf_counter()
    sim_time = 0.0
    done: dict[str, int] = {}  # trials run per condition
    planned_left = total_steps  # planned steps of the trials not yet run
    timing = _SolveTiming()
    try:
        for cond, phases in plan:
            controller = phases[0][1].controller
            trial = 0
            for ph, comp in phases:
                comp = Components(sim=comp.sim, task=comp.task, controller=controller)
                for i in range(n_trials(ph)):
                    trial += 1
                    done[cond.name] = trial
                    seed = trial_seed(int(cfg.seed), trial)
                    planned = int(duration(comp) / comp.sim.control_dt)  # before re-timing
                    planned_left -= planned
                    if bar is not None:
                        bar.reserve = planned_left
                    rec = run_trial(
                        comp, seed, duration(comp), bar.advance if bar else None,
                        max_extension_s=extension,
                        expect=bar.trial_steps if bar else None,
                    )  # fmt: skip
                    if bar is not None:  # a re-timed trial: expect the phase's next ones alike
                        later = n_trials(ph) - i - 1
                        bar.expect(bar.n + planned_left + later * (len(rec) - planned))
                    sim_time += len(rec) * comp.sim.control_dt
                    if keep_trial(settings["timeseries"], i, n_trials(ph)):  # experiment.timeseries
                        write_timeseries(
                            trial_path(out_dir, cond.name, trial), rec.arrays(),
                            settings["timeseries_bits"],
                        )  # fmt: skip
                    row = {"condition": cond.name, "phase": ph.name, "trial": trial, "seed": seed}
                    trials_out.append({**row, **_score_trial(rec, comp, settings, extra, cfg)})
                    timing.add(cond.name, comp.controller.report())
                    kept = logs.setdefault(cond.name, [])
                    kept[1:] = []  # keep the first and the latest trial's log for figures
                    kept.append(rec.arrays())
                    controller.end_trial()
                comp.sim.close()
    finally:
        if bar is not None:
            bar.close()
    save_learned_states(out_dir, plan, done)
    info = {"wall_time_s": (wall := time.perf_counter() - wall0), "sim_time_s": sim_time,
            "realtime_factor": sim_time / wall, **timing.info()}  # fmt: skip
    if settings["animate"] == "first_last":  # clips of each condition's first and last trial
        wall0 = time.perf_counter()
        animate.write_animations(out_dir, cfg, plan, logs, trials_out)
        info["animate_wall_s"] = time.perf_counter() - wall0
    return _write_run(cfg, out_dir, plan, logs, settings, trials_out, info)


def _score_trial(
    rec: TrialRecorder, comp: Components, settings: Mapping[str, Any], extra: Sequence[str],
    cfg: DictConfig,
) -> dict[str, Any]:  # fmt: skip
    """The metrics of one recorded trial: the base ones, the pattern's end and the extra
    metrics the experiment names."""
    arrays = rec.arrays()
    metrics = trial_metrics(
        arrays,
        comp.task.dim,
        comp.sim.control_dt,
        rec.pattern_duration,
        settings["lowpass_hz"],
        settings["completion_tol_m"],
    )
    # the (re-timed) pattern's end: "the motion pattern was completed in" (seed A §4.5.1);
    # completion_time_s also asks for the error to settle
    metrics["pattern_time_s"] = rec.pattern_duration
    metrics.update(compute_extra_metrics(extra, arrays, comp, cfg))
    return metrics


class _SolveTiming:
    """Wall time, process CPU time and IPOPT iterations of each MPC solve (GP-MPC), per
    condition, from the controllers' ``report()``; summarised for ``run_info.json``."""

    def __init__(self) -> None:
        self.wall: dict[str, list[float]] = {}
        self.cpu: dict[str, list[float]] = {}
        self.iters: dict[str, list[int]] = {}

    def add(self, name: str, report: Mapping[str, Any] | None) -> None:
        timing = (report or {}).get("timing") or {}
        self.wall.setdefault(name, []).extend(timing.get("mpc_solve_s", []))
        self.cpu.setdefault(name, []).extend(timing.get("mpc_solve_cpu_s", []))
        self.iters.setdefault(name, []).extend(timing.get("mpc_iterations", []))

    def info(self) -> dict[str, Any]:
        """Seed B Table 2's "MPC rate" (median solves per second) from wall and CPU time,
        the median iterations (an active constraint takes more: the rate's context) and the
        cost of one iteration; empty without MPC solves."""
        if not any(self.wall.values()):
            return {}
        solve_s, solve_it = self.wall, self.iters
        return {
            "mpc_rate_hz": {n: 1.0 / float(np.median(v)) for n, v in solve_s.items() if v},
            # from the process's CPU time: what another job on the machine cannot slow
            "mpc_cpu_rate_hz": {
                n: 1.0 / float(np.median(v)) for n, v in self.cpu.items() if v and np.median(v) > 0
            },
            "mpc_iterations_median": {n: float(np.median(v)) for n, v in solve_it.items() if v},
            "mpc_ms_per_iteration": {  # the cost of one iteration, whatever their number
                n: 1e3 * float(np.median([t / i for t, i in zip(solve_s[n], v, strict=True)
                                          if i > 0]))
                for n, v in solve_it.items()
                if any(i > 0 for i in v)
            },
        }  # fmt: skip


def _write_run(
    cfg: DictConfig, out_dir: Path, plan: Plan, logs: Mapping[str, Any],
    settings: Mapping[str, Any], trials_out: list[dict[str, Any]], info: dict[str, Any],
) -> dict[str, Any]:  # fmt: skip
    """Figures, the H4 contact table, ``run_info.json`` (wall-clock facts vary run to run,
    so they live outside the summary) and ``summary.json`` last; returns the summary."""
    if settings["figures"]:
        from ccm.plots.run import write_figures

        write_figures(
            out_dir / "figures",
            {cond.name: phases[-1][1] for cond, phases in plan},
            logs,
            {**settings, "metrics": to_plain(cfg.metrics)},
            trials_out,
        )
    table = contact_table(trials_out)
    if table is not None:  # seed A Table 1 layout (H4 contact learning)
        write_atomic(out_dir / "contact_learning.md", table)
    last_phase = {cond.name: phases[-1][0].name for cond, phases in plan}
    summary = {
        "experiment": str(cfg.experiment.name),
        "status": "ok",
        "seed": int(cfg.seed),
        "task": str(cfg.task.name),
        "conditions": {
            name: condition_summary(
                [
                    {k: v for k, v in t.items() if k not in _TRIAL_KEYS}
                    for t in trials_out
                    if t["condition"] == name and t["phase"] == phase
                ],
                cfg.metrics.get("convergence_trials", 10),
            )
            for name, phase in last_phase.items()
        },
        "trials": trials_out,
    }
    init_from = OmegaConf.select(cfg, "init_from", default=None)
    if init_from is not None:
        summary["init_from"] = str(init_from)  # as given: the same command, the same summary
    write_json_atomic(out_dir / "run_info.json", info)
    write_json_atomic(out_dir / "summary.json", summary)
    return summary


_TRIAL_KEYS = ("condition", "phase", "trial", "seed")


def failed_summary(cfg: DictConfig | None, error: str) -> dict[str, Any]:
    """The summary.json of a failed run (status ``failed`` and the cause)."""
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

    class Bar(tqdm):
        reserve = 0  # steps planned for the trials after the current one

        def advance(self, n: int) -> None:
            """Update by ``n`` steps. A trial that runs past its plan (re-timed) grows the
            total, keeping ``reserve`` steps ahead for the later trials: never past 100 %."""
            if self.total is not None and self.n + n + self.reserve > self.total:
                self.total = self.n + n + self.reserve
            self.update(n)

        def trial_steps(self, n: int) -> None:
            """A trial of ``n`` steps (re-timed) starts: expect it and ``reserve`` more."""
            self.expect(self.n + n + self.reserve)

        def expect(self, total: int) -> None:
            """Set the expected total steps (after a trial: what is left, re-estimated); shown
            at the next update (refreshing now would show the bar before its delay)."""
            self.total = max(self.n, int(total))

    return Bar(total=total, desc=desc, unit="step", delay=2.0, mininterval=0.5, leave=False)
