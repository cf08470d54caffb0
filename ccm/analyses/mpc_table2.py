"""Seed B Table 2 by replay: the MPC loop rate of each feature on recorded rail data.

Seed B gives its Table 2 rates "as evaluated by playing back the data recorded from the rail
assembly problem" (26.2 Hz baseline down to 10.6 Hz with two modes). This analysis
(``experiment.kind: mpc_table2``, ``configs/experiment/mpc_table2.yaml``) does the same:

1. **Record.** The run's plan (:func:`ccm.experiment.components.plan_experiment`: mpc_rail's
   scene and controller, its ``variance_cost`` condition) runs mpc_rail's three demonstrations
   and then one execution trial, in process, through :func:`ccm.experiment.trial.run_trial`
   with the runner's trial seeds. Kept: the controller after its demonstrations (its fitted
   GP models, and the GP data each demonstration added, read from ``state_dict``), and from
   the execution trial's recorded columns, at every MPC tick, the measured state ξ_t = [x, ẋ]
   (``pos_*``, ``vel_*``), the measured force and the recorded belief.
   Why the recorded columns and not a hook in the controller: the recorder already holds the
   Observation the controller saw at each step, at full precision, so nothing in the runner
   or the controller changes; the ticks follow the controller's own rule (a solve at the
   first step with t ≥ the next multiple of ``mpc_period_s``), and the summary checks that
   the count equals the controller's solves and that the row with the recording controller's
   own settings reproduces its M, D and f^r at every tick.
2. **Replay.** One :class:`ccm.control.mpc.problem.GPMPCProblem` per row of ``table2.rows``:
   the recording controller's ``controller.mpc`` block (horizon, T_s, bounds, weights) with
   ``table2.baseline`` merged on (no variance cost, no constraint), then the row's own
   ``mpc`` block (each feature alone on the baseline). Rows with ``demo_modes`` get one GP
   set per mode, fitted by the controller's own code from the demonstrations' data; their
   belief is Eq. 12 replayed along the recorded force (``belief: eq12``) or uniform. Every
   tick solves every row once, interleaved (:mod:`ccm.analyses.mpc_replay`).
3. **Output.** ``summary.json`` (identical for the same config and seed): per row the ticks,
   IPOPT iterations, unsuccessful solves and the ranges of the applied M and D; the
   recording's checks. ``run_info.json`` (timing): per row ``mpc_cpu_rate_hz``,
   ``mpc_rate_hz``, ``mpc_iterations_median``, ``mpc_ms_per_iteration`` (the shape ``ccm
   report`` joins to the conditions, as for mpc_contact) and ``table2``: each rate and each
   rate ratio to the baseline with its block-bootstrap interval, beside seed B's.
   ``figures/mpc_table2.png``: the rates and ratios beside seed B's.

What a row costs here is what its terms add to ccm's problem, whose baseline differs from
seed B's in one respect that matters for the ratios: Eq. 13 in seed B carries the covariance
Σ as shooting variables in every problem, whereas ccm propagates Σ as an expression (Eq. 8)
that casadi evaluates only when a cost or constraint uses it. ccm's baseline therefore never
evaluates the GP variance (O(M²) per pose for M training points); the model-variance row does.
"""

from __future__ import annotations

import math
import os
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from omegaconf import DictConfig

from ccm.analyses import mpc_replay
from ccm.analyses.mpc_replay import AXES, Variant
from ccm.control.mpc.settings import MPCSettings
from ccm.control.registry import make_controller
from ccm.core.errors import (
    ConfigError,
    check_choice,
    check_int_positive,
    check_keys,
    check_positive,
    check_range,
    config_block,
    to_plain,
)
from ccm.core.records import save_figure, write_json_atomic
from ccm.experiment.components import Components, check_experiment, plan_experiment, trial_seed
from ccm.experiment.config_check import trial_duration
from ccm.experiment.trial import run_trial
from ccm.plots.style import outside_legend

_KEYS = ("baseline", "rows", "bootstrap", "ratios", "seed_b_hz")
_ROW_KEYS = ("mpc", "demo_modes", "belief")
_BOOT_KEYS = ("resamples", "block_ticks", "level")
BASELINE = "baseline"  # the row every rate ratio divides by (seed B Table 2's first row)


