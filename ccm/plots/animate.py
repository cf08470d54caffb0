"""``ccm animate RUN_DIR``: a clip of one recorded trial; and ``experiment.animate``.

The clip replays ``timeseries/<condition>/trial_NNN.parquet`` (the controller never runs
again): 2D runs through :mod:`ccm.plots.animate2d` (matplotlib), 3D runs through
:mod:`ccm.plots.animate3d` (PyBullet's offscreen renderer). The scene comes from the run's
composed config (``.hydra/config.yaml``) with the condition's and the trial's phase's
overrides of ``task.*`` / ``sim.*`` applied. Clips are MP4 (through imageio-ffmpeg's ffmpeg),
GIF without one (:mod:`ccm.plots.frames`), written to ``animations/<condition>/trial_NNN.<ext>`` by
default. Every bad argument raises :class:`ccm.core.errors.ConfigError` naming it.
"""

from __future__ import annotations

import json
import re
from collections.abc import Callable, Iterator, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from ccm.core.errors import ConfigError, check_choice, to_plain
from ccm.core.timeseries import read_timeseries, trial_path
from ccm.plots.frames import AnimateSettings, check_out, default_suffix, write_clip

#: ``experiment.animate``: no clips, or the first and last trial of each condition
MODES = ("none", "first_last")
_TRIAL_FILE = re.compile(r"trial_(\d+)\.parquet")


def check_config(cfg: Any) -> str:
    """``experiment.animate`` (one of :data:`MODES`) and the ``animate`` block, validated
    (else a one-line error naming the key); returns the mode."""
    AnimateSettings.from_mapping(cfg.get("animate"))
    return check_choice("experiment.animate", cfg.experiment.get("animate", "none"), MODES)


def clip_path(run_dir: Path, condition: str, trial: int, suffix: str | None = None) -> Path:
    """``<run_dir>/animations/<condition>/trial_NNN.<mp4|gif>`` (GIF only without an ffmpeg)."""
    name = f"trial_{int(trial):03d}{suffix or default_suffix()}"
    return Path(run_dir) / "animations" / condition / name


def frames(
    log: Mapping[str, np.ndarray],
    scene_cfg: Any,
    sim_cfg: Any,
    settings: AnimateSettings,
    labels: Mapping[str, Any],
) -> Iterator[np.ndarray]:
    """The frames of one trial: ``scene_cfg`` / ``sim_cfg`` are the ``task.scene`` and ``sim``
    configs (mappings) or the parsed objects a built simulator holds (``sim.scene``,
    ``sim.config``)."""
    name = sim_cfg.get("name") if isinstance(sim_cfg, Mapping) else None
    three_d = name in ("pybullet3d", "mujoco3d") or "pos_z" in log
    if three_d:  # either 3-D engine's run: the same Panda, replayed from its joint angles
        from ccm.plots.animate3d import frames_3d
        from ccm.sim.mujoco.config import MuJoCo3DConfig
        from ccm.sim.pybullet.scene import PyBullet3DConfig
        from ccm.sim.scene3d import Scene3D

        if isinstance(scene_cfg, Mapping):
            scene_cfg = Scene3D.from_mapping(scene_cfg, "task.scene")
            parse = MuJoCo3DConfig if name == "mujoco3d" else PyBullet3DConfig
            sim_cfg = parse.from_mapping(sim_cfg, "sim")
        return frames_3d(log, scene_cfg, sim_cfg, settings, labels)
    from ccm.plots.animate2d import frames_2d
    from ccm.sim.pymunk.scene import SceneSpec

    if isinstance(scene_cfg, Mapping):
        scene_cfg = SceneSpec.from_mapping(scene_cfg, "task.scene")
    return frames_2d(log, scene_cfg, settings, labels)


def segment_names(task_cfg: Any) -> list[str | None]:
    """The names of the task's pattern segments (None where a segment has none)."""
    pattern = to_plain(task_cfg.get("pattern")) if task_cfg is not None else None
    return [seg.get("name") if isinstance(seg, dict) else None for seg in pattern or []]


