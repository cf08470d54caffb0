"""H3 (seed A §4.4, Figs 11-14): the offline long-horizon SVM + GP baseline (Khader et al.
2020, :class:`ccm.learn.svm_gp.ModalGPDynamics`) against ccm's incremental forward model.

An experiment with ``experiment.kind: h3`` runs :func:`run_h3` instead of the trial loop
(``experiment.fast``: one trial of ≥ 2.5 s per dataset, two training frictions):

1. **Data** (:mod:`ccm.h3_data`): ``table_wall`` trials with a fixed-gain controller, or the
   datasets of a previous run (``h3.data_from``). ``medium_multi``: medium stiffness, wall
   friction ``train_frictions`` (seed A: 0.1-0.7); ``medium_single``: medium, one friction
   (0.6; medium_multi's trials at that friction when it has them); ``high_multi``: high
   stiffness, the same frictions; ``medium_test`` / ``high_test``: the test friction (0.9).
   Saved as ``data/<name>.npz``.
2. **Variants** (seed A §4.4.1-4.4.3), on the data subsampled every ``subsample`` steps:
   ``joint_single`` / ``joint_multi`` / ``joint_high``: (i) joint space, X = [q, q̇] → next,
   rolled out over the whole test trial from its first state; ``task_long``: (ii)
   X = [F, ẋ] → next F, rolled out with the test trial's measured ẋ as exogenous input;
   ``task_one_step``: (iii) the same model fed the real [F_t, ẋ_t] every step; ``igmm``:
   ccm's incremental forward model (IGMM + GMR, Eq. 2-6), trained by streaming the
   training trials through it and revised online during the test trial, one step ahead,
   on ‖F‖ (its features are magnitudes; ‖ω‖ and ‖τ‖ are taken as 0: the data hold neither,
   and the tool's orientation is held); ``persistence``: ‖F̂_{t+1}‖ = ‖F_t‖, the naive
   reference every one-step predictor must beat.
3. **Metrics** per variant, averaged over the test trials: ``joint_pred_rmse_rad`` (all 7
   joints), ``force_pred_rmse_N`` (on ‖F‖, the quantity every variant can be scored on;
   ``force_pred_rmse_wall_N`` on the steps in contact with the wall, the unseen friction),
   ``force_y_pred_rmse_N`` (along the wall, seed A Figs 13-14; GP variants only),
   ``coverage_95`` (fraction of true values inside mean ± 1.96 std;
   ``coverage_95_wall`` after the wall contact), the mean band width
   ``band_width_rad`` / ``band_width_N`` and ``joint_lag_s`` (the delay that best aligns the
   true joint trajectory with the prediction; > 0: the truth lags, seed A Fig. 11). Training and
   prediction times are wall-clock facts and go to ``run_info.json`` (``make bench``).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from omegaconf import DictConfig

from ccm.errors import ConfigError, check_int_positive, config_block
from ccm.h3_data import collect, load_dataset, save_dataset
from ccm.learn.forward_model import N_STATE, make_forward_model
from ccm.learn.svm_gp import ModalGPDynamics
from ccm.records import write_json_atomic

_KEYS = (
    "controllers", "train_frictions", "trials_per_friction", "single_friction", "single_trials",
    "test_friction", "test_trials", "subsample", "baseline", "forward_model", "data_from",
    "max_time_s",
)  # fmt: skip
Trial = Mapping[str, np.ndarray]


def _settings(cfg: DictConfig) -> dict[str, Any]:
    h3 = config_block(cfg, "h3", _KEYS)
    for k in ("trials_per_friction", "single_trials", "test_trials", "subsample"):
        h3[k] = check_int_positive(f"h3.{k}", h3.get(k))
    if not h3.get("train_frictions"):
        raise ConfigError("h3.train_frictions", "must list at least one wall friction")
    if cfg.experiment.get("fast", False):  # tests: one short trial per dataset
        fast_s = float(cfg.experiment.get("fast_time_s", 0.5))
        h3 |= {
            "trials_per_friction": 1, "single_trials": 1, "test_trials": 1,
            "train_frictions": h3["train_frictions"][:2], "max_time_s": max(fast_s, 2.5),
        }  # fmt: skip
    return h3


def _datasets(h3: Mapping[str, Any], cfg: DictConfig, compose: Callable, out_dir: Path) -> dict:
    """The five datasets of the module docstring: recorded now, or read from ``data_from``."""
    specs = {
        "medium_multi": ("medium", h3["train_frictions"], h3["trials_per_friction"]),
        "medium_single": ("medium", [h3["single_friction"]], h3["single_trials"]),
        "high_multi": ("high", h3["train_frictions"], h3["trials_per_friction"]),
        "medium_test": ("medium", [h3["test_friction"]], h3["test_trials"]),
        "high_test": ("high", [h3["test_friction"]], h3["test_trials"]),
    }
    out = {}
    first = 1
    for name, (ctl, frictions, n) in specs.items():
        path = out_dir / "data" / f"{name}.npz"
        if h3.get("data_from"):
            out[name], _ = load_dataset(Path(h3["data_from"]) / "data" / f"{name}.npz")
            save_dataset(path, out[name], {"copied_from": str(h3["data_from"])})
            continue
        controller = h3["controllers"][ctl]
        subset = _single_friction_subset(name, out, h3)
        if subset is not None:  # the same controller and friction: reuse, do not re-record
            meta = {"controller": controller, "frictions": list(frictions), "seed": int(cfg.seed),
                    "subset_of": "medium_multi"}  # fmt: skip
            save_dataset(path, subset, meta)
            out[name] = subset
            continue
        trials = collect(
            compose, [f"controller={controller}"], frictions, n, int(cfg.seed),
            first_trial=first, max_time_s=h3.get("max_time_s"),
        )  # fmt: skip
        first += len(trials)
        meta = {"controller": controller, "frictions": list(frictions), "seed": int(cfg.seed)}
        save_dataset(path, trials, meta)
        out[name] = trials
    return out


def _single_friction_subset(name: str, out: Mapping[str, list], h3: Mapping) -> list | None:
    """``medium_single`` as the first ``single_trials`` trials of ``medium_multi`` at
    ``single_friction``, when that set holds enough of them (None otherwise: record anew).

    Both sets use the same controller, so trials at the same friction differ only in their
    sensor noise; reusing them saves recording time and makes the single-friction training
    set a subset of the multi-friction one (seed A §4.4.1 trains on each)."""
    if name != "medium_single" or "medium_multi" not in out:
        return None
    mu = float(h3["single_friction"])
    same = [tr for tr in out["medium_multi"] if float(tr["wall_friction"]) == mu]
    return same[: h3["single_trials"]] if len(same) >= h3["single_trials"] else None


def _sub(tr: Trial, k: int) -> dict[str, np.ndarray]:
    return {f: (v[::k] if np.ndim(v) else v) for f, v in tr.items()}


def _pairs(trials: Sequence[Trial], inputs: Callable[[Trial], np.ndarray], n_out: int) -> tuple:
    """(X_t, Y_{t+1}, mode_t) stacked over trials; Y = the first ``n_out`` input columns."""
    xs, ys, ms = [], [], []
    for tr in trials:
        x = inputs(tr)
        xs.append(x[:-1])
        ys.append(x[1:, :n_out])
        ms.append(tr["mode"][:-1])
    return np.vstack(xs), np.vstack(ys), np.concatenate(ms)


def _joint(tr: Trial) -> np.ndarray:
    return np.hstack([tr["q"], tr["dq"]])


def _task(tr: Trial) -> np.ndarray:
    return np.hstack([tr["force"], tr["velocity"]])


def _lag(truth: np.ndarray, pred: np.ndarray, dt: float, max_s: float = 2.0) -> float:
    """Delay [s] that best aligns the truth with the prediction (least squares over the
    overlap): > 0 when the truth lags the prediction (seed A Fig. 11), < 0 when it leads."""
    n = len(truth)
    best, best_k = math.inf, 0
    for k in range(-int(max_s / dt), int(max_s / dt) + 1):
        a, b = (truth[k:], pred[: n - k]) if k >= 0 else (truth[: n + k], pred[-k:])
        err = float(np.mean((a - b) ** 2))
        if err < best:
            best, best_k = err, k
    return best_k * dt


def _coverage(truth: np.ndarray, mean: np.ndarray, std: np.ndarray) -> float:
    return float(np.mean(np.abs(truth - mean) <= 1.96 * std))


def _rmse(a: np.ndarray, b: np.ndarray) -> float | None:
    """Root-mean-square difference; None for no samples (e.g. a trial that never reached
    the wall)."""
    d = np.asarray(a) - np.asarray(b)
    return float(np.sqrt(np.mean(d**2))) if d.size else None


def _fit(train: Sequence[Trial], inputs: Callable, n_out: int, h3: Mapping, seed: int) -> tuple:
    x, y, m = _pairs(train, inputs, n_out)
    model = ModalGPDynamics(**dict(h3.get("baseline") or {}), seed=seed, key="h3.baseline")
    t0 = time.perf_counter()
    model.fit(x, y, m)
    return model, time.perf_counter() - t0


def _igmm(train: Sequence[Trial], test: Trial, h3: Mapping) -> tuple[np.ndarray, float, float]:
    """One-step ‖F‖ predictions of the incremental model on ``test`` (module docstring)."""
    fm = make_forward_model(dict(h3.get("forward_model") or {}), "h3.forward_model")

    def states(tr: Trial) -> np.ndarray:
        s = np.zeros((len(tr["t"]), N_STATE))
        s[:, 0] = np.linalg.norm(tr["velocity"], axis=1)
        s[:, 2] = np.linalg.norm(tr["force"], axis=1)
        return s

    t0 = time.perf_counter()
    for tr in train:
        s = states(tr)
        for k in range(1, len(s)):
            fm.update(s[k - 1], s[k, 2:])
    t_train = time.perf_counter() - t0
    s = states(test)
    pred = np.full(len(s), np.nan)
    t0 = time.perf_counter()
    for k in range(1, len(s)):
        pred[k] = fm.predict(s[k - 1])[0]  # D̂_k from S_{k-1}, before D_k is seen
        fm.update(s[k - 1], s[k, 2:])  # then learn from it (incremental, seed A §3.1)
    return pred, t_train, time.perf_counter() - t0


def evaluate(
    data: Mapping[str, Sequence[Trial]], h3: Mapping, seed: int
) -> tuple[list[dict[str, Any]], dict[str, float], dict[str, dict[str, np.ndarray]]]:
    """Per-test-trial metrics of every variant, the wall-clock times, and the first test
    trial's curves for the figures (``t``, ``truth``, ``mean``, ``std``, ``contact_t``: the
    wall contact); see the module docstring."""
    k = h3["subsample"]
    d = {name: [_sub(tr, k) for tr in trials] for name, trials in data.items()}
    rows: list[dict[str, Any]] = []
    times: dict[str, float] = {}
    curves: dict[str, dict[str, np.ndarray]] = {}

    def curve(name: str, tr: Trial, truth, mean, std=None) -> None:
        if name not in curves:
            wall = np.flatnonzero(tr["mode"] == 2)
            curves[name] = {
                "t": tr["t"][1:], "truth": truth, "mean": mean,
                "std": np.full_like(mean, np.nan) if std is None else std,
                "contact_t": np.array(tr["t"][wall[0]] if wall.size else np.nan),
            }  # fmt: skip

    joint = {"joint_single": ("medium_single", "medium_test"),
             "joint_multi": ("medium_multi", "medium_test"),
             "joint_high": ("high_multi", "high_test")}  # fmt: skip
    for name, (train, test) in joint.items():
        model, times[f"{name}_train_s"] = _fit(d[train], _joint, 14, h3, seed)
        t0 = time.perf_counter()
        for i, tr in enumerate(d[test], start=1):
            x = _joint(tr)
            mean, std, _ = model.rollout(x[0], len(x) - 1)
            truth = x[1:]
            rows.append({
                "condition": name, "trial": i,
                "joint_pred_rmse_rad": _rmse(mean[:, :7], truth[:, :7]),
                "coverage_95": _coverage(truth[:, :7], mean[:, :7], std[:, :7]),
                "band_width_rad": float(np.mean(2 * 1.96 * std[:, :7])),
                "joint_lag_s": _lag(truth[:, :7], mean[:, :7], float(np.median(np.diff(tr["t"])))),
            })  # fmt: skip
            curve(name, tr, truth[:, 0], mean[:, 0], std[:, 0])  # joint 1 (seed A Fig. 11)
        times[f"{name}_predict_s"] = time.perf_counter() - t0
    model, times["task_train_s"] = _fit(d["medium_multi"], _task, 3, h3, seed)
    for i, tr in enumerate(d["medium_test"], start=1):
        x = _task(tr)
        truth = x[1:, :3]
        t0 = time.perf_counter()
        mean, std, _ = model.rollout(x[0], len(x) - 1, exog=x[:, 3:])
        times["task_long_predict_s"] = (
            times.get("task_long_predict_s", 0.0) + time.perf_counter() - t0
        )
        wall = tr["mode"][1:] == 2  # after the wall contact: the unseen friction (0.9)
        rows.append(_force_row("task_long", i, truth, mean, std, wall))
        curve("task_long", tr, truth[:, 1], mean[:, 1], std[:, 1])  # F_y (seed A Fig. 13)
        t0 = time.perf_counter()
        mean1, std1 = model.predict_step(x[:-1])
        times["task_one_step_predict_s"] = (
            times.get("task_one_step_predict_s", 0.0) + time.perf_counter() - t0
        )
        rows.append(_force_row("task_one_step", i, truth, mean1, std1, wall))
        curve("task_one_step", tr, truth[:, 1], mean1[:, 1], std1[:, 1])  # Fig. 14a
        pred, t_train, t_pred = _igmm(d["medium_multi"], tr, h3)
        times["igmm_train_s"], times["igmm_predict_s"] = t_train, t_pred
        f = np.linalg.norm(tr["force"], axis=1)
        rows.append({"condition": "igmm", "trial": i,
                     "force_pred_rmse_N": _rmse(pred[1:], f[1:]),
                     "force_pred_rmse_wall_N": _rmse(pred[1:][wall], f[1:][wall])})  # fmt: skip
        # naive reference: the next ‖F‖ equals the last one (what a one-step model must beat)
        rows.append({"condition": "persistence", "trial": i,
                     "force_pred_rmse_N": _rmse(f[:-1], f[1:]),
                     "force_pred_rmse_wall_N": _rmse(f[:-1][wall], f[1:][wall])})  # fmt: skip
        curve("igmm", tr, f[1:], pred[1:])  # ‖F‖ (Fig. 14b: ccm's model)
    return rows, times, curves


def _force_row(
    name: str, i: int, truth: np.ndarray, mean: np.ndarray, std: np.ndarray, wall: np.ndarray
) -> dict:
    """‖F‖ and F_y scores of a force-predicting GP variant (‖F̂‖ from the predicted vector);
    ``wall`` marks the steps after the wall contact."""
    f_hat, f = np.linalg.norm(mean, axis=1), np.linalg.norm(truth, axis=1)
    return {
        "condition": name, "trial": i,
        "force_pred_rmse_N": _rmse(f_hat, f),
        "force_pred_rmse_wall_N": _rmse(f_hat[wall], f[wall]),
        "force_y_pred_rmse_N": _rmse(mean[:, 1], truth[:, 1]),
        "coverage_95": _coverage(truth, mean, std),
        "coverage_95_wall": _coverage(truth[wall], mean[wall], std[wall]) if wall.any() else None,
        "band_width_N": float(np.mean(2 * 1.96 * std)),
    }  # fmt: skip


def run_h3(cfg: DictConfig, compose: Callable, out_dir: Path) -> dict[str, Any]:
    """Run the H3 experiment and write its run directory (module docstring)."""
    from ccm.metrics import aggregate

    h3 = _settings(cfg)
    wall0 = time.perf_counter()
    data = _datasets(h3, cfg, compose, out_dir)
    collect_s = time.perf_counter() - wall0
    rows, times, curves = evaluate(data, h3, int(cfg.seed))
    names = dict.fromkeys(r["condition"] for r in rows)
    summary = {
        "experiment": str(cfg.experiment.name),
        "status": "ok",
        "seed": int(cfg.seed),
        "conditions": {
            n: aggregate(
                [
                    {k: v for k, v in r.items() if k not in ("condition", "trial")}
                    for r in rows
                    if r["condition"] == n
                ]
            )  # fmt: skip
            for n in names
        },
        "trials": rows,
    }
    if cfg.experiment.get("figures", True):
        from ccm.plots_h3 import write_h3_figures

        write_h3_figures(out_dir / "figures", curves)
    info = {"wall_time_s": time.perf_counter() - wall0, "collect_s": collect_s, **times}
    write_json_atomic(out_dir / "run_info.json", info)
    write_json_atomic(out_dir / "summary.json", summary)
    return summary