def merged(base: Mapping[str, Any], over: Mapping[str, Any]) -> dict[str, Any]:
    """``base`` with ``over`` merged on, mapping into mapping; any other value replaces."""
    out = dict(base)
    for k, v in over.items():
        both = isinstance(v, Mapping) and isinstance(out.get(k), Mapping)
        out[k] = merged(out[k], v) if both else v
    return out


def parse_settings(cfg: DictConfig) -> dict[str, Any]:
    """The ``table2`` block, checked: every row's merged MPC block parses (one ConfigError
    line naming its key otherwise), before anything is simulated."""
    s = config_block(cfg, "table2", _KEYS)
    ctrl = to_plain(cfg.controller)
    if ctrl.get("type") != "gp_mpc" or not isinstance(ctrl.get("mpc"), Mapping):
        raise ConfigError("controller.type", "mpc_table2 replays a gp_mpc controller with an MPC")
    base = merged(ctrl["mpc"], _mapping("table2.baseline", s.get("baseline")))
    MPCSettings.parse(base, "table2.baseline")
    rows = _mapping("table2.rows", s.get("rows"))
    if BASELINE not in rows:
        raise ConfigError("table2.rows", f"needs a row named {BASELINE!r} (the ratios' divisor)")
    n_demos = len(ctrl.get("demo_modes") or [])
    s["rows"] = {name: _row(name, row, base, ctrl, n_demos) for name, row in rows.items()}
    boot = _mapping("table2.bootstrap", s.get("bootstrap"))
    check_keys("table2.bootstrap", boot, _BOOT_KEYS)
    s["bootstrap"] = {
        "resamples": check_int_positive("table2.bootstrap.resamples", boot.get("resamples")),
        "block_ticks": check_int_positive("table2.bootstrap.block_ticks", boot.get("block_ticks")),
        "level": check_range("table2.bootstrap.level", boot.get("level"), 0.5, 0.999),
    }
    s["ratios"] = [_pair(i, p, s["rows"]) for i, p in enumerate(s.get("ratios") or [])]
    seed_b = _mapping("table2.seed_b_hz", s.get("seed_b_hz"))
    check_keys("table2.seed_b_hz", seed_b, list(s["rows"]))
    s["seed_b_hz"] = {k: check_positive(f"table2.seed_b_hz.{k}", v) for k, v in seed_b.items()}
    return s


def _mapping(key: str, value: Any) -> dict[str, Any]:
    if value is None:
        return {}
    if not isinstance(value, Mapping):
        raise ConfigError(key, f"must be a mapping, got {value!r}")
    return dict(value)


def _row(name: str, row: Any, base: Mapping, ctrl: Mapping, n_demos: int) -> dict[str, Any]:
    """One row: its merged MPC block (parsed), its demonstrations' modes and belief rule."""
    key = f"table2.rows.{name}"
    row = _mapping(key, row)
    check_keys(key, row, _ROW_KEYS)
    mpc = merged(base, _mapping(f"{key}.mpc", row.get("mpc")))
    st = MPCSettings.parse(mpc, f"{key}.mpc")
    if st.disturbance is not None and math.isnan(st.disturbance[0]):
        raise ConfigError(f"{key}.mpc.disturbance.alpha", "must be a number [N] in a replay")
    modes = row.get("demo_modes")
    if modes is not None:
        if not isinstance(modes, list) or len(modes) != n_demos:
            raise ConfigError(f"{key}.demo_modes", f"needs one mode per demonstration ({n_demos})")
        make_controller({**ctrl, "demo_modes": modes}, key=key)  # the controller's own checks
    belief = check_choice(f"{key}.belief", row.get("belief", "eq12"), ("eq12", "uniform"))
    return {"mpc": mpc, "demo_modes": modes, "belief": belief}


def _pair(i: int, pair: Any, rows: Mapping[str, Any]) -> tuple[str, str]:
    key = f"table2.ratios[{i}]"
    if not isinstance(pair, list) or len(pair) != 2 or any(p not in rows for p in pair):
        raise ConfigError(key, f"must be [row, row] of {', '.join(rows)}, got {pair!r}")
    return str(pair[0]), str(pair[1])


# ------------------------------------------------------------------------------ record
@dataclass
class Recording:
    """What the replay needs from the recorded trials (module docstring, 1)."""

    controller: Any  # the recording GPMPC, after its demonstrations and the execution trial
    demo_data: list[np.ndarray]  # per demonstration: the GP data rows [x, f] it added
    arrays: dict[str, np.ndarray]  # the execution trial's recorded columns
    ticks: np.ndarray  # indices of the MPC ticks in ``arrays``
    dim: int
    control_dt: float
    report: dict[str, Any]  # the controller's report() after the execution trial

    def columns(self, prefix: str) -> np.ndarray:
        """(n_ticks, dim) of ``<prefix>_<axis>`` at the ticks."""
        return np.column_stack([self.arrays[f"{prefix}_{a}"][self.ticks] for a in AXES[: self.dim]])


