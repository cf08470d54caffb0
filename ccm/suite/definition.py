"""A benchmark suite's definition: its tasks, protocol and metrics, read from
``configs/suite/<name>.yaml`` (format in ``changing_contact_v1.yaml``'s header).

Each task composes a run config the way ``ccm run`` does (its ``sim`` and ``task`` options
plus the controller's), then sets the task's ``settings`` (dotted keys) and the protocol's
``experiment`` node (:func:`protocol_experiment`). :func:`fingerprint` hashes what defines a
task's world, so stored results of another scene are never ranked beside new ones.
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from omegaconf import DictConfig, OmegaConf, open_dict

from ccm.core.errors import (
    ConfigError,
    check_int_nonneg,
    check_int_positive,
    check_nonneg,
    to_plain,
)
from ccm.experiment.user_configs import config_dir

#: the suite ``ccm suite`` runs when none is named
DEFAULT_SUITE = "changing_contact_v1"
#: the metrics node keys a suite's metrics read (part of a task's fingerprint)
METRIC_KEYS = ("lowpass_hz", "completion_tol_m", "contact_loss_min_s", "vel_split_hz")


@dataclass(frozen=True)
class SuiteTask:
    """One task of a suite: its simulator and task options, the settings that make it this
    suite's task, and the metrics it ranks."""

    name: str
    description: str
    sim: str
    task: str
    settings: Mapping[str, Any]
    ranked: tuple[str, ...]
    extra_metrics: tuple[str, ...] = ()


@dataclass(frozen=True)
class Suite:
    """A versioned set of tasks with one protocol (seeds, warm-up and scored trials)."""

    name: str
    version: int
    description: str
    seeds: tuple[int, ...]
    warmup_trials: int
    scored_trials: int
    settle_time_s: float  # s after the pattern's end (completion-time window)
    max_retime_s: float  # s a re-timing controller may lengthen a trial by
    metrics: Mapping[str, Mapping[str, str]]  # name -> {label, unit}
    tasks: Mapping[str, SuiteTask] = field(default_factory=dict)
    #: the built-in entries whose results are stored: name -> controller overrides
    entries: Mapping[str, tuple[str, ...]] = field(default_factory=dict)
    source: Path | None = None  # the YAML file it was read from

    @property
    def trials(self) -> int:
        return self.warmup_trials + self.scored_trials


def suite_names() -> list[str]:
    """The suites shipped in the package's ``configs/suite``."""
    return sorted(p.stem for p in (config_dir() / "suite").glob("*.yaml"))


def load_suite(name: str = DEFAULT_SUITE) -> Suite:
    """Read and validate ``configs/suite/<name>.yaml``, or the YAML file ``name`` (a user's
    own suite, same format); an unknown name or a bad field is a ConfigError naming it."""
    path = config_dir() / "suite" / f"{name}.yaml"
    if name.endswith((".yaml", ".yml")):
        path = Path(name)
        name = path.stem
    if not path.is_file():
        raise ConfigError("--suite", f"unknown suite {name!r}; allowed: {', '.join(suite_names())}"
                          " or a suite's YAML file")  # fmt: skip
    raw = to_plain(OmegaConf.load(path), f"suite {name}")
    key = f"suite {name}"
    metrics = raw.get("metrics") or {}
    seeds = [check_int_nonneg(f"{key}.seeds", s) for s in raw.get("seeds") or []]
    if not seeds:
        raise ConfigError(f"{key}.seeds", "needs at least one seed")
    tasks = {t: _task(f"{key}.tasks.{t}", t, spec, metrics) for t, spec in raw["tasks"].items()}
    return Suite(
        name=name,
        version=check_int_positive(f"{key}.version", raw.get("version")),
        description=str(raw.get("description", "")),
        seeds=tuple(seeds),
        warmup_trials=check_int_nonneg(f"{key}.warmup_trials", raw.get("warmup_trials", 0)),
        scored_trials=check_int_positive(f"{key}.scored_trials", raw.get("scored_trials", 1)),
        settle_time_s=check_nonneg(f"{key}.settle_time_s", raw.get("settle_time_s", 0.5)),
        max_retime_s=check_nonneg(f"{key}.max_retime_s", raw.get("max_retime_s", 60.0)),
        metrics=metrics,
        tasks=tasks,
        entries={str(k): tuple(map(str, v)) for k, v in (raw.get("entries") or {}).items()},
        source=path.resolve(),
    )


