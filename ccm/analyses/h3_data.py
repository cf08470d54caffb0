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

**Run-to-run variability** (issue #38 item 8; :class:`Variability`, ``h3.variability``):
seed A §4.4.1 trains on a dataset of demonstrations that differ, and puts Fig. 11b's wider band
down to "the larger variability in the training data". Each recorded trial may start from a
jittered tool position (``task.start`` moved by a normal draw per axis; the plan starts there
too, and the arm's posture target is the start configuration, so the joint paths stay apart)
and may carry white noise on its recorded encoders (q, q̇). Both are drawn from the trial's
seed, on streams of their own: the F/T noise draws stay as they were, and zero variability
records exactly what the code recorded before it.

Datasets are NPZ files (``np.load(..., allow_pickle=False)``) with one key per trial and
field, ``trial_<k>/<field>``, and a ``meta`` JSON string (how the data were made).
"""

from __future__ import annotations

import copy
import json
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from omegaconf import DictConfig

from ccm.core.errors import ConfigError, check_finite, check_int_positive, check_nonneg
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


#: the variability's random streams, beside the trial seed: (seed, STREAM, 0) the start,
#: (seed, STREAM, 1) the encoders (the simulator's F/T noise uses the seed alone)
STREAM = 38


@dataclass(frozen=True)
class Variability:
    """How the recorded runs differ besides their F/T noise (module docstring): std per axis
    of the start position [m] and of the recorded encoders' white noise [rad, rad/s]."""

    start_jitter_m: float = 0.0
    encoder_noise_rad: float = 0.0
    encoder_noise_rad_s: float = 0.0

    @classmethod
    def from_config(cls, cfg: Mapping[str, Any] | None, key: str = "h3.variability") -> Variability:
        """From ``h3.variability`` (missing keys: 0); a negative or unknown value names its key."""
        cfg = dict(cfg or {})
        unknown = sorted(set(cfg) - set(cls.__dataclass_fields__))
        if unknown:
            raise ConfigError(f"{key}.{unknown[0]}", "unknown key")
        return cls(**{k: check_nonneg(f"{key}.{k}", v) for k, v in cfg.items()})

    def start_offset(self, seed: int) -> np.ndarray:
        """The start position's offset [m] (3,) of the trial with seed ``seed``."""
        if self.start_jitter_m == 0.0:
            return np.zeros(3)
        return np.random.default_rng((seed, STREAM, 0)).normal(0.0, self.start_jitter_m, 3)

    def encoder_noise(self, seed: int, n: int) -> tuple[np.ndarray, np.ndarray]:
        """White noise (n, 7) on the recorded q [rad] and q̇ [rad/s] of the trial ``seed``."""
        rng = np.random.default_rng((seed, STREAM, 1))
        return (
            rng.normal(0.0, self.encoder_noise_rad, (n, 7)),
            rng.normal(0.0, self.encoder_noise_rad_s, (n, 7)),
        )


def record_trial(
    comp: Any, seed: int, duration_s: float, variability: Variability | None = None
) -> dict[str, np.ndarray]:
    """Run one trial and return it in the layout of the module docstring; ``variability``'s
    encoder noise is added to the recorded q and q̇ (its start jitter is :func:`collect`'s)."""
    joints: list[np.ndarray] = []
    rec = run_trial(
        comp, seed, duration_s,
        on_step=lambda sim: joints.append(np.concatenate(sim.joint_state())),
    )  # fmt: skip
    a = rec.arrays()
    jq = np.asarray(joints)
    variability = variability or Variability()
    if variability.encoder_noise_rad > 0.0 or variability.encoder_noise_rad_s > 0.0:
        nq, ndq = variability.encoder_noise(seed, len(jq))
        jq = jq + np.hstack([nq, ndq])
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
    variability: Variability | None = None,
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
        variability: how the trials differ besides their F/T noise (module docstring); with
            a start jitter each trial builds its own components (its own ``task.start``).
    """
    n = check_int_positive("h3.trials_per_friction", trials_per_friction)
    variability = variability or Variability()
    if len(frictions) == 0:
        raise ConfigError("h3.frictions", "must list at least one wall friction")
    out: list[dict[str, np.ndarray]] = []
    k = first_trial
    for f in frictions:
        mu = check_finite("h3.frictions", f)
        if mu < 0.0:
            raise ConfigError("h3.frictions", f"must be >= 0, got {mu}")
        cfg = compose([*overrides, f"{WALL_FRICTION}={mu}"])
        comp = None
        try:
            for _ in range(n):
                seed_k = trial_seed(seed, k)
                if comp is None or variability.start_jitter_m > 0.0:
                    if comp is not None:
                        comp.sim.close()
                    comp = build_components(_jittered(cfg, variability.start_offset(seed_k)))
                duration = trial_duration_s(comp.task.pattern.duration, settle_time_s, max_time_s)
                out.append(record_trial(comp, seed_k, duration, variability))
                k += 1
        finally:
            if comp is not None:
                comp.sim.close()
    return out


def _jittered(cfg: DictConfig, offset: np.ndarray) -> DictConfig:
    """``cfg`` with ``task.start``'s position moved by ``offset`` (itself when it is zero)."""
    if not np.any(offset):
        return cfg
    cfg = copy.deepcopy(cfg)
    start = [float(v) for v in cfg.task.start]
    start[:3] = (np.asarray(start[:3]) + offset).tolist()
    cfg.task.start = start
    return cfg


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
