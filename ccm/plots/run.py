"""Run figures: path, tracking error, force, stiffness, velocity/acceleration (issue #2)."""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from ccm.core.errors import to_plain
from ccm.core.filters import derivatives
from ccm.core.records import AXES, axes_columns, save_figure
from ccm.metrics.trial import motion_error
from ccm.plots.adaptation import write_stiffness_figure
from ccm.plots.contacts import wants_contact_figures, write_contact_figures
from ccm.plots.modes import write_mode_figures
from ccm.plots.mpc import write_mpc_figures
from ccm.plots.patches import write_patch_figure
from ccm.plots.rail import write_rail_figure
from ccm.plots.style import bound_style, condition_style, nonzero, outside_legend


def figure_inputs(
    components: Mapping[str, Any], settings: Mapping[str, Any], metrics: Mapping[str, Any]
) -> dict[str, Any]:
    """What the figures need of a run besides its time series and trial records, as JSON-ready
    data (the run writes it as ``plot_inputs.json``; ``ccm plots`` reads it back): the task's
    dimension and contacts, each condition's chance-constraint bound f̄ and f^r-target force,
    the low-pass of the derived kinematics and the ``metrics`` config. ``components``:
    condition -> an object with ``task`` (``dim``, ``contacts``) and optionally
    ``controller``."""
    task = next(iter(components.values())).task
    return {
        "dim": int(task.dim),
        "contacts": to_plain(list(getattr(task, "contacts", ()) or ())),
        "chance_bounds": _chance_bounds(components),
        "force_targets": _force_targets_of(components),
        "lowpass_hz": float(settings["lowpass_hz"]),
        "metrics": to_plain(dict(metrics)),
    }


def write_figures(
    fig_dir: Path,
    inputs: Mapping[str, Any],
    logs: Mapping[str, Sequence[Mapping[str, np.ndarray]]],
    trials: Sequence[Mapping[str, Any]] = (),
) -> list[Path]:
    """Write PNGs comparing the last trial of every condition; return their paths.

    ``inputs`` is :func:`figure_inputs`' data; ``logs`` holds each condition's first and
    latest trial's columns. Besides the five standard figures, ``error_vs_trial.png`` appears
    when a condition has several trials, ``force_prediction.png`` when a controller logs
    ``pred_force_N``, and ``modes.png`` / ``mode_stiffness_error.png`` when it logs ``mode``
    (:mod:`ccm.plots.modes`), and ``contact_transitions.png`` / ``patch_transitions.png`` for
    the H4 contacts experiments (:mod:`ccm.plots.contacts`, :mod:`ccm.plots.patches`), and
    ``mpc_*.png`` for the GP-MPC controller (:mod:`ccm.plots.mpc`), ``mpc_rail_damping.png``
    for its rail task (:mod:`ccm.plots.rail`).
    """
    import matplotlib

    matplotlib.use("Agg")

    fig_dir.mkdir(parents=True, exist_ok=True)
    written: list[Path] = []
    last = {name: runs[-1] for name, runs in logs.items() if runs}
    if not last:
        return written
    dim = int(inputs["dim"])
    metrics_cfg = inputs.get("metrics") or {}
    lowpass_hz = float(inputs["lowpass_hz"])

    def save(fig: Any, name: str) -> None:
        path = fig_dir / name
        save_figure(fig, path)
        written.append(path)

    _path_figure(last, save)
    _tracking_error_figure(last, dim, save)
    _force_figure(last, dim, save)
    # stiffness vs time, environment changes marked; per trial (seed A Eq. 4b, Fig. 10a)
    write_stiffness_figure(last, trials, metrics_cfg, save)
    _kinematics_figure(last, dim, lowpass_hz, save)
    _error_vs_trial_figure(trials, save)
    _force_prediction_figure(last, dim, save)
    # contact modes with confidences; stiffness and error around transitions (seed A Figs 9-10)
    write_mode_figures(logs, dim, trials, save)
    # speed, acceleration and force around collisions (seed A §4.5.1, Fig. 16)
    f_d = metrics_cfg.get("impact_force_target_N")
    write_contact_figures(logs, dim, trials, lowpass_hz, save, f_d)
    if wants_contact_figures(logs, trials):  # impact-less transitions (seed A Figs 19-20)
        write_patch_figure(logs, inputs.get("contacts") or (), dim, lowpass_hz, save)
    # seed B GP-MPC: contact force, impedance, belief (seed B Figs 6, 8, 11)
    bounds, targets = (dict(inputs.get(k) or {}) for k in ("chance_bounds", "force_targets"))
    write_mpc_figures(last, dim, save, bounds, targets)
    # seed B rail task: damping against the distance to the rail (seed B Fig. 8)
    write_rail_figure(fig_dir.parent, trials, dim, metrics_cfg, save)
    return written


Logs = Mapping[str, Mapping[str, np.ndarray]]
Save = Callable[[Any, str], None]