def mpc_ticks(t: np.ndarray, period: float) -> np.ndarray:
    """The steps at which :class:`GPMPC` solves: the first with t ≥ the next multiple of
    ``period`` (its rule: ``obs.t + 1e-9 >= next``, then ``next += period``)."""
    out, nxt = [], 0.0
    for k, tk in enumerate(np.asarray(t, dtype=float)):
        if tk + 1e-9 >= nxt:
            out.append(k)
            nxt += period
    return np.asarray(out, dtype=int)


def record(cfg: DictConfig, compose: Callable[[Sequence[str]], DictConfig]) -> Recording:
    """Run the plan's demonstrations and its one execution trial (module docstring, 1)."""
    settings = check_experiment(cfg)
    plan = plan_experiment(cfg, compose, settings["trials"])
    if len(plan) != 1:
        raise ConfigError("experiment.conditions", "mpc_table2 records exactly one condition")
    phases = plan[0][1]
    ctrl = phases[0][1].controller
    counts = [min(ph.trials, settings["trials"]) if settings["fast"] else ph.trials
              for ph, _ in phases]  # fmt: skip
    if sum(counts) != len(ctrl.demo_modes) + 1:
        raise ConfigError("experiment.phases", "must be the demonstrations, then one trial")
    seed, trial, demo_data, rec, comp = int(cfg.seed), 0, [], None, phases[0][1]
    for (_, built), n in zip(phases, counts, strict=True):
        comp = Components(sim=built.sim, task=built.task, controller=ctrl)
        try:
            for _ in range(n):
                trial += 1
                demo, before = ctrl.demonstrating, ctrl.state_dict()["data"]
                duration = trial_duration(comp.task.pattern.duration, settings)
                rec = run_trial(comp, trial_seed(seed, trial), duration, max_extension_s=0.0)
                if demo:
                    demo_data.append(_added_rows(before, ctrl.state_dict()["data"], comp.task.dim))
                ctrl.end_trial()
        finally:
            built.sim.close()
    assert rec is not None
    arrays = rec.arrays()
    return Recording(
        controller=ctrl, demo_data=demo_data, arrays=arrays,
        ticks=mpc_ticks(arrays["t"], ctrl.mpc_period_s), dim=comp.task.dim,
        control_dt=float(comp.sim.control_dt), report=ctrl.report(),
    )  # fmt: skip


def _added_rows(before: Sequence[list], after: Sequence[list], dim: int) -> np.ndarray:
    """The GP data rows [x, f] a demonstration added, over all modes (``state_dict`` data)."""
    added = [np.reshape(a[len(b) :], (-1, 2 * dim)) for a, b in zip(after, before, strict=True)]
    return np.concatenate(added)


# ------------------------------------------------------------------------------ rows
def mode_models(ctrl_cfg: Mapping[str, Any], modes: Sequence[int], rec: Recording, key: str) -> Any:
    """A GPMPC with ``demo_modes`` = ``modes``, fitted by its own code (``load_state_dict``,
    then ``reset``: one GP set per mode, seed B §3.1.1) from the demonstrations' data."""
    ctrl = make_controller({**ctrl_cfg, "demo_modes": list(modes)}, key=key)
    data: list[list[list[float]]] = [[] for _ in range(max(modes) + 1)]
    for m, rows in zip(modes, rec.demo_data, strict=True):
        data[m].extend(rows.tolist())
    ctrl.load_state_dict({"trials_done": len(modes), "data": data, "hf_power": []})
    ctrl.reset(rec.dim, rec.control_dt)
    return ctrl


def eq12_beliefs(models: Sequence[Any], rec: Recording, min_belief: float) -> np.ndarray:
    """The belief a multi-mode GPMPC holds at each tick: Eq. 12 from uniform, updated with
    the measured force at the measured pose (as ``GPMPC._mpc_step``, GP variance + noise)."""
    from ccm.control.mpc.terms import belief_update

    b = np.full(len(models), 1.0 / len(models))
    noise = np.array([[gm.noise_var_ for gm in g.models] for g in models])
    out = []
    for x, f in zip(rec.columns("pos"), rec.columns("force"), strict=True):
        preds = [g.predict(x[None, :]) for g in models]
        means = np.array([p[0][0] for p in preds])
        variances = np.array([p[1][0] for p in preds])
        b = belief_update(b, f, means, variances + noise, min_belief=min_belief)
        out.append(b)
    return np.asarray(out)


