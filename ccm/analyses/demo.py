"""``ccm demo TASK --out FILE``: record one demonstration of a task in simulation.

Seed A (§3) takes the target pattern P from one kinesthetic demonstration: a person guides
the compliant robot through the task. Here seed B's simulated human
(:class:`ccm.sim.pymunk.hri.HumanSpec`, a bounded, noisy PD pull of the hand toward a goal,
seed B §3.1) does the guiding, and the robot runs in admittance mode:

* **Human.** The hand's goal is the task's planned pattern P, sampled every
  :data:`GOAL_DT_S` as a goal sequence (``HumanSpec.goal_times``), and held at P's end for
  :data:`SETTLE_S`. Where P asks for a force F along d, the goal lies F / k past the planned
  point along d (k the hand's stiffness), so that a hand stopped by the surface presses
  with F, as a person pressing the tool down would. It is part of the environment: the
  robot feels it only through the F/T sensor and its own motion, like a real person's hand.
* **Robot.** Zero-stiffness impedance, a pure damper: Eq. 1 of seed A with K_p acting on a
  zero error (the reference is the robot's own measured position, every step), fixed damping
  :data:`ROBOT_DAMPING_NSPM`, no inertial feed-forward. That is the admittance law f = D ẋ
  of seed B Eq. 4 with f^r = 0, realised on a torque-controlled robot whose mass is its
  own, so the tool yields to whatever pushes it: the hand, and the task's scene (springs,
  surfaces) as they would in a real demonstration. The controller sees the Observation only.

The file (CSV or Parquet, by suffix) has one row per control step: ``t`` [s], ``x, y(, z)``
[m] (the measured position), ``fx, fy(, fz)`` [N] (the force the tool exerts on the
environment: minus the simulator's contact force; in 3D its normal part, friction left out,
since friction follows from the motion and is no target; pymunk does not split it, so in 2D
friction is included) and, for inspection, ``human_fx, …`` [N] (the hand's force).
``{type: recording, file: FILE}`` reads it back (:mod:`ccm.tasks.recording`). 2D tasks run
on pymunk (``HumanSpec`` with ``goal_times``), 3D tasks on PyBullet: the hand
(:class:`ccm.sim.hand.HandSpec`, the same law) is an external force at the tool point, on
the tool link below the wrist F/T sensor, which therefore measures it.
"""

from __future__ import annotations

import argparse
import math
import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from omegaconf import DictConfig

from ccm.control.registry import make_controller
from ccm.core.errors import ConfigError, SimulationDiverged, to_plain
from ccm.core.records import atomic_path
from ccm.core.types import TargetSample
from ccm.experiment.components import check_dims
from ccm.sim import make_sim, sim_class
from ccm.sim.base import check_state_finite
from ccm.tasks.task import load_task

AXES = ("x", "y", "z")

USAGE = (
    "usage: ccm demo TASK --out FILE.csv|FILE.parquet [--force] [--seed N] [--rate HZ] [OVERRIDES…]"
)

#: Goal-sequence spacing [s]: the hand's intent updated at 100 Hz, smooth to the 1 kg tool
#: (chosen).
GOAL_DT_S = 0.01
#: Time recorded after P's end, the hand holding the last goal [s] (chosen: about 10 time
#: constants of the hand-robot system below, so the demonstration ends at rest).
SETTLE_S = 1.0
#: The hand (chosen, within seed B's human-arm range): stiffness [N/m], damping [N s/m],
#: force bound [N], noise std per axis [N] and its cut-off [Hz], force rise time [s].
HUMAN: dict[str, float] = {
    "stiffness": 1000.0,
    "damping": 20.0,
    "max_force": 40.0,
    "noise_std": 0.3,
    "noise_cutoff_hz": 2.0,
    "ramp_s": 0.2,
}
#: The robot's admittance damping D [N s/m] (chosen: with the hand's 1000 N/m and 20 N s/m and
#: the 1 kg tool, the hand-robot system is close to critically damped, ζ ≈ 0.95).
ROBOT_DAMPING_NSPM = 40.0