def _path_figure(last: Logs, save: Save) -> None:
    """Path vs target in the x-y plane; one panel per condition when there are several."""
    import matplotlib.pyplot as plt

    names = list(last)
    ncol = 1 if len(names) <= 2 else min(4, len(names))
    nrow = 1 if len(names) <= 2 else -(-len(names) // ncol)
    panels = [names] if len(names) <= 2 else [[n] for n in names]
    fig, axs = plt.subplots(nrow, ncol, figsize=(4.2 * ncol, 4.2 * nrow), squeeze=False)
    for p, group in enumerate(panels):
        ax = axs.flat[p]
        for name in group:
            log = last[name]
            ax.plot(
                log["target_pos_x"],
                log["target_pos_y"],
                "k--",
                lw=1,
                alpha=0.6,
                zorder=3,  # above the path, which hides it wherever tracking is good
                label="target" if name == group[0] else None,
            )
            style = condition_style(names.index(name), len(log["pos_x"]))
            ax.plot(log["pos_x"], log["pos_y"], lw=1.5, label=name, **style)
        ax.set_xlabel("x [m]")
        ax.set_ylabel("y [m]")
        ax.set_aspect("equal", adjustable="datalim")
        ax.grid(alpha=0.3)
        outside_legend(ax, "above", ncol=2)
    for ax in list(axs.flat)[len(panels) :]:
        ax.set_visible(False)
    fig.suptitle("End-effector path vs target (last trial)")
    save(fig, "path.png")


def _tracking_error_figure(last: Logs, dim: int, save: Save) -> None:
    """Tracking error in the motion-controlled subspace vs time."""
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(8, 4))
    for c, (name, log) in enumerate(last.items()):
        err = motion_error(
            axes_columns(log, "pos", dim),
            axes_columns(log, "target_pos", dim),
            axes_columns(log, "force_dir", dim),
        )
        ax.plot(log["t"], 1000.0 * err, label=name, **condition_style(c, len(err)))
    ax.set_xlabel("time [s]")
    ax.set_ylabel("tracking error [mm]")
    ax.set_title("Tracking error in the motion-controlled subspace (last trial)")
    ax.grid(alpha=0.3)
    outside_legend(ax, fontsize=8)
    save(fig, "tracking_error.png")


def _force_figure(last: Logs, dim: int, save: Save) -> None:
    """Measured force vs time: magnitude and components."""
    import matplotlib.pyplot as plt

    fig, axs = plt.subplots(dim + 1, 1, figsize=(9, 2.0 * (dim + 1)), sharex=True)
    for c, (name, log) in enumerate(last.items()):
        f = axes_columns(log, "force", dim)
        style = condition_style(c, len(f))
        axs[0].plot(log["t"], np.linalg.norm(f, axis=1), label=name, **style)
        for a in range(dim):
            axs[a + 1].plot(log["t"], f[:, a], label=name, **style)
    _force_targets(axs[0], last)
    axs[0].set_ylabel("|F| [N]")
    for a in range(dim):
        axs[a + 1].set_ylabel(f"F_{AXES[a]} [N]")
    for ax in axs:
        ax.grid(alpha=0.3)
    axs[-1].set_xlabel("time [s]")
    outside_legend(axs[0], fontsize=8)
    axs[0].set_title("Measured external force on the end-effector (F/T sensor, last trial)")
    save(fig, "force.png")


def _kinematics_figure(last: Logs, dim: int, lowpass_hz: Any, save: Save) -> None:
    """Speed and acceleration magnitude vs time (acceleration low-passed, ``lowpass_hz``)."""
    import matplotlib.pyplot as plt

    fig, axs = plt.subplots(2, 1, figsize=(9, 5), sharex=True)
    for c, (name, log) in enumerate(last.items()):
        vel = axes_columns(log, "vel", dim)
        dt = float(np.median(np.diff(log["t"]))) if len(log["t"]) > 1 else 1.0
        acc, _ = derivatives(vel, dt, float(lowpass_hz))
        style = condition_style(c, len(vel))
        axs[0].plot(log["t"], np.linalg.norm(vel, axis=1), label=f"{name}", **style)
        axs[1].plot(log["t"], np.linalg.norm(acc, axis=1), label=name, **style)
    tgt = next(iter(last.values()))
    axs[0].plot(
        tgt["t"],
        np.linalg.norm(axes_columns(tgt, "target_vel", dim), axis=1),
        "k--",
        lw=1,
        zorder=3,  # above the conditions' speeds, which hide it wherever tracking is good
        label="target",
    )
    axs[0].set_ylabel("speed [m/s]")
    axs[1].set_ylabel("|acceleration| [m/s²]")
    axs[1].set_xlabel("time [s]")
    axs[0].set_title(f"Velocity and acceleration (low-pass {lowpass_hz} Hz, last trial)")
    for ax in axs:
        ax.grid(alpha=0.3)
    outside_legend(axs[0], fontsize=8)
    save(fig, "kinematics.png")


