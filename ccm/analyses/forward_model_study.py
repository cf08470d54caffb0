"""How far ahead must a forward model predict to know more than the last reading? (issue #16)

Seed A's forward model predicts D_{t+1} from S_t (Eq. 6) with ‖F_t‖ among the inputs. At a
1 kHz control step under sensor noise, persistence (D̂_{t+1} = D_t) is as good as any model,
so λ and K_p of Eq. 4b–4c cannot react to what the model knows. This analysis
(``experiment.kind: forward_model_horizon``) measures the skill of the models against the
horizon H over which they predict, on the same recorded data:

1. **Data.** For each task in ``fm_study.tasks``, one *train* and one *test* trial recorded
   with ``fm_study.recorder`` (a fixed-gain controller, so every model and horizon sees the
   same trajectories), with the task's train / test overrides (porridge stirring: seed A
   §4.1's 0 → 80 and 0 → 150 N s/m ramps).
2. **Models**, per horizon H (in control steps), on the pairs X_t = [S_{t−H}, D_t] of Eq. 2–3:
   ``persistence`` (D̂_t = D_{t−H}); ``igmm`` (the controller's incremental model, streamed
   through the train trial, then predicting each test pair before learning it, as in closed
   loop); ``fixed_gmm_k<k>`` (scikit-learn GMM fit on the train pairs, frozen) for each k in
   ``fixed_components``; ``fixed_gmm_selected``: the k with the lowest GMR prediction RMSE on
   the last ``holdout_frac`` of the train trial when fit on the rest (training data only).
3. **Scores** on the test trial: ``pred_rmse_N`` of ‖F‖, ``pred_skill`` = 1 − RMSE /
   RMSE_persistence, and the same on the unseen range (viscosity above the task's
   ``unseen_above_Nspm``) as ``*_unseen``.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from omegaconf import DictConfig

from ccm.core.errors import ConfigError, check_int_positive, check_range, config_block
from ccm.core.records import write_json_atomic
from ccm.experiment.components import build_components, trial_seed
from ccm.experiment.trial import run_trial
from ccm.learn.mixtures.forecast import horizon_steps
from ccm.learn.mixtures.forward_model import N_STATE, make_forward_model
from ccm.metrics.adaptation import skill

_KEYS = ("recorder", "tasks", "horizons_s", "fixed_components", "holdout_frac", "forward_model")
_TASK_KEYS = ("train", "test", "unseen_above_Nspm")


def _settings(cfg: DictConfig) -> dict[str, Any]:
    s = config_block(cfg, "fm_study", _KEYS)
    if not s.get("tasks"):
        raise ConfigError("fm_study.tasks", "must name at least one task")
    for name, task in s["tasks"].items():
        if not isinstance(task, Mapping) or set(task) - set(_TASK_KEYS):
            raise ConfigError(f"fm_study.tasks.{name}", f"allowed keys: {', '.join(_TASK_KEYS)}")
    if not s.get("horizons_s"):
        raise ConfigError("fm_study.horizons_s", "must list at least one horizon [s]")
    s["fixed_components"] = [
        check_int_positive(f"fm_study.fixed_components[{i}]", k)
        for i, k in enumerate(s.get("fixed_components") or [])
    ]
    s["holdout_frac"] = check_range("fm_study.holdout_frac", s.get("holdout_frac", 0.2), 0.05, 0.5)
    s["max_time_s"] = None
    if cfg.experiment.get("fast", False):  # tests: two horizons, two sizes, 1 s trials
        s |= {"horizons_s": s["horizons_s"][:2], "fixed_components": s["fixed_components"][:2],
              "max_time_s": max(float(cfg.experiment.get("fast_time_s", 0.5)), 1.0)}  # fmt: skip
    return s


def record_states(comp: Any, seed: int, duration_s: float) -> tuple[np.ndarray, np.ndarray]:
    """One trial's S_t of Eq. 2 per control step, and the true viscosity (NaN if none)."""
    a = run_trial(comp, seed, duration_s).arrays()
    dim = comp.task.dim
    rot = ("z",) if dim == 2 else ("x", "y", "z")
    col = lambda p, axes: np.column_stack([a[f"{p}_{k}"] for k in axes])  # noqa: E731
    vel, force = col("vel", "xyz"[:dim]), col("force", "xyz"[:dim])
    ang = np.zeros((len(vel), 1)) if "ang_vel_z" not in a else col("ang_vel", rot)
    torque = col("torque", rot)
    s = np.column_stack([np.linalg.norm(x, axis=1) for x in (vel, ang, force, torque)])  # Eq. 2
    return s, a.get("truth_viscosity_Nspm", np.full(len(s), np.nan))


def _record(s: Mapping[str, Any], compose: Callable, seed: int) -> tuple[dict, float]:
    """train/test states of every task (module docstring, 1), and the control period [s]."""
    out: dict[str, dict[str, Any]] = {}
    trial, dt = 0, 0.0
    for name, task in s["tasks"].items():
        out[name] = {"unseen_above_Nspm": task.get("unseen_above_Nspm")}
        for split in ("train", "test"):
            trial += 1
            comp = build_components(compose([f"controller={s['recorder']}", *task[split]]))
            dt = float(comp.sim.control_dt)
            try:
                duration = comp.task.pattern.duration
                if s["max_time_s"] is not None:
                    duration = min(duration, s["max_time_s"])
                out[name][split] = record_states(comp, trial_seed(seed, trial), duration)
            finally:
                comp.sim.close()
    return out, dt