def build_variants(s: Mapping[str, Any], rec: Recording, ctrl_cfg: Mapping) -> list[Variant]:
    """One :class:`Variant` per row, starting from the execution trial's initial M, D, f^r."""
    from ccm.control.mpc.problem import GPMPCProblem

    n, ticks = rec.dim, len(rec.ticks)
    start = [np.broadcast_to(np.asarray(ctrl_cfg[k], float), (n,)).copy()
             for k in ("init_mass", "init_damping", "init_f_ref")]  # fmt: skip
    out = []
    for name, row in s["rows"].items():
        key = f"table2.rows.{name}"
        if row["demo_modes"] is None:  # the recording controller's models and belief
            models = rec.controller.models
            n_modes = len(models)
            beliefs = np.column_stack(
                [rec.arrays[f"belief_{m}"][rec.ticks] for m in range(n_modes)]
            )
        else:
            ctrl = mode_models(ctrl_cfg, row["demo_modes"], rec, key)
            models = ctrl.models
            beliefs = (eq12_beliefs(models, rec, ctrl.min_belief) if row["belief"] == "eq12"
                       else np.full((ticks, len(models)), 1.0 / len(models)))  # fmt: skip
        problem = GPMPCProblem([g.casadi_functions() for g in models], n, key=f"{key}.mpc",
                               **row["mpc"])  # fmt: skip
        points = sum(len(g.models[0].alpha_) for g in models)
        out.append(Variant(name, problem, beliefs, *(v.copy() for v in start), gp_points=points))
    return out


# ------------------------------------------------------------------------------ output
def recording_check(rec: Recording, variants: Sequence[Variant], s: Mapping, mpc: Mapping) -> dict:
    """The recording and how faithfully the replay follows it: its ticks against the
    controller's solves, and for a row with the recording controller's own settings and
    models, the largest difference of its M, D, f^r from the recorded ones over the ticks."""
    n = rec.dim
    out: dict[str, Any] = {
        "demonstrations": len(rec.demo_data),
        "demo_gp_rows": [len(d) for d in rec.demo_data],
        "execution_steps": len(rec.arrays["t"]),
        "ticks": len(rec.ticks),
        "controller_solves": int(rec.report["mpc_solves"]),
        "closed_loop_infeasible": int(rec.report["mpc_infeasible"]),
    }
    cols = [f"{p}_{a}_{u}" for p, u in (("mass", "kg"), ("damping", "Nspm"), ("f_ref", "N"))
            for a in AXES[:n]]  # fmt: skip
    recorded = np.column_stack([rec.arrays[c][rec.ticks] for c in cols])
    for v in variants:
        row = s["rows"][v.name]
        if row["demo_modes"] is None and row["mpc"] == mpc:
            diff = np.abs(np.asarray(v.applied) - recorded).max(axis=0)
            out[f"{v.name}_vs_recording_max_abs_diff"] = {
                "mass_kg": float(diff[:n].max()),
                "damping_Nspm": float(diff[n : 2 * n].max()),
                "f_ref_N": float(diff[2 * n :].max()),
            }
    return out


