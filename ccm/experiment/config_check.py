"""Checks of a ``ccm run`` beyond its components (issue #19): trial length, Hydra's launcher
and output settings, and the directories ``ccm run``, ``ccm report`` and ``ccm paper`` write.

Each raises :class:`ccm.core.errors.ConfigError` naming the key and what is allowed, so the CLI
prints one line before Hydra creates a run directory. Imports only the standard library and
:mod:`ccm.core.errors` at module level: :mod:`ccm.experiment.runner` imports this module.
"""

from __future__ import annotations

import math
import os
import shutil
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from ccm.core.errors import NAME_MAX, ConfigError

#: a trial shorter than this many control steps measures nothing (issue #19: one step gave
#: status ok, error 0 and a 1-row CSV); chosen: a few steps more than the metrics' filters need
MIN_TRIAL_STEPS = 10

#: a trial longer than this many control steps is refused (issue #39: ``duration=1e7`` grew
#: memory without limit). The trial loop keeps every step's record until the trial ends:
#: measured 2026-12-05, ~2.3 kB per control step (smoke, 2-D, 80 000 steps: +182 MB RSS), so
#: 600 000 steps (10 min at 1 kHz) hold ~1.4 GB in 2-D, more in 3-D
MAX_TRIAL_STEPS = 600_000

#: what ``hydra.launcher._target_`` ends with for SLURM, and the commands submitit calls
_SLURM = ("SlurmLauncher", ("sbatch", "srun"))


def trial_duration(pattern_s: float, settings: Mapping[str, Any]) -> float:
    """A trial's planned length [s]: the pattern plus ``settle_time_s``, cut at
    ``max_time_s`` (``settings`` from :func:`ccm.experiment.components.check_experiment`)."""
    d = pattern_s + settings["settle_time_s"]
    return d if settings["max_time_s"] is None else min(d, settings["max_time_s"])


def check_trial_steps(plan: Any, settings: Mapping[str, Any]) -> None:
    """Every condition × phase of ``plan`` (:data:`ccm.experiment.components.Plan`) runs
    trials of :data:`MIN_TRIAL_STEPS` to :data:`MAX_TRIAL_STEPS` control steps, over which the
    metrics' low-pass (``metrics.lowpass_hz``) is defined (:func:`check_lowpass`)."""
    for cond, phases in plan:
        for _, comp in phases:
            pattern_s = comp.task.pattern.duration
            d = trial_duration(pattern_s, settings)
            dt = comp.sim.control_dt
            steps = math.floor(d / dt + 1e-9)
            where = f" (condition {cond.name})" if cond.overrides else ""
            if steps > MAX_TRIAL_STEPS:
                longer = settings["settle_time_s"] > pattern_s  # the part that made it long
                raise ConfigError(
                    "experiment.settle_time_s" if longer else "task.pattern",
                    f"a trial of {d:g} s is {steps} control steps of {dt:g} s; "
                    f"at most {MAX_TRIAL_STEPS} (each step's record is kept until the trial "
                    f"ends, ~2.3 kB): shorten it or set experiment.max_time_s{where}",
                )  # fmt: skip
            if steps >= MIN_TRIAL_STEPS:
                check_lowpass(settings["lowpass_hz"], dt, d, where)
                continue
            cut = d < pattern_s + settings["settle_time_s"]
            key = "experiment.max_time_s" if cut else "task.pattern"
            if cut and settings.get("fast"):  # fast mode cuts at the smaller of the two
                key += " or experiment.fast_time_s"
            what = "" if cut else " (pattern + experiment.settle_time_s)"
            raise ConfigError(
                key, f"a trial of {d:g} s{what} is {steps} control steps of {dt:g} s "
                f"(sim.dt x sim.control_decimation); a trial needs >= {MIN_TRIAL_STEPS}: "
                f"lengthen it or lower sim.dt{where}",
            )  # fmt: skip


