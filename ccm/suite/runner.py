"""Run one controller (an *entry*) over a suite's tasks and seeds.

Each (task, seed) is a job: its config is composed as ``ccm run`` composes one (the task's
``sim`` and ``task`` options, the entry's controller overrides, the seed, the user's config
directories), the task's settings and the suite's protocol are set on it
(:func:`ccm.suite.definition.apply_task`), and :func:`ccm.experiment.runner.run_experiment`
runs it into ``<out>/runs/<task>/seed_<seed>/``. A job that fails (a plugin that raises, a
simulation that diverges) writes ``summary.json`` with ``status: failed`` and its cause, and
the other jobs go on. Jobs run ``jobs`` at a time in worker processes (spawned: each builds
its own simulators); results do not depend on ``jobs``.
"""

from __future__ import annotations

import multiprocessing
import os
import time
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from omegaconf import DictConfig, OmegaConf

from ccm.core.errors import ConfigError, SimulationDiverged, exception_line
from ccm.core.records import write_json_atomic
from ccm.experiment import user_configs
from ccm.experiment.components import build_components
from ccm.experiment.runner import failed_summary, run_experiment
from ccm.suite.definition import Suite, SuiteTask, apply_task, fingerprint, load_suite

#: the per-seed numbers an entry's results keep: the suite metrics and ``completed``
KEPT_EXTRA = ("completed",)


@dataclass(frozen=True)
class Job:
    """One task and seed of an entry (picklable: it crosses to a worker process)."""

    suite: str
    task: str
    seed: int
    overrides: tuple[str, ...]
    dirs: tuple[str, ...]
    out_dir: str


def compose_task(
    suite: Suite, task: SuiteTask, overrides: Sequence[str], seed: int, dirs: Sequence[Path]
) -> DictConfig:
    """The run config of ``task`` for the controller ``overrides`` and ``seed``."""
    from hydra import compose, initialize_config_dir

    extra = [f"sim={task.sim}", f"task={task.task}", *overrides, f"seed={seed}",
             *user_configs.searchpath_override(dirs)]  # fmt: skip
    with initialize_config_dir(str(user_configs.config_dir()), version_base="1.3",
                               job_name="ccm_suite"):  # fmt: skip
        cfg = compose("config", overrides=extra)
    return apply_task(cfg, suite, task)


def check_overrides(overrides: Sequence[str], dirs: Sequence[Path]) -> None:
    """Only the controller may be chosen: ``controller=…``, ``controller.*``, ``+controller.*``
    (the tasks are the suite's); an unknown controller option names the allowed ones."""
    for ov in overrides:
        key, _, value = ov.lstrip("+~").partition("=")
        if key != "controller" and not key.startswith("controller."):
            raise ConfigError(key, "ccm suite takes controller overrides only (controller=NAME, "
                              "controller.KEY=VALUE): the suite fixes the tasks")  # fmt: skip
        if key == "controller" and value not in user_configs.group_options("controller", dirs):
            allowed = ", ".join(user_configs.group_options("controller", dirs))
            raise ConfigError(f"controller={value}", f"unknown option; allowed: {allowed}")


def precheck(suite: Suite, tasks: Sequence[str], overrides: Sequence[str],
             dirs: Sequence[Path]) -> dict[str, str]:  # fmt: skip
    """Compose every task with the entry's overrides and build its components once, so that a
    bad override or plugin is one ConfigError before anything runs; return the tasks'
    fingerprints."""
    from hydra.errors import HydraException

    check_overrides(overrides, dirs)
    prints = {}
    for name in tasks:
        task = suite.tasks[name]
        try:
            cfg = compose_task(suite, task, overrides, suite.seeds[0], dirs)
        except HydraException as exc:
            raise ConfigError(f"task {name}", " ".join(str(exc).split())[:300]) from None
        comp = build_components(cfg)
        comp.sim.close()
        prints[name] = fingerprint(cfg, suite)
    return prints


def task_fingerprints(suite: Suite, tasks: Sequence[str]) -> dict[str, str]:
    """Today's fingerprint of each task (composed with the default controller: the controller
    is not part of it)."""
    return {t: fingerprint(compose_task(suite, suite.tasks[t], [], suite.seeds[0], ()), suite)
            for t in tasks}  # fmt: skip


