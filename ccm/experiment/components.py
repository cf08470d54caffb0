"""From a composed config to the objects of a run: conditions, phases and components.

A condition is a list of Hydra overrides applied on top of the run's own overrides (e.g.
``[controller=fixed_impedance_high]``), so every condition is a fully composed config; each
becomes a :class:`Components` (simulator, task, controller). Learned state: with
``init_from=<run dir>`` each condition's controller is built from the config as usual and then
loads ``<run dir>/state/<condition>.json`` before its first trial (format in
:mod:`ccm.experiment.learned_state`).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from omegaconf import DictConfig, OmegaConf

from ccm.control.base import Controller
from ccm.control.registry import make_controller
from ccm.core.errors import (
    ConfigError,
    check_bool,
    check_file_name,
    check_int_nonneg,
    check_int_positive,
    check_nonneg,
    check_positive,
    to_plain,
)
from ccm.core.timeseries import FLOAT32_BITS, check_bits, check_mode
from ccm.experiment.learned_state import load_states, save_states
from ccm.plots import animate
from ccm.sim import BACKENDS, backend, make_sim, sim_class
from ccm.sim.base import Simulator
from ccm.tasks.task import Task, load_task

#: compose(extra_overrides) -> config; provided by the CLI (Hydra compose API)
ComposeFn = Callable[[Sequence[str]], DictConfig]


#: the experiment.kind values that name an analysis (:data:`ccm.analyses.dispatch.ANALYSES`),
#: not the condition × phase × trial loop this module runs
ANALYSIS_KINDS = (
    "h3", "mpc_convexity", "gp_contact_models", "forward_model_horizon", "mpc_table2",
)  # fmt: skip


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
        # named after the controller: its preset's name where it has one, else its type
        ctrl = cfg.controller
        name = ctrl.get("name") or ctrl.get("type") or ctrl.get("_target_") or "default"
        return [Condition(name=str(name).rpartition(".")[2].rpartition(":")[2], cfg=cfg,
                          overrides=[])]  # fmt: skip
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
    sim, task = build_sim_task(cfg)
    controller = make_controller(to_plain(cfg.controller))
    controller.reset(task.dim, sim.control_dt)  # validates dimension-dependent gains
    return Components(sim=sim, task=task, controller=controller)


def build_sim_task(cfg: DictConfig) -> tuple[Simulator, Task]:
    """The simulator and the task of one composed config (no controller: e.g. to time the
    raw engine loop on a run's scene, whatever controller schema that run had)."""
    start = list(to_plain(cfg.task.get("start")) or [])
    orientation = to_plain(cfg.task.get("orientation"))
    if orientation and cfg.task.get("dim") == 3:  # the 3D start pose includes the tool's quaternion
        start += list(orientation)
    # before the scene is parsed: a 2-D scene read as a 3-D one fails on an "unknown key"
    check_dims(cfg.task.get("dim"), sim_class(to_plain(cfg.sim)).dim, cfg)
    sim = make_sim(to_plain(cfg.sim), to_plain(cfg.task.get("scene", {})), start)
    task = load_task(cfg.task, sim.control_dt)
    check_dims(task.dim, sim.dim, cfg)
    return sim, task


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