def _task(key: str, name: str, spec: Mapping[str, Any], metrics: Mapping[str, Any]) -> SuiteTask:
    ranked = tuple(spec.get("ranked") or ())
    unknown = [m for m in ranked if m not in metrics]
    if unknown or not ranked:
        got = f", got {unknown[0]!r}" if unknown else ""
        allowed = ", ".join(metrics)
        raise ConfigError(f"{key}.ranked", f"needs metrics of the suite's list ({allowed}){got}")
    return SuiteTask(
        name=name,
        description=str(spec.get("description", "")),
        sim=str(spec["sim"]),
        task=str(spec["task"]),
        settings=dict(spec.get("settings") or {}),
        ranked=ranked,
        extra_metrics=tuple(spec.get("extra_metrics") or ()),
    )


def protocol_experiment(suite: Suite, task: SuiteTask) -> dict[str, Any]:
    """The ``experiment`` node of a suite run: one condition, the warm-up then the scored
    trials, the suite's metrics, no figures or time series (the numbers are the product)."""
    phases = [{"name": "scored", "trials": suite.scored_trials, "overrides": []}]
    if suite.warmup_trials:
        phases.insert(0, {"name": "warmup", "trials": suite.warmup_trials, "overrides": []})
    return {
        "name": f"suite_{task.name}",
        "description": f"{suite.name} task {task.name}: {task.description}",
        "kind": "trials",
        "trials": suite.trials,
        "conditions": {},
        "phases": phases,
        "metrics": ["suite", *task.extra_metrics],
        "settle_time_s": suite.settle_time_s,
        "max_time_s": None,
        "max_retime_s": suite.max_retime_s,
        "fast": False,
        "figures": False,
        "timeseries": "none",
        "animate": "none",
    }


def apply_task(cfg: DictConfig, suite: Suite, task: SuiteTask) -> DictConfig:
    """Set the task's settings and the protocol on a composed run config (in place); a
    setting that names no key of the config is a ConfigError naming it."""
    with open_dict(cfg):
        for dotted, value in task.settings.items():
            if OmegaConf.select(cfg, dotted, default=_MISSING) is _MISSING:
                raise ConfigError(f"suite {suite.name}.tasks.{task.name}.settings.{dotted}",
                                  "names no key of the composed config")  # fmt: skip
            OmegaConf.update(cfg, dotted, value, merge=False)
        cfg.experiment = protocol_experiment(suite, task)
    return cfg


_MISSING = object()


def fingerprint(cfg: DictConfig, suite: Suite) -> str:
    """A hash of what defines a task's world and protocol in a composed run config: the
    resolved ``sim`` and ``task`` nodes, the metric settings the suite reads and the trials
    (the controller and the seed are not part of it)."""
    sim = {k: v for k, v in to_plain(cfg.sim).items() if k not in ("description",)}
    task = {k: v for k, v in to_plain(cfg.task).items() if k not in ("description",)}
    metrics = {k: cfg.metrics.get(k) for k in METRIC_KEYS}
    payload = {"sim": sim, "task": task, "metrics": metrics, "seeds": list(suite.seeds),
               "trials": [suite.warmup_trials, suite.scored_trials]}  # fmt: skip
    text = json.dumps(payload, sort_keys=True, default=str)
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def results_dir(suite: Suite) -> Path:
    """Where the stored results of the built-in entries live: shipped with the package for
    its own suites, ``<name>_results/`` beside a user's suite file."""
    if suite.source is not None and suite.source.parent != (config_dir() / "suite").resolve():
        return suite.source.parent / f"{suite.name}_results"
    return Path(__file__).resolve().parent / "results" / suite.name


def check_task_names(suite: Suite, names: Sequence[str]) -> list[str]:
    """``names`` (``--tasks``) checked against the suite's; all of them when empty."""
    for n in names:
        if n not in suite.tasks:
            raise ConfigError("--tasks", f"unknown task {n!r}; allowed: {', '.join(suite.tasks)}")
    return list(names) or list(suite.tasks)