def run_job(job: Job) -> dict[str, Any]:
    """Run one job into its directory; return ``{task, seed, status, metrics | error,
    wall_s, cpu_s}`` (never raises for a failing controller or simulation)."""
    from threadpoolctl import threadpool_limits

    suite = load_suite(job.suite)
    task = suite.tasks[job.task]
    out = Path(job.out_dir)
    out.mkdir(parents=True, exist_ok=True)
    wall0, cpu0 = time.perf_counter(), time.process_time()
    row: dict[str, Any] = {"task": job.task, "seed": job.seed}
    cfg = None
    try:
        with threadpool_limits(limits=1):  # one BLAS thread per job, as ccm run
            cfg = compose_task(suite, task, job.overrides, job.seed, [Path(d) for d in job.dirs])
            (out / "config.yaml").write_text(OmegaConf.to_yaml(cfg, resolve=True))
            summary = run_experiment(cfg, _no_compose, out, show_progress=False)
        row.update(status="ok", metrics=scored_metrics(summary, suite))
    except Exception as exc:  # a plugin may raise anything: the job fails, the suite goes on
        expected = isinstance(exc, ConfigError | SimulationDiverged)
        row.update(status="failed", error=str(exc) if expected else exception_line(exc))
        write_json_atomic(out / "summary.json", failed_summary(cfg, row["error"]))
    row.update(wall_s=time.perf_counter() - wall0, cpu_s=time.process_time() - cpu0)
    return row


def _set_env(env: dict[str, str]) -> None:
    """A worker's environment: the user's config directories, as in the parent."""
    os.environ.update(env)


def _no_compose(extra: Sequence[str]) -> DictConfig:
    raise ConfigError("experiment", f"a suite run has no conditions to compose ({list(extra)})")


def scored_metrics(summary: dict[str, Any], suite: Suite) -> dict[str, float | None]:
    """The scored trials' means (the summary's one condition averages its last phase) of
    the suite's metrics."""
    (means,) = summary["conditions"].values()
    return {k: means.get(k) for k in (*suite.metrics, *KEPT_EXTRA)}


def run_entry(
    suite: Suite,
    tasks: Sequence[str],
    overrides: Sequence[str],
    out_dir: Path,
    dirs: Sequence[Path] = (),
    jobs: int = 2,
    on_done: Callable[[dict[str, Any]], None] | None = None,
) -> list[dict[str, Any]]:
    """Every (task, seed) job of one entry, ``jobs`` at a time; the rows of :func:`run_job`
    in task then seed order. The 3-D tasks start first (the longest jobs)."""
    specs = [
        Job(str(suite.source or suite.name), t, s, tuple(overrides), tuple(map(str, dirs)),
            str(out_dir / "runs" / t / f"seed_{s}"))
        for t in tasks for s in suite.seeds
    ]  # fmt: skip
    order = sorted(specs, key=lambda j: suite.tasks[j.task].sim == "pymunk2d")
    rows: list[dict[str, Any]] = []
    if jobs <= 1:
        for job in order:
            rows.append(run_job(job))
            if on_done is not None:
                on_done(rows[-1])
    else:
        ctx = multiprocessing.get_context("spawn")  # no simulator state crosses a fork
        env = {user_configs.DIRS_ENV: os.pathsep.join(map(str, dirs))}
        with ProcessPoolExecutor(jobs, mp_context=ctx, initializer=_set_env,
                                 initargs=(env,)) as pool:  # fmt: skip
            try:
                for future in as_completed([pool.submit(run_job, job) for job in order]):
                    rows.append(future.result())
                    if on_done is not None:
                        on_done(rows[-1])
            except BaseException:  # Ctrl-C: the jobs not started are dropped, not waited for
                pool.shutdown(wait=False, cancel_futures=True)
                raise
    index = {(j.task, j.seed): i for i, j in enumerate(specs)}
    return sorted(rows, key=lambda r: index[(r["task"], r["seed"])])