def run_table2(cfg: DictConfig, compose: Callable, out_dir: Path) -> dict[str, Any]:
    """Record, replay and write the run directory (module docstring)."""
    wall0, cpu, c0 = time.perf_counter(), {}, time.process_time()
    s = parse_settings(cfg)
    ctrl_cfg = to_plain(cfg.controller)
    rec = record(cfg, compose)
    cpu["record"], c0 = time.process_time() - c0, time.process_time()
    variants = build_variants(s, rec, ctrl_cfg)
    cpu["build"], c0 = time.process_time() - c0, time.process_time()
    states = np.column_stack([rec.columns("pos"), rec.columns("vel")])
    load = [os.getloadavg()[0]]
    wall_replay = time.perf_counter()
    mpc_replay.replay(variants, states)
    wall_replay = time.perf_counter() - wall_replay
    load.append(os.getloadavg()[0])
    cpu["replay"], c0 = time.process_time() - c0, time.process_time()
    pairs = [(v.name, BASELINE) for v in variants if v.name != BASELINE] + list(s["ratios"])
    info = mpc_replay.timing_info(variants, pairs, s["seed_b_hz"], s["bootstrap"], int(cfg.seed))
    if cfg.experiment.get("figures", True):
        figure(out_dir / "figures" / "mpc_table2.png", info, [v.name for v in variants])
    cpu["figures"] = time.process_time() - c0
    closed = rec.report["timing"]
    info.update(
        wall_time_s=time.perf_counter() - wall0, replay_wall_s=wall_replay, cpu_s=cpu,
        load_avg_1min=load,
        recording_closed_loop={  # the recording controller's own solves, in the closed loop
            "mpc_cpu_rate_hz": 1.0 / float(np.median(closed["mpc_solve_cpu_s"])),
            "mpc_rate_hz": 1.0 / float(np.median(closed["mpc_solve_s"])),
        },
    )  # fmt: skip
    summary = {
        "experiment": str(cfg.experiment.name), "status": "ok", "seed": int(cfg.seed),
        "conditions": {v.name: mpc_replay.row_summary(v, rec.dim) for v in variants},
        "recording": recording_check(rec, variants, s, ctrl_cfg["mpc"]),
        "trials": [],
    }  # fmt: skip
    write_json_atomic(out_dir / "run_info.json", info)
    write_json_atomic(out_dir / "summary.json", summary)
    return summary


def figure(path: Path, info: Mapping[str, Any], names: Sequence[str]) -> None:
    """Per row: the CPU and wall-clock rates (left) and the CPU rate over the baseline's
    (right), with their bootstrap intervals, beside seed B's Table 2."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows, ratios = info["table2"]["rows"], info["table2"]["ratios"]
    x = np.arange(len(names))
    fig, (ax_r, ax_q) = plt.subplots(1, 2, figsize=(12, 4.5))
    for off, key, label, style in ((-0.15, "cpu_rate_hz", "ccm, CPU time", "o"),
                                   (0.0, "wall_rate_hz", "ccm, wall clock", "s")):  # fmt: skip
        _interval_plot(ax_r, x + off, [rows[n][key] for n in names], style, label)
    ax_r.plot(x + 0.15, [rows[n]["seed_b_hz"] or np.nan for n in names], "k*", ms=9,
              label="seed B Table 2")  # fmt: skip
    ax_r.set_yscale("log")
    ax_r.set_ylabel("MPC rate, 1 / median solve time [Hz]")
    keyed = [
        (i, ratios[f"{n}/{BASELINE}"]) for i, n in enumerate(names) if f"{n}/{BASELINE}" in ratios
    ]
    idx = np.array([i for i, _ in keyed])
    _interval_plot(ax_q, idx - 0.1, [r["cpu"] for _, r in keyed], "o", "ccm, CPU time")
    ref = np.array([np.nan if r["seed_b"] is None else r["seed_b"] for _, r in keyed])
    ax_q.plot(idx + 0.1, ref, "k*", ms=9, label="seed B Table 2")
    ax_q.bar(idx + 0.1, 0.5 * ref, bottom=0.75 * ref, width=0.5, color="k", alpha=0.1,
             label="seed B ± 25 % (the claims' band)")  # fmt: skip
    ax_q.axhline(1.0, color="gray", lw=0.8)
    ax_q.set_ylabel(f"MPC rate / {BASELINE} rate [-]")
    for ax in (ax_r, ax_q):
        ax.set_xticks(x, [n.replace("_", " ") for n in names], rotation=20)
        ax.set_xlabel("Table 2 row (each feature alone on the baseline)")
        ax.grid(alpha=0.3)
        outside_legend(ax, "above", fontsize=8, ncol=2)
    fig.suptitle(
        "Seed B Table 2 by replay of a recorded rail trial (error bars: 95 % block bootstrap)"
    )
    path.parent.mkdir(parents=True, exist_ok=True)
    save_figure(fig, path)


def _interval_plot(
    ax: Any, x: np.ndarray, vals: Sequence[Sequence[float]], fmt: str, label: str
) -> None:
    """[value, low, high] per x as a marker with error bars."""
    v = np.asarray(vals, dtype=float).reshape(-1, 3)
    ax.errorbar(x, v[:, 0], yerr=[v[:, 0] - v[:, 1], v[:, 2] - v[:, 0]], fmt=fmt, capsize=3,
                label=label)  # fmt: skip