def write_animations(
    out_dir: Path,
    cfg: Any,
    plan: Sequence[Any],
    logs: Mapping[str, Sequence[Mapping]],
    trials: Sequence[Mapping[str, Any]],
) -> list[Path]:
    """``experiment.animate: first_last`` (called by the runner after the trial loop): a clip
    of the first and the last trial of each condition, from the logs the runner kept (its
    first and latest trial per condition), the scene of each trial's phase."""
    settings = AnimateSettings.from_mapping(cfg.get("animate"))
    written = []
    for cond, phases in plan:
        rows = [t for t in trials if t["condition"] == cond.name]
        kept = logs.get(cond.name) or []
        if not rows or not kept:
            continue
        comps = {ph.name: comp for ph, comp in phases}
        ends = [rows[0]] if len(rows) == 1 else [rows[0], rows[-1]]
        for row, log in zip(ends, [kept[0], kept[-1]][: len(ends)], strict=True):
            sim = comps[row["phase"]].sim
            labels = {"phase": row["phase"], "segments": segment_names(cond.cfg.task)}
            path = clip_path(out_dir, cond.name, row["trial"])
            write_clip(path, frames(log, sim.scene, sim.config, settings, labels), settings.fps)
            written.append(path)
    return written


def animate_run(
    run_dir: str | Path,
    condition: str | None = None,
    trial: int | None = None,
    out: str | Path | None = None,
    fps: float | None = None,
) -> tuple[Path, int]:
    """``ccm animate``: write the clip of ``condition``'s ``trial`` (defaults: the first
    condition, its last recorded trial); returns the clip's path and frame count."""
    run = check_run_dir(Path(run_dir))
    cfg = _load_config(run)
    conditions = _conditions(cfg, run)
    cond = conditions[0] if condition is None else condition
    if cond not in conditions:
        raise ConfigError(
            "--condition", f"{cond!r} is not a condition of {run}; allowed: {', '.join(conditions)}"
        )
    recorded = recorded_trials(run, cond)
    number = recorded[-1] if trial is None else trial
    if number not in recorded:
        raise ConfigError(
            "--trial",
            f"condition {cond} of {run} has no time series of trial "
            f"{number}; recorded: {', '.join(map(str, recorded))}",
        )
    path = trial_path(run, cond, number)
    target = check_out(Path(out)) if out is not None else clip_path(run, cond, number)
    phase = _phase_of(run, cond, number)
    ccfg = condition_config(cfg, cond, phase)
    settings = AnimateSettings.from_mapping(ccfg.get("animate"), fps)
    labels = {"phase": phase, "segments": segment_names(ccfg.task), "source": str(path)}
    log = {k: np.asarray(v, dtype=float) for k, v in _readable(path, read_timeseries).items()}
    clip = frames(log, to_plain(ccfg.task.scene), to_plain(ccfg.sim), settings, labels)
    try:
        return target, write_clip(target, clip, settings.fps)
    except OSError as exc:  # a read-only run, a full disk
        raise ConfigError("--out", f"{target}: cannot write ({exc.strerror or exc}); give "
                          "--out FILE in a writable place") from None  # fmt: skip


USAGE = "usage: ccm animate RUN_DIR [--condition C] [--trial N] [--out FILE] [--fps F]"


def main(args: Sequence[str]) -> int:
    """``ccm animate RUN_DIR [--condition C] [--trial N] [--out FILE] [--fps F]``: write the
    clip, print its path; a bad argument raises :class:`ConfigError` naming it (the CLI
    prints it as one line, exit 2)."""
    import argparse

    if args and args[0] in ("-h", "--help"):
        print(USAGE)
        return 0
    parser = argparse.ArgumentParser(prog="ccm animate", exit_on_error=False, add_help=False)
    parser.add_argument("run_dir", nargs="?")
    parser.add_argument("--condition")
    parser.add_argument("--trial", type=int)
    parser.add_argument("--out")
    parser.add_argument("--fps", type=float)
    try:
        ns, rest = parser.parse_known_args(list(args))
    except argparse.ArgumentError as exc:
        raise ConfigError("animate", f"{exc}; {USAGE}") from None
    if rest or ns.run_dir is None:
        problem = f"unexpected {rest[0]!r}" if rest else "RUN_DIR is required"
        raise ConfigError("animate", f"{problem}; {USAGE}")
    path, count = animate_run(ns.run_dir, ns.condition, ns.trial, ns.out, ns.fps)
    print(f"ccm: {count} frames -> {path}")
    return 0