def check_lowpass(cutoff_hz: float, dt: float, trial_s: float, where: str = "") -> None:
    """``metrics.lowpass_hz`` (the first-order filter of :func:`ccm.core.filters.lowpass`)
    must lie below the Nyquist frequency 1/(2 dt), where the filter stops filtering, and its
    time constant 1/(2π f) within a trial, else the filtered velocity never moves (issue #39:
    1e-300 Hz gave accelerations of exactly 0)."""
    low, high = 1.0 / (2.0 * math.pi * trial_s), 0.5 / dt
    if not low <= cutoff_hz < high:
        raise ConfigError(
            "metrics.lowpass_hz", f"{cutoff_hz:g} Hz: must lie in [{low:.3g}, {high:g}) Hz for "
            f"trials of {trial_s:g} s at {dt:g} s a control step (its time constant within a "
            f"trial, below the Nyquist frequency){where}",
        )  # fmt: skip


def check_output_dir(key: str, path: str | Path) -> None:
    """``path`` can be a directory this process writes into: it is one, or can be created
    (its nearest existing parent is a writable directory); no path component is longer than
    the file system allows."""
    path = Path(path)
    long = [p for p in path.parts if len(os.fsencode(p)) > NAME_MAX]
    if long:
        raise ConfigError(
            key, f"a path component is {len(os.fsencode(long[0]))} bytes long; at most "
            f"{NAME_MAX} allowed ({long[0][:40]}…)",
        )  # fmt: skip
    existing = path
    while not existing.exists() and existing != existing.parent:
        if existing.is_symlink():  # a dangling link: mkdir would fail on it
            raise ConfigError(key, f"{existing} is a broken symbolic link; give a directory")
        existing = existing.parent
    if not existing.is_dir():
        where = "is" if existing == path else f"is under {existing}, which is"
        raise ConfigError(key, f"{path} {where} a file, not a directory; give a directory")
    if not os.access(existing, os.W_OK | os.X_OK):
        where = "" if existing == path else f" (its parent {existing})"
        raise ConfigError(key, f"{path}{where} is not writable; give a writable directory")


def check_hydra(hydra: Any, multirun: bool) -> None:
    """Hydra's settings of a ``ccm run`` (``hydra`` = the composed ``hydra`` node): the run or
    sweep directory, the job name (its log file) and, for a sweep, the launcher."""
    from omegaconf import OmegaConf

    def get(key: str) -> Any:
        try:  # an interpolation that resolves only inside a job: skip its check
            return OmegaConf.select(hydra, key, default=None)
        except Exception:  # noqa: BLE001 - omegaconf raises many kinds on resolution
            return None

    out = "sweep.dir" if multirun else "run.dir"
    if get(out) is not None:
        check_output_dir(f"hydra.{out}", str(get(out)))
    name = get("job.name")
    if name is not None and (len(os.fsencode(f"{name}.log")) > NAME_MAX or "/" in str(name)):
        raise ConfigError(
            "hydra.job.name", f"names the job's log file: at most {NAME_MAX - 4} characters "
            f"and no '/', got one of {len(str(name))}",
        )  # fmt: skip
    if multirun:
        _check_launcher(str(get("launcher._target_") or ""), get("launcher.n_jobs"))


def _check_launcher(target: str, n_jobs: Any) -> None:
    if n_jobs is not None and (
        not isinstance(n_jobs, int) or isinstance(n_jobs, bool) or n_jobs == 0
    ):
        raise ConfigError(
            "hydra.launcher.n_jobs", f"must be a non-zero integer (worker processes; -1 = "
            f"every core), got {n_jobs!r}",
        )  # fmt: skip
    suffix, commands = _SLURM
    missing = [c for c in commands if shutil.which(c) is None]
    if target.endswith(suffix) and missing:
        raise ConfigError(
            "hydra/launcher", f"slurm needs {' and '.join(missing)} on PATH (a SLURM cluster's "
            "login node); here use hydra/launcher=local or submitit_local_test",
        )  # fmt: skip