def _pairs(states: np.ndarray, h: int) -> tuple[np.ndarray, np.ndarray]:
    """(S_{t−H}, D_t) for every t >= H."""
    return states[:-h], states[h:, 2:N_STATE]


def _predict(model: Any, x: np.ndarray) -> np.ndarray:
    return np.array([model.predict(xi)[0] for xi in x])


def _fixed(x: np.ndarray, y: np.ndarray, k: int, fm_cfg: Mapping[str, Any]) -> Any:
    """The frozen GMM with ``k`` components fit on the pairs (x, y)."""
    sub = {**(fm_cfg.get("fixed_gmm") or {}), "fit_steps": len(x), "n_components": k}
    model = make_forward_model(
        {**fm_cfg, "kind": "fixed_gmm", "fixed_gmm": sub}, "fm_study.forward_model"
    )
    for xi, yi in zip(x, y, strict=True):
        model.update(xi, yi)
    return model


def _select_k(x: np.ndarray, y: np.ndarray, ks: Sequence[int], frac: float, fm: Mapping) -> int:
    """The k whose GMR predicts the last ``frac`` of the train pairs best, fit on the rest."""
    cut = int(round(len(x) * (1.0 - frac)))
    rmse = {k: float(np.sqrt(np.mean((_predict(_fixed(x[:cut], y[:cut], k, fm), x[cut:])
                                       - y[cut:, 0]) ** 2))) for k in ks}  # fmt: skip
    return min(rmse, key=lambda k: (rmse[k], k))


def _igmm(xtr, ytr, xte, yte, fm_cfg: Mapping[str, Any]) -> np.ndarray:  # noqa: ANN001
    model = make_forward_model(dict(fm_cfg), "fm_study.forward_model")
    for xi, yi in zip(xtr, ytr, strict=True):
        model.update(xi, yi)
    pred = np.empty(len(xte))
    for i, (xi, yi) in enumerate(zip(xte, yte, strict=True)):
        pred[i] = model.predict(xi)[0]  # before the pair is seen (closed-loop order)
        model.update(xi, yi)
    return pred


def _scores(pred: np.ndarray, y: np.ndarray, persist: np.ndarray, unseen: np.ndarray) -> dict:
    def rmse(p: np.ndarray, rows: np.ndarray) -> float | None:
        return float(np.sqrt(np.mean((p[rows] - y[rows]) ** 2))) if rows.any() else None

    every = np.ones(len(y), dtype=bool)
    out: dict[str, float | None] = {}
    for suffix, rows in (("", every), ("_unseen", unseen)):
        m, p = rmse(pred, rows), rmse(persist, rows)
        out[f"pred_rmse{suffix}_N"], out[f"pred_skill{suffix}"] = m, skill(m, p)
    return out


def evaluate(data: Mapping[str, Any], s: Mapping[str, Any], dt: float) -> list[dict[str, Any]]:
    """Rows {task, horizon_s, model, scores} (module docstring, 2-3)."""
    rows: list[dict[str, Any]] = []
    fm = dict(s.get("forward_model") or {})
    for task, d in data.items():
        for i, hs in enumerate(s["horizons_s"]):
            h = horizon_steps(hs, dt, f"fm_study.horizons_s[{i}]")
            fm_h = {**fm, "horizon_s": float(hs)}  # the models' label of their horizon
            xtr, ytr = _pairs(d["train"][0], h)
            xte, yte = _pairs(d["test"][0], h)
            limit = d["unseen_above_Nspm"]
            visc = d["test"][1][h:]
            unseen = visc > float(limit) if limit is not None else np.zeros(len(yte), bool)
            y, persist = yte[:, 0], xte[:, 2]
            preds = {"persistence": persist, "igmm": _igmm(xtr, ytr, xte, yte, fm_h)}
            for k in s["fixed_components"]:
                preds[f"fixed_gmm_k{k}"] = _predict(_fixed(xtr, ytr, k, fm_h), xte)
            extra: dict[str, Any] = {}
            if s["fixed_components"]:
                k = _select_k(xtr, ytr, s["fixed_components"], s["holdout_frac"], fm_h)
                preds["fixed_gmm_selected"] = preds[f"fixed_gmm_k{k}"]
                extra["fixed_gmm_selected"] = {"selected_k": float(k)}
            for name, pred in preds.items():
                scores = _scores(pred, y, persist, unseen)
                row = {"task": task, "horizon_s": float(hs), "model": name, **scores}
                rows.append({**row, **extra.get(name, {})})
    return rows


def run_study(cfg: DictConfig, compose: Callable, out_dir: Path) -> dict[str, Any]:
    """Run the study and write ``summary.json`` (conditions ``<task>/h<ms>ms/<model>``)."""
    s = _settings(cfg)
    data, dt = _record(s, compose, int(cfg.seed))
    rows = evaluate(data, s, dt)
    summary = {
        "experiment": str(cfg.experiment.name),
        "status": "ok",
        "seed": int(cfg.seed),
        "conditions": {
            f"{r['task']}/h{r['horizon_s'] * 1e3:g}ms/{r['model']}": {
                k: v for k, v in r.items() if k not in ("task", "horizon_s", "model")
            }
            for r in rows
        },
        "trials": rows,
    }
    write_json_atomic(out_dir / "summary.json", summary)
    return summary