def check_run_dir(run: Path) -> Path:
    """RUN_DIR: an existing run directory with its composed config and recorded series."""
    if not run.exists():
        raise ConfigError("RUN_DIR", f"{run} does not exist")
    if not (run / ".hydra" / "config.yaml").is_file():
        jobs = sorted(p.parent.parent.name for p in run.glob("*/.hydra/config.yaml"))
        hint = f" (a sweep? its runs: {', '.join(jobs[:5])}{' …' if len(jobs) > 5 else ''})"
        raise ConfigError(
            "RUN_DIR",
            f"{run} is not a ccm run directory: no .hydra/config.yaml" + (hint if jobs else ""),
        )
    if not any((run / "timeseries").glob("*/trial_*.parquet")):
        raise ConfigError(
            "RUN_DIR",
            f"{run} recorded no time series (experiment.timeseries=none?); run it again "
            "with experiment.timeseries=first_last or all",
        )
    return run


def recorded_trials(run: Path, condition: str) -> list[int]:
    """The trial numbers of ``condition`` with a time-series file, ascending."""
    found = [_TRIAL_FILE.fullmatch(f.name) for f in (run / "timeseries" / condition).glob("*")]
    numbers = sorted(int(m.group(1)) for m in found if m)
    if not numbers:
        raise ConfigError(
            "--condition",
            f"{condition} of {run} recorded no time series; "
            f"conditions with some: {', '.join(_with_series(run))}",
        )
    return numbers


def _with_series(run: Path) -> list[str]:
    return sorted(p.name for p in (run / "timeseries").iterdir() if any(p.glob("trial_*.parquet")))


def _load_config(run: Path) -> Any:
    from omegaconf import OmegaConf

    path = run / ".hydra" / "config.yaml"
    cfg = _readable(path, OmegaConf.load)
    missing = [
        k for k in ("experiment", "task", "sim") if not OmegaConf.is_dict(cfg) or k not in cfg
    ]
    if missing:
        raise ConfigError("RUN_DIR", f"{path} cannot be read (no {missing[0]!r} in it); the run's "
                          "record is damaged")  # fmt: skip
    return cfg


def _readable(path: Path, read: Callable[[Path], Any]) -> Any:
    """``read(path)``; a damaged file (truncated, not UTF-8, not its format) is a ConfigError
    naming it (issue #39: tracebacks from JSON, YAML and Parquet readers)."""
    import yaml

    try:
        return read(path)
    except (OSError, ValueError, yaml.YAMLError) as exc:  # pyarrow's ArrowInvalid: ValueError
        text = str(exc).replace(f"'{path}'", "").replace(str(path), "").strip()
        why = text.splitlines()[0] if text else type(exc).__name__
        raise ConfigError("RUN_DIR", f"{path} cannot be read ({why[:160]}); the run's "
                          "record is damaged") from None  # fmt: skip


def _conditions(cfg: Any, run: Path) -> list[str]:
    """The run's conditions in the config's order (or the controller's name, as the runner
    names a run without conditions)."""
    spec = {k: v for k, v in (to_plain(cfg.experiment.get("conditions")) or {}).items() if v}
    if spec:
        return list(spec)
    return _with_series(run)


def _phase_of(run: Path, condition: str, trial: int) -> str | None:
    """The trial's phase, from summary.json (None when the run has no summary yet)."""
    summary = run / "summary.json"
    if not summary.is_file():
        return None
    data = _readable(summary, lambda p: json.loads(p.read_text(encoding="utf-8")))
    rows = (data.get("trials") if isinstance(data, dict) else None) or []
    for row in rows:
        if row.get("condition") == condition and row.get("trial") == trial:
            return row.get("phase")
    return None


def condition_config(cfg: Any, condition: str, phase: str | None) -> Any:
    """The run's config with the condition's and the phase's ``task.*`` / ``sim.*`` /
    ``animate.*`` overrides applied (what the scene of that trial was built from). A
    condition that swaps the whole task or sim group cannot be rebuilt from the run alone."""
    from hydra.core.override_parser.overrides_parser import OverridesParser
    from omegaconf import OmegaConf

    cfg = OmegaConf.create(OmegaConf.to_container(cfg, resolve=False))
    spec = to_plain(cfg.experiment.get("conditions")) or {}
    overrides = list(spec.get(condition) or [])
    for ph in to_plain(cfg.experiment.get("phases")) or []:
        if isinstance(ph, dict) and ph.get("name") == phase:
            overrides += list(ph.get("overrides") or [])
    for ov in OverridesParser.create().parse_overrides(overrides):
        key = ov.key_or_group
        if key in ("task", "sim"):
            raise ConfigError(
                f"experiment.conditions.{condition}",
                f"{ov.input_line} swaps the {key} group; ccm animate draws the run's own only",
            )
        if key.split(".")[0] in ("task", "sim", "animate"):
            OmegaConf.update(cfg, key, ov.value(), merge=False, force_add=True)
    return cfg
