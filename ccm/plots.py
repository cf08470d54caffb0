"""Run figures: path, tracking error, force, stiffness, velocity/acceleration (issue #2)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from ccm.metrics import derivatives, motion_error
from ccm.records import AXES


def _axes_arrays(log: Mapping[str, np.ndarray], prefix: str, dim: int) -> np.ndarray:
    return np.column_stack([log[f"{prefix}_{a}"] for a in AXES[:dim]])


def write_figures(
    fig_dir: Path,
    components: Mapping[str, Any],
    logs: Mapping[str, Sequence[Mapping[str, np.ndarray]]],
    settings: Mapping[str, Any],
) -> list[Path]:
    """Write PNGs comparing the last trial of every condition; return their paths."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig_dir.mkdir(parents=True, exist_ok=True)
    written: list[Path] = []
    last = {name: runs[-1] for name, runs in logs.items() if runs}
    if not last:
        return written
    dim = next(iter(components.values())).task.dim
    colors = plt.rcParams["axes.prop_cycle"].by_key()["color"]

    def save(fig: Any, name: str) -> None:
        path = fig_dir / name
        fig.tight_layout()
        fig.savefig(path, dpi=110)
        plt.close(fig)
        written.append(path)

    # 1. path vs target (x-y plane; 3-D adds x-z)
    n_planes = 1 if dim == 2 else 2
    fig, axs = plt.subplots(1, n_planes, figsize=(5.5 * n_planes, 5), squeeze=False)
    for p, (i, j) in enumerate([(0, 1), (0, 2)][:n_planes]):
        ax = axs[0, p]
        for c, (name, log) in enumerate(last.items()):
            col = colors[c % len(colors)]
            ax.plot(
                log[f"target_pos_{AXES[i]}"],
                log[f"target_pos_{AXES[j]}"],
                "--",
                color=col,
                lw=1,
                alpha=0.7,
                label=f"{name} target",
            )
            ax.plot(
                log[f"pos_{AXES[i]}"],
                log[f"pos_{AXES[j]}"],
                "-",
                color=col,
                lw=1.5,
                label=f"{name} actual",
            )
        ax.set_xlabel(f"{AXES[i]} [m]")
        ax.set_ylabel(f"{AXES[j]} [m]")
        ax.set_aspect("equal", adjustable="datalim")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7)
    fig.suptitle("End-effector path vs target (last trial)")
    save(fig, "path.png")

    # 2. tracking error vs time
    fig, ax = plt.subplots(figsize=(8, 4))
    for name, log in last.items():
        err = motion_error(
            _axes_arrays(log, "pos", dim),
            _axes_arrays(log, "target_pos", dim),
            _axes_arrays(log, "force_dir", dim),
        )
        ax.plot(log["t"], 1000.0 * err, label=name)
    ax.set_xlabel("time [s]")
    ax.set_ylabel("tracking error [mm]")
    ax.set_title("Tracking error in the motion-controlled subspace (last trial)")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    save(fig, "tracking_error.png")

    # 3. measured force vs time (magnitude and components)
    fig, axs = plt.subplots(dim + 1, 1, figsize=(8, 2.0 * (dim + 1)), sharex=True)
    for name, log in last.items():
        f = _axes_arrays(log, "force", dim)
        axs[0].plot(log["t"], np.linalg.norm(f, axis=1), label=name)
        for a in range(dim):
            axs[a + 1].plot(log["t"], f[:, a], label=name)
    axs[0].set_ylabel("|F| [N]")
    for a in range(dim):
        axs[a + 1].set_ylabel(f"F_{AXES[a]} [N]")
    for ax in axs:
        ax.grid(alpha=0.3)
    axs[-1].set_xlabel("time [s]")
    axs[0].legend(fontsize=8)
    axs[0].set_title("Measured external force on the end-effector (F/T sensor, last trial)")
    save(fig, "force.png")

    # 4. stiffness vs time
    fig, ax = plt.subplots(figsize=(8, 3.5))
    for name, log in last.items():
        if "stiffness_Npm" in log:
            ax.plot(log["t"], log["stiffness_Npm"], label=name)
    ax.set_xlabel("time [s]")
    ax.set_ylabel("stiffness K_p [N/m]")
    ax.set_title("Controller stiffness (last trial)")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    save(fig, "stiffness.png")

    # 5. velocity and acceleration vs time
    fig, axs = plt.subplots(2, 1, figsize=(8, 5), sharex=True)
    for name, log in last.items():
        vel = _axes_arrays(log, "vel", dim)
        dt = float(np.median(np.diff(log["t"]))) if len(log["t"]) > 1 else 1.0
        acc, _ = derivatives(vel, dt, float(settings["lowpass_hz"]))
        axs[0].plot(log["t"], np.linalg.norm(vel, axis=1), label=f"{name}")
        axs[1].plot(log["t"], np.linalg.norm(acc, axis=1), label=name)
    tgt = next(iter(last.values()))
    axs[0].plot(
        tgt["t"],
        np.linalg.norm(_axes_arrays(tgt, "target_vel", dim), axis=1),
        "k--",
        lw=1,
        label="target",
    )
    axs[0].set_ylabel("speed [m/s]")
    axs[1].set_ylabel("|acceleration| [m/s²]")
    axs[1].set_xlabel("time [s]")
    axs[0].set_title(
        f"Velocity and acceleration (low-pass {settings['lowpass_hz']} Hz, last trial)"
    )
    for ax in axs:
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
    save(fig, "kinematics.png")
    return written