def demo_overrides(task: str, extra: Sequence[str]) -> list[str]:
    """Hydra overrides of a demonstration: the task, the damper controller, then ``extra``."""
    return [
        f"task={task}",
        "controller=fixed_impedance",
        "controller.loop.damping_rule=fixed",
        f"controller.loop.damping={ROBOT_DAMPING_NSPM}",
        "controller.loop.inertia_feedforward=false",
        *extra,
    ]


def compose_demo(task: str, extra: Sequence[str]) -> DictConfig:
    """The composed config of a demonstration of ``task`` (a 3D task on ``sim=pybullet3d``);
    a Hydra error (an unknown task or key) is one ConfigError line."""
    from hydra import compose, initialize_config_dir
    from hydra.errors import HydraException
    from omegaconf.errors import OmegaConfBaseException

    from ccm.experiment.user_configs import config_dir

    try:
        with initialize_config_dir(str(config_dir()), version_base="1.3", job_name="ccm_demo"):
            dim = compose("config", overrides=[f"task={task}"]).task.get("dim")
            sim = [] if dim != 3 or any(a.startswith("sim=") for a in extra) else ["sim=pybullet3d"]
            return compose("config", overrides=demo_overrides(task, [*sim, *extra]))
    except (HydraException, OmegaConfBaseException) as exc:
        raise ConfigError("demo", " ".join(str(exc).split())[:300]) from None


def human_spec(pattern: Any) -> dict[str, Any]:
    """The scene's ``human`` entry: the hand pulling along P (a goal every GOAL_DT_S)."""
    times = np.arange(0.0, pattern.duration + GOAL_DT_S / 2, GOAL_DT_S)
    plan = pattern.sample_many(times)
    # where P asks for a force, the hand aims F/k past the planned point: it presses with F
    goals = plan["position"] + plan["force_dir"] * (plan["force_mag"] / HUMAN["stiffness"])[:, None]
    return {**HUMAN, "goals": goals.tolist(), "goal_times": times.tolist()}


def record_demo(cfg: DictConfig, seed: int) -> dict[str, np.ndarray]:
    """Run one demonstration; returns its columns (see the module docstring)."""
    control_dt = float(cfg.sim.dt) * int(cfg.sim.control_decimation)
    planned = load_task(cfg.task, control_dt)
    check_dims(planned.dim, sim_class(to_plain(cfg.sim, "sim")).dim, cfg)
    scene = to_plain(cfg.task.scene, "task.scene")
    if scene.get("human") is not None:
        raise ConfigError("task.scene.human", "the task has a simulated human already")
    scene["human"] = human_spec(planned.pattern)
    start = list(planned.start) + (list(planned.pattern.orientation) if planned.dim == 3 else [])
    sim = make_sim(to_plain(cfg.sim, "sim"), scene, start)
    ctrl = make_controller(to_plain(cfg.controller, "controller"))
    ctrl.reset(planned.dim, sim.control_dt)
    steps = int(math.floor((planned.duration + SETTLE_S) / sim.control_dt + 1e-9)) + 1
    rows: dict[str, list[Any]] = {k: [] for k in ("t", "pos", "force", "hand")}
    zero = np.zeros(planned.dim)
    hand_keys = [f"human_f{a}_N" for a in AXES[: planned.dim]]
    obs, info = sim.reset(seed=seed)
    try:
        for k in range(steps):
            rows["t"].append(obs.t)
            rows["pos"].append(obs.position.copy())
            rows["force"].append(-_normal_force(info, planned.dim))
            rows["hand"].append([info.extra.get(key, 0.0) for key in hand_keys])
            if k == steps - 1:
                break
            here = TargetSample(obs.t, obs.position.copy(), zero, zero,
                                planned.pattern.orientation)  # fmt: skip
            obs, info = sim.step(ctrl.step(obs, here))
            reason = check_state_finite(obs, float(cfg.sim.get("max_speed", math.inf)))
            if reason is not None:
                raise SimulationDiverged(reason)
    finally:
        sim.close()
    out = {"t": np.asarray(rows["t"], dtype=float)}
    for name, prefix in (("pos", ""), ("force", "f"), ("hand", "human_f")):
        values = np.asarray(rows[name], dtype=float)
        out.update({f"{prefix}{a}": values[:, i] for i, a in enumerate(AXES[: planned.dim])})
    return out


