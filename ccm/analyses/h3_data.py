"""H3 training and test data (seed A §4.4, Fig. 1b): ``table_wall`` trials with a fixed-gain
controller, recorded with what the offline baseline (Khader et al. 2020) learns from.

Each trial is a dict of equal-length arrays, one row per control step:

* ``t`` [s]; ``q``, ``dq`` (n, 7): joint encoders [rad, rad/s], the robot's own measurement
  (:meth:`ccm.sim.pybullet.backend.PyBullet3D.joint_state`), for the joint-space variant (§4.4.1);
* ``position``, ``velocity`` (n, 3): tool point [m, m/s]; ``force`` (n, 3): the F/T sensor's
  measured force [N] (task-space variants, §4.4.2-4.4.3);
* ``mode`` (n,): contact-mode label from the simulator's contact truth: 0 free space, 1 on
  the table only, 2 against the wall. Khader et al. identify the modes of their training
  demonstrations; labelling the *training* data from the simulator stands in for that
  identification (the SVM then predicts the mode from the state alone);
* ``wall_friction`` (scalar array): the trial's wall friction.

Datasets are NPZ files (``np.load(..., allow_pickle=False)``) with one key per trial and
field, ``trial_<k>/<field>``, and a ``meta`` JSON string (how the data were made).
"""

from __future__ import annotations

import json
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from omegaconf import DictConfig

from ccm.core.errors import ConfigError, check_finite, check_int_positive
from ccm.core.records import atomic_path
from ccm.experiment.components import build_components, trial_seed
from ccm.experiment.trial import run_trial

FIELDS = ("t", "q", "dq", "position", "velocity", "force", "mode", "wall_friction")
WALL_FRICTION = "task.scene.boxes.0.friction"  # the one field H3 varies (table_wall.yaml)
SETTLE_TIME_S = 0.5  # s simulated after the pattern ends (chosen: the runner's settle_time_s)
CONTACT_N = 0.5  # N of true normal force that labels a surface touched (chosen: 10x the F/T
#                  noise; only the training labels use it, never a controller)


def contact_modes(table_normal_N: np.ndarray, box_normal_N: np.ndarray) -> np.ndarray:
    """Mode labels from the true normal forces: 0 free, 1 table only, 2 wall (module doc)."""
    wall = np.asarray(box_normal_N) > CONTACT_N
    table = np.asarray(table_normal_N) > CONTACT_N
    return np.where(wall, 2, np.where(table, 1, 0)).astype(np.int64)


def record_trial(comp: Any, seed: int, duration_s: float) -> dict[str, np.ndarray]:
    """Run one trial and return it in the layout of the module docstring."""
    joints: list[np.ndarray] = []
    rec = run_trial(
        comp, seed, duration_s,
        on_step=lambda sim: joints.append(np.concatenate(sim.joint_state())),
    )  # fmt: skip
    a = rec.arrays()
    jq = np.asarray(joints)
    axes = "xyz"
    return {
        "t": a["t"],
        "q": jq[:, :7],
        "dq": jq[:, 7:],
        "position": np.column_stack([a[f"pos_{k}"] for k in axes]),
        "velocity": np.column_stack([a[f"vel_{k}"] for k in axes]),
        "force": np.column_stack([a[f"force_{k}"] for k in axes]),
        "mode": contact_modes(a["truth_table_normal_N"], a["truth_box_normal_N"]),
        "wall_friction": np.array(float(comp.sim.scene.boxes[0].friction)),
    }


def trial_duration_s(
    pattern_s: float, settle_time_s: float = SETTLE_TIME_S, max_time_s: float | None = None
) -> float:
    """Simulated seconds of one recorded trial: the pattern, then ``settle_time_s``, truncated
    at ``max_time_s`` when given."""
    duration = pattern_s + settle_time_s
    return duration if max_time_s is None else min(duration, max_time_s)


def collect(
    compose: Callable[[Sequence[str]], DictConfig],
    overrides: Sequence[str],
    frictions: Sequence[float],
    trials_per_friction: int,
    seed: int,
    settle_time_s: float = SETTLE_TIME_S,
    first_trial: int = 1,
    max_time_s: float | None = None,
) -> list[dict[str, np.ndarray]]:
    """Record ``trials_per_friction`` trials at each wall friction.

    Args:
        compose: config composer (as the runner's); ``overrides`` select sim, task and
            controller (e.g. ``["sim=pybullet3d", "task=table_wall", "controller=..."]``).
        frictions: wall frictions (``task.scene.boxes.0.friction``), each ≥ 0.
        trials_per_friction: trials at each friction (the trials differ by their seeds: the
            sensor noise).
        seed: root seed; trial k (counted from ``first_trial`` over all frictions) uses
            :func:`ccm.experiment.components.trial_seed`.
        settle_time_s: simulated after the pattern ends [s].
        first_trial: number of the first trial (for its seed).
        max_time_s: truncate every trial (tests); None = the whole pattern.
    """
    n = check_int_positive("h3.trials_per_friction", trials_per_friction)
    if len(frictions) == 0:
        raise ConfigError("h3.frictions", "must list at least one wall friction")
    out: list[dict[str, np.ndarray]] = []
    k = first_trial
    for f in frictions:
        mu = check_finite("h3.frictions", f)
        if mu < 0.0:
            raise ConfigError("h3.frictions", f"must be >= 0, got {mu}")
        comp = build_components(compose([*overrides, f"{WALL_FRICTION}={mu}"]))
        try:
            for _ in range(n):
                duration = trial_duration_s(comp.task.pattern.duration, settle_time_s, max_time_s)
                out.append(record_trial(comp, trial_seed(seed, k), duration))
                k += 1
        finally:
            comp.sim.close()
    return out


def save_dataset(path: Path, trials: Sequence[Mapping[str, np.ndarray]], meta: Mapping) -> Path:
    """Write ``trials`` and ``meta`` (JSON-safe) to an NPZ file (no pickle); return the path."""
    arrays: dict[str, np.ndarray] = {"meta": np.array(json.dumps(dict(meta), sort_keys=True))}
    for i, tr in enumerate(trials):
        for name in FIELDS:
            arrays[f"trial_{i:03d}/{name}"] = np.asarray(tr[name])
    with atomic_path(path) as tmp, open(tmp, "wb") as fh:
        np.savez_compressed(fh, **arrays)
    return path


def load_dataset(path: Path, key: str = "h3.data_from") -> tuple[list[dict[str, np.ndarray]], dict]:
    """Read a dataset written by :func:`save_dataset`; a missing or malformed file is a
    one-line :class:`ConfigError` named ``key``."""
    try:
        with np.load(path, allow_pickle=False) as z:
            meta = json.loads(str(z["meta"]))
            ids = sorted({k.split("/")[0] for k in z.files if k.startswith("trial_")})
            trials = [{f: z[f"{i}/{f}"] for f in FIELDS} for i in ids]
    except FileNotFoundError:
        raise ConfigError(key, f"no dataset at {path}") from None
    except (OSError, ValueError, KeyError) as exc:
        raise ConfigError(key, f"{path}: not a ccm H3 dataset ({exc})") from None
    lengths = {len(tr["t"]) for tr in trials}
    if not trials or any(len(tr[f]) != len(tr["t"]) for tr in trials for f in FIELDS[:-1]):
        raise ConfigError(key, f"{path}: empty or ragged trials (lengths {sorted(lengths)})")
    return trials, meta