def _error_vs_trial_figure(trials: Sequence[Mapping[str, Any]], save: Save) -> None:
    """RMS tracking error over repeated trials (learning across trials, e.g. BAC, seed A
    Fig. 7); only when a condition has several trials."""
    import matplotlib.pyplot as plt

    by_cond: dict[str, list[tuple[int, float]]] = {}
    for tr in trials:
        if isinstance(tr.get("rms_tracking_error_m"), float):
            by_cond.setdefault(tr["condition"], []).append(
                (tr["trial"], tr["rms_tracking_error_m"])
            )
    if not any(len(v) > 1 for v in by_cond.values()):
        return
    fig, ax = plt.subplots(figsize=(8, 4))
    for c, (name, pts) in enumerate(by_cond.items()):
        xs, ys = zip(*pts, strict=True)
        style = condition_style(c) | {"markevery": 1}  # a marker on every trial
        ax.plot(xs, 1000.0 * np.asarray(ys), label=name, **style)
    ax.set_xlabel("trial")
    ax.xaxis.get_major_locator().set_params(integer=True)  # no ticks between trials
    ax.set_ylabel("RMS tracking error [mm]")
    ax.set_yscale("log")
    ax.set_title("Tracking error over repeated trials")
    ax.grid(alpha=0.3, which="both")
    outside_legend(ax, fontsize=8)
    save(fig, "error_vs_trial.png")


def _force_prediction_figure(last: Logs, dim: int, save: Save) -> None:
    """Force predicted one model step (horizon_s) earlier vs measured (seed A Fig. 4); only
    for controllers that log ``pred_force_N``."""
    import matplotlib.pyplot as plt

    pred = {n: log for n, log in last.items() if "pred_force_N" in log}
    if not pred:
        return
    fig, axs = plt.subplots(len(pred), 1, figsize=(9, 2.8 * len(pred)), sharex=True, squeeze=False)
    for ax, (name, log) in zip(axs[:, 0], pred.items(), strict=True):
        f = np.linalg.norm(axes_columns(log, "force", dim), axis=1)
        ax.plot(log["t"], f, color="tab:green", lw=1.2, label="measured |F|")
        ax.plot(log["t"], log["pred_force_N"], color="tab:red", lw=1,
                label="predicted |F| (from S_{t-H})")  # fmt: skip
        ax.set_ylabel("|F| [N]")
        ax.set_title(name, fontsize=9)
        ax.grid(alpha=0.3)
        if "truth_viscosity_Nspm" in log:
            ax2 = ax.twinx()
            ax2.plot(log["t"], log["truth_viscosity_Nspm"], color="0.5", lw=0.8, ls=":",
                     label="viscosity (truth, right axis)")  # fmt: skip
            ax2.set_ylabel("viscosity [N s/m]", color="0.4")
            handles = ax.get_legend_handles_labels()[0] + ax2.get_legend_handles_labels()[0]
            outside_legend(ax, "above", handles=handles, fontsize=8)
        else:
            outside_legend(ax, "above", fontsize=8)
    axs[-1, 0].set_xlabel("time [s]")
    fig.suptitle("Force predicted one model step (horizon_s) earlier (last trial)")
    save(fig, "force_prediction.png")


def _force_targets(ax: Any, last: Logs) -> None:
    """The hybrid force loop's target (``force_target_N``, seed A Eq. 1 u_fc) of each
    condition that sets one, dashed grey where it is not 0; labelled once."""
    label = "force target u_fc (task)"
    for log in last.values():
        target = log.get("force_target_N")
        if target is not None and np.any(np.asarray(target) != 0.0):
            ax.step(log["t"], nonzero(target), where="post", label=label, **bound_style("target"))
            label = None


def _chance_bounds(components: Mapping[str, Any]) -> dict[str, float]:
    """Condition -> the f̄ [N] of its GP-MPC chance constraint (Eq. 18), where it has one."""
    out = {}
    for name, comp in components.items():
        ctrl = getattr(comp, "controller", None)  # a figure-only caller may pass none
        chance = (getattr(ctrl, "mpc_cfg", None) or {}).get("chance") or {}
        if "f_max" in chance:
            out[name] = float(chance["f_max"])
    return out


def _force_targets_of(components: Mapping[str, Any]) -> dict[str, float]:
    """Condition -> ‖f_target‖ [N] of its GP-MPC f^r-target cost (seed B §6.2), where the cost
    is weighted and the target is not 0."""
    out = {}
    for name, comp in components.items():
        cfg = getattr(getattr(comp, "controller", None), "mpc_cfg", None) or {}
        weight = float((cfg.get("weights") or {}).get("f_ref_target", 0.0) or 0.0)
        norm = float(np.linalg.norm(np.atleast_1d(np.asarray(cfg.get("f_ref_target", 0.0), float))))
        if weight > 0.0 and norm > 0.0:
            out[name] = norm
    return out
