"""Experiment runner: conditions × phases × trials, seeded; writes the run directory.

The plan and its components are :mod:`ccm.experiment.components`; one trial's loop is
:mod:`ccm.experiment.trial`. The runner never changes the working directory;
``summary.json`` is written after every other record, and the figures after it
(:func:`_draw_figures`). At the end of a run, every condition whose controller
learns writes ``state/<condition>.json`` (format in :mod:`ccm.experiment.learned_state`).
Trials are numbered 1..n within the run (and seeded accordingly), also after ``init_from``.
"""

from __future__ import annotations

import sys
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from omegaconf import DictConfig, OmegaConf

from ccm.core.errors import (
    ConfigError,
    to_plain,
)
from ccm.core.records import TrialRecorder, write_atomic, write_json_atomic
from ccm.core.timeseries import (
    keep_trial,
    trial_path,
    write_timeseries,
)
from ccm.experiment.components import (
    Components,
    ComposeFn,
    Phase,
    Plan,
    check_experiment,
    plan_experiment,
    save_learned_states,
    trial_seed,
)
from ccm.experiment.config_check import check_trial_steps, trial_duration
from ccm.experiment.interrupts import raise_if_interrupted
from ccm.experiment.trial import run_trial
from ccm.metrics.contact_beliefs import contact_table
from ccm.metrics.trial import (
    check_extra_metrics,
    compute_extra_metrics,
    condition_summary,
    trial_metrics,
)
from ccm.plots import animate
from ccm.plots.redraw import PLOT_INPUTS, read_plot_inputs
from ccm.plots.run import figure_inputs, write_figures


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
    Returns the summary dict (also written to ``out_dir/summary.json``, before the figures).
    Each trial's record is appended to ``finished``, if given, as soon as the trial ends
    (what an interrupted run's summary keeps).
    """
    settings = check_experiment(cfg)  # an unknown experiment.kind is refused here
    kind = cfg.experiment.get("kind", "trials")
    if kind != "trials":
        raise ConfigError(
            "experiment.kind", f"{kind!r} is an analysis: ccm.analyses.dispatch.run runs it"
        )
    cpu0 = time.process_time()  # CPU seconds per part of the run: run_info.json's cpu_s
    plan = plan_experiment(cfg, compose, settings["trials"])
    check_trial_steps(plan, settings)
    cpu = {"plan": time.process_time() - cpu0}
    run = _Run(settings, check_extra_metrics(cfg), [] if finished is None else finished)
    total_steps = sum(
        _planned_steps(comp, settings) * _n_trials(ph, settings)
        for _, phases in plan
        for ph, comp in phases
    )
    progress = _Progress(total_steps, cfg.experiment.name, show_progress)
    wall0, cpu0 = time.perf_counter(), time.process_time()
    try:
        for cond, phases in plan:
            _run_condition(cfg, out_dir, cond.name, phases, run, progress)
    finally:
        progress.close()
    cpu["trials"] = time.process_time() - cpu0  # loops, recording, metrics, time series
    cpu["figures"] = 0.0  # drawn after summary.json (_draw_figures), if at all
    save_learned_states(out_dir, plan, run.done)
    info = {"wall_time_s": (wall := time.perf_counter() - wall0), "sim_time_s": run.sim_time,
            "realtime_factor": run.sim_time / wall, "cpu_s": cpu, **run.timing.info()}  # fmt: skip
    if settings["animate"] == "first_last":  # clips of each condition's first and last trial
        wall0 = time.perf_counter()
        animate.write_animations(out_dir, cfg, plan, run.logs, run.trials)
        info["animate_wall_s"] = time.perf_counter() - wall0
    summary = _write_run(cfg, out_dir, plan, settings, run.trials, info)
    if settings["figures"]:
        _draw_figures(out_dir, run.logs, run.trials, info)
    return summary


@dataclass
class _Run:
    """What the trial loop of :func:`run_experiment` collects."""

    settings: Mapping[str, Any]
    extra: Sequence[str]  # the extra metrics experiment.metrics names
    trials: list[dict[str, Any]]  # a record per finished trial
    logs: dict[str, list[dict[str, np.ndarray]]] = field(default_factory=dict)  # figures
    done: dict[str, int] = field(default_factory=dict)  # trials run per condition
    sim_time: float = 0.0
    timing: _SolveTiming = field(default_factory=lambda: _SolveTiming())


def _n_trials(ph: Phase, settings: Mapping[str, Any]) -> int:
    return min(ph.trials, settings["trials"]) if settings["fast"] else ph.trials


def _planned_steps(comp: Components, settings: Mapping[str, Any]) -> int:
    """Control steps of a trial of the planned pattern (before any re-timing)."""
    return int(trial_duration(comp.task.pattern.duration, settings) / comp.sim.control_dt)


def _run_condition(
    cfg: DictConfig,
    out_dir: Path,
    name: str,
    phases: Sequence[tuple[Phase, Components]],
    run: _Run,
    progress: _Progress,
) -> None:
    """Every phase and trial of one condition, with one controller throughout."""
    settings = run.settings
    # a truncated trial (max_time_s, fast) is never lengthened by re-timing
    extension = 0.0 if settings["max_time_s"] is not None else settings["max_retime_s"]
    controller = phases[0][1].controller
    trial = 0
    for ph, comp in phases:
        comp = Components(sim=comp.sim, task=comp.task, controller=controller)
        n = _n_trials(ph, settings)
        for i in range(n):
            trial += 1
            run.done[name] = trial
            seed = trial_seed(int(cfg.seed), trial)
            planned = _planned_steps(comp, settings)
            progress.start_trial(planned)
            rec = run_trial(
                comp, seed, trial_duration(comp.task.pattern.duration, settings),
                progress.advance, max_extension_s=extension, expect=progress.trial_steps,
            )  # fmt: skip
            progress.end_trial(len(rec), planned, later=n - i - 1)
            run.sim_time += len(rec) * comp.sim.control_dt
            if keep_trial(settings["timeseries"], i, n):  # experiment.timeseries
                write_timeseries(
                    trial_path(out_dir, name, trial), rec.arrays(), settings["timeseries_bits"]
                )
            row = {"condition": name, "phase": ph.name, "trial": trial, "seed": seed}
            run.trials.append({**row, **_score_trial(rec, comp, settings, run.extra, cfg)})
            run.timing.add(name, comp.controller.report())
            kept = run.logs.setdefault(name, [])
            kept[1:] = []  # keep the first and the latest trial's log for figures
            kept.append(rec.arrays())
            controller.end_trial()
            raise_if_interrupted()  # a signal a destructor swallowed
        comp.sim.close()


class _Progress:
    """The progress bar's bookkeeping: the planned steps of the trials not yet run, and the
    bar's estimate once a re-timed trial shows how long the phase's next ones will be."""

    def __init__(self, total_steps: int, name: str, show: bool) -> None:
        self.bar = _progress_bar(total_steps, name, show)
        self.left = total_steps  # planned steps of the trials not yet run
        self.advance = self.bar.advance if self.bar is not None else None
        self.trial_steps = self.bar.trial_steps if self.bar is not None else None

    def start_trial(self, planned: int) -> None:
        self.left -= planned
        if self.bar is not None:
            self.bar.reserve = self.left

    def end_trial(self, steps: int, planned: int, later: int) -> None:
        if self.bar is not None:  # a re-timed trial: expect the phase's next ones alike
            self.bar.expect(self.bar.n + self.left + later * (steps - planned))

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()


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
    metrics.update(compute_extra_metrics(extra, arrays, comp, cfg, base=metrics))
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
    cfg: DictConfig, out_dir: Path, plan: Plan, settings: Mapping[str, Any],
    trials_out: list[dict[str, Any]], info: dict[str, Any],
) -> dict[str, Any]:  # fmt: skip
    """The H4 contact table, ``plot_inputs.json`` (what the figures need besides the time
    series: :func:`ccm.plots.run.figure_inputs`), ``run_info.json`` (wall-clock facts vary run
    to run, so they live outside the summary) and ``summary.json`` last; returns the summary."""
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
    inputs = figure_inputs(
        {cond.name: phases[-1][1] for cond, phases in plan}, settings, to_plain(cfg.metrics)
    )
    write_json_atomic(out_dir / PLOT_INPUTS, inputs)
    write_json_atomic(out_dir / "run_info.json", info)
    write_json_atomic(out_dir / "summary.json", summary)
    return summary


def _draw_figures(
    out_dir: Path, logs: Mapping[str, Any], trials: Sequence[Mapping[str, Any]],
    info: dict[str, Any],
) -> None:  # fmt: skip
    """The run's figures, drawn after its numbers are written (issue #40: ``summary.json``
    never waits on a figure). A figure that fails leaves the record whole: one line on
    stderr, ``figures_error`` in ``run_info.json``, and ``ccm plots`` draws them again. Their
    CPU seconds join ``run_info.json``'s ``cpu_s``."""
    cpu0 = time.process_time()
    try:
        write_figures(out_dir / "figures", read_plot_inputs(out_dir), logs, trials)
    except Exception as exc:  # the numbers stand; a figure bug must not fail the run
        info["figures_error"] = f"{type(exc).__name__}: {exc}"
        print(
            f"ccm: warning: figures failed ({info['figures_error']}); the numbers are written; "
            f"`ccm plots {out_dir}` draws them again",
            file=sys.stderr,
        )
    info["cpu_s"]["figures"] = time.process_time() - cpu0
    write_json_atomic(out_dir / "run_info.json", info)


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