def _normal_force(info: Any, dim: int) -> np.ndarray:
    """The contact force on the tool, its normal part where the simulator gives one (PyBullet:
    ``normal_force_*``; friction is the demonstration's consequence, not a force target)."""
    keys = [f"normal_force_{a}" for a in AXES[:dim]]
    if all(k in info.extra for k in keys):
        return np.array([info.extra[k] for k in keys], dtype=float)
    return np.asarray(info.contact_force, dtype=float)


def write_demo(columns: dict[str, np.ndarray], out: Path) -> None:
    """Write the columns as CSV (9 significant digits: 1 nm at 1 m) or Parquet, by suffix."""
    import pandas as pd

    frame = pd.DataFrame(columns)
    try:
        with atomic_path(out) as tmp:  # a killed write leaves no half file under the name
            if out.suffix.lower() == ".csv":
                frame.to_csv(tmp, index=False, float_format="%.9g")
            else:
                frame.to_parquet(tmp, index=False)
    except OSError as exc:
        raise ConfigError("--out", f"{out}: cannot write ({exc.strerror or exc})") from None


def check_out(out: Path, force: bool) -> None:
    """Refuse ``--out`` before anything is simulated (issue #39): a directory, an existing
    file without ``--force``, or a place that cannot be written; each as one line."""
    if out.suffix.lower() not in (".csv", ".parquet", ".pq"):
        raise ConfigError("--out", f"{out}: must end in .csv or .parquet")
    if out.is_dir():
        raise ConfigError(
            "--out", f"{out} is a directory; give a file name ending in .csv or .parquet"
        )
    if out.exists() and not force:
        raise ConfigError(
            "--out", f"{out} exists; pass --force to replace it, or choose another name"
        )
    if out.exists() and not out.is_file():
        raise ConfigError("--out", f"{out} is not a regular file; choose another name")
    parent = out.parent
    while not parent.exists():  # the nearest folder that exists must take the new ones
        parent = parent.parent
    if not parent.is_dir() or not os.access(parent, os.W_OK | os.X_OK):
        raise ConfigError("--out", f"{out}: cannot write in {parent}; choose a writable place")


def main(args: Sequence[str]) -> int:
    """``ccm demo TASK --out FILE [--seed N] [--rate HZ] [OVERRIDES…]``: record one
    demonstration (every control step, or every k-th for ``--rate``), write it, print a line."""
    if args and args[0] in ("-h", "--help"):
        print(USAGE)
        return 0
    parser = argparse.ArgumentParser(prog="ccm demo", exit_on_error=False, add_help=False)
    parser.add_argument("task", nargs="?")
    parser.add_argument("--out")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--force", action="store_true")
    parser.add_argument("--rate", type=float)
    try:
        ns, rest = parser.parse_known_args(list(args))
    except argparse.ArgumentError as exc:
        raise ConfigError("demo", f"{exc}; {USAGE}") from None
    bad = [a for a in rest if a.startswith("-") or "=" not in a]
    if ns.task is None or ns.out is None or bad:
        problem = f"unexpected {bad[0]!r}" if bad else "TASK and --out FILE are required"
        raise ConfigError("demo", f"{problem}; {USAGE}")
    out = Path(ns.out)
    check_out(out, ns.force)
    if ns.seed < 0:
        raise ConfigError("--seed", f"must be an integer >= 0, got {ns.seed}")
    cfg = compose_demo(ns.task, rest)
    every = 1  # a smaller file for --rate: every k-th control step
    if ns.rate is not None:
        control_dt = float(cfg.sim.dt) * int(cfg.sim.control_decimation)
        if not 0.0 < ns.rate <= 1.0 / control_dt:
            raise ConfigError("--rate", f"must lie in (0, {1.0 / control_dt:g}] Hz, got {ns.rate}")
        every = max(1, round(1.0 / (ns.rate * control_dt)))
    columns = {name: values[::every] for name, values in record_demo(cfg, ns.seed).items()}
    write_demo(columns, out)
    t = columns["t"]
    print(f"ccm: demonstration of {ns.task} ({len(t)} rows, {t[-1]:.3g} s) -> {out}")
    return 0
