"""H3 (seed A §4.4, Figs 11-14): the offline long-horizon SVM + GP baseline (Khader et al.
2020, :class:`ccm.learn.gp.svm_gp.ModalGPDynamics`) against ccm's incremental forward model.

An experiment with ``experiment.kind: h3`` runs :func:`run_h3` instead of the trial loop
(``experiment.fast``: one trial of ≥ 2.5 s per dataset, two training frictions):

1. **Data** (:mod:`ccm.analyses.h3_data`): ``table_wall`` trials with a fixed-gain controller, or
the
   datasets of a previous run (``h3.data_from``). ``medium_multi``: medium stiffness, wall
   friction ``train_frictions`` (seed A: 0.1-0.7); ``medium_single``: medium, one friction
   (0.6; medium_multi's trials at that friction when it has them); ``high_multi``: high
   stiffness, the same frictions; ``medium_test`` / ``high_test``: the test friction (0.9).
   Saved as ``data/<name>.npz``. The recorded runs differ by ``h3.variability`` (a start
   jitter, encoder noise; :class:`ccm.analyses.h3_data.Variability`) besides their F/T noise.
2. **Variants** (seed A §4.4.1-4.4.3), on the data subsampled every ``subsample`` steps
   (one H3 step = ``subsample`` control periods, 10 ms), one row each:

   * ``joint_single`` / ``joint_multi`` / ``joint_high``: (i) joint space, X = [q, q̇] →
     next, rolled out over the whole test trial from its first state (Figs 11a, 11b, 12).
   * ``task_long``: (ii) the task-space GP as seed A §4.4.2 writes it, p(F_{t+1} | F_t, ẋ_t):
     it predicts the *absolute* next force; rolled out with the test trial's measured ẋ as
     exogenous input (Fig. 13).
   * ``task_one_step``: (iii) the same absolute GP fed the real [F_t, ẋ_t] every step
     (§4.4.3, Fig. 14a).
   * ``task_long_delta`` / ``task_one_step_delta``: as (ii) / (iii) with a separately fitted
     GP of the *increment* F_{t+1} − F_t (``predict_delta``), which falls back to
     persistence away from its data where the absolute GP falls back to its mean; not seed
     A's formulation (ccm's main rows until issue #16). Both task-space GPs are fitted on
     the same points and share one mode classifier.
   * ``igmm``: ccm's incremental forward model (IGMM + GMR, Eq. 2-6), trained by streaming
     the training trials through it and revised online during the test trial, one step
     ahead, on ‖F‖ (its features are magnitudes; ‖ω‖ and ‖τ‖ are taken as 0: the data hold
     neither, and the tool's orientation is held). Its ``forward_model.horizon_s`` must be
     one H3 step (checked). For F_y its ‖F̂‖ is put along the latest measured force,
     F̂ = ‖F̂‖ F_t / ‖F_t‖ (Fig. 14b).
   * ``persistence``: F̂_{t+1} = F_t, the naive reference every one-step predictor must beat.
3. **Metrics** per variant, averaged over the test trials (:mod:`ccm.analyses.h3_scores`; "wall":
   the steps in contact with the wall, after the wall contact, at the unseen friction):
   ``joint_pred_rmse_rad`` (all 7 joints), ``train_spread_rad`` (the joint rows' training
   set: std across its trials of the joint positions, mean over time and joints; what seed A
   §4.4.1 calls the variability in the training data), ``force_pred_rmse_N`` (on ‖F‖, the quantity
   every variant can be scored on; ``force_pred_rmse_wall_N`` after the wall contact),
   ``force_y_pred_rmse_N`` / ``force_y_pred_rmse_wall_N`` (F_y along the wall, Figs 13-14;
   every force-predicting variant), ``coverage_95`` (share of true values inside mean ±
   1.96 std; ``coverage_95_wall``, and ``coverage_95_y_wall`` for F_y, after the wall
   contact), the mean band width ``band_width_rad`` / ``band_width_N`` /
   ``band_width_y_wall_N`` and ``joint_lag_s`` (the delay that best aligns the true joint
   trajectory with the prediction; > 0: the truth lags, seed A Fig. 11). Training and
   prediction times are wall-clock facts and go to ``run_info.json`` (``make bench``; the
   cost claims compare the baseline's with the incremental model's: ``igmm_train_s`` is one
   training on the training set, ``igmm_predict_s`` its predictions and online updates over
   all test trials).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from omegaconf import DictConfig

from ccm.analyses.h3_data import (
    Variability,
    collect,
    load_dataset,
    save_dataset,
    trial_duration_s,
)
from ccm.analyses.h3_scores import Y, along_latest, gp_force_scores, joint_scores, norm_force_scores
from ccm.core.errors import ConfigError, check_bool, check_int_positive, config_block
from ccm.core.records import write_json_atomic
from ccm.learn.gp.svm_gp import ModalGPDynamics
from ccm.learn.mixtures.forward_model import N_STATE, make_forward_model

_KEYS = (
    "controllers", "train_frictions", "trials_per_friction", "single_friction", "single_trials",
    "test_friction", "test_trials", "subsample", "baseline", "forward_model", "data_from",
    "save_data", "max_time_s", "variability",
)  # fmt: skip
Trial = Mapping[str, np.ndarray]


def _settings(cfg: DictConfig) -> dict[str, Any]:
    h3 = config_block(cfg, "h3", _KEYS)
    for k in ("trials_per_friction", "single_trials", "test_trials", "subsample"):
        h3[k] = check_int_positive(f"h3.{k}", h3.get(k))
    if not h3.get("train_frictions"):
        raise ConfigError("h3.train_frictions", "must list at least one wall friction")
    h3["save_data"] = check_bool("h3.save_data", h3.get("save_data", False))
    h3["variability"] = Variability.from_config(h3.get("variability"))
    if cfg.experiment.get("fast", False):  # tests: one short trial per dataset
        fast_s = float(cfg.experiment.get("fast_time_s", 0.5))
        h3 |= {
            "trials_per_friction": 1, "single_trials": 1, "test_trials": 1,
            "train_frictions": h3["train_frictions"][:2], "max_time_s": max(fast_s, 2.5),
        }  # fmt: skip
    return h3


def _dataset_specs(h3: Mapping[str, Any]) -> dict[str, tuple[str, list, int]]:
    """The five datasets: (controller, wall frictions, trials per friction) by name."""
    return {
        "medium_multi": ("medium", list(h3["train_frictions"]), h3["trials_per_friction"]),
        "medium_single": ("medium", [h3["single_friction"]], h3["single_trials"]),
        "high_multi": ("high", list(h3["train_frictions"]), h3["trials_per_friction"]),
        "medium_test": ("medium", [h3["test_friction"]], h3["test_trials"]),
        "high_test": ("high", [h3["test_friction"]], h3["test_trials"]),
    }


def collection_plan(cfg: DictConfig, pattern_s: float) -> tuple[int, float]:
    """(trials, simulated seconds per trial) that :func:`_datasets` records for ``cfg``, whose
    ``table_wall`` pattern lasts ``pattern_s``: the reused sets record nothing (``data_from``;
    ``medium_single`` inside ``medium_multi``, as :func:`_single_friction_subset` finds it).
    For ``make bench``'s paper floor, which has the run's config but not its data."""
    h3 = _settings(cfg)
    if h3.get("data_from"):
        return 0, 0.0
    mu = float(h3["single_friction"])
    reused = h3["trials_per_friction"] >= h3["single_trials"] and any(
        float(f) == mu for f in h3["train_frictions"]
    )
    trials = sum(
        len(frictions) * n
        for name, (_, frictions, n) in _dataset_specs(h3).items()
        if not (name == "medium_single" and reused)
    )
    return trials, trial_duration_s(pattern_s, max_time_s=h3.get("max_time_s"))


def _datasets(h3: Mapping[str, Any], cfg: DictConfig, compose: Callable, out_dir: Path) -> dict:
    """The five datasets of the module docstring: recorded now, or read from ``data_from``;
    written to ``data/*.npz`` only with ``save_data`` (600 MB for five seeds)."""
    out = {}
    first = 1
    for name, (ctl, frictions, n) in _dataset_specs(h3).items():
        path = out_dir / "data" / f"{name}.npz"
        save = save_dataset if h3["save_data"] else _discard
        if h3.get("data_from"):
            out[name] = _reuse(Path(h3["data_from"]), name)
            save(path, out[name], {"copied_from": str(h3["data_from"])})
            continue
        controller = h3["controllers"][ctl]
        subset = _single_friction_subset(name, out, h3)
        if subset is not None:  # the same controller and friction: reuse, do not re-record
            meta = {"controller": controller, "frictions": list(frictions), "seed": int(cfg.seed),
                    "subset_of": "medium_multi",
                    "variability": asdict(h3["variability"])}  # fmt: skip
            save(path, subset, meta)
            out[name] = subset
            continue
        trials = collect(
            compose, [f"controller={controller}"], frictions, n, int(cfg.seed),
            first_trial=first, max_time_s=h3.get("max_time_s"), variability=h3["variability"],
        )  # fmt: skip
        first += len(trials)
        meta = {"controller": controller, "frictions": list(frictions), "seed": int(cfg.seed),
                "variability": asdict(h3["variability"])}  # fmt: skip
        save(path, trials, meta)
        out[name] = trials
    return out


def _discard(path: Path, trials: Sequence[Trial], meta: Mapping) -> None:
    """``h3.save_data: false``: the datasets are used, not written."""


def _reuse(run: Path, name: str) -> list:
    """Dataset ``name`` of the earlier run ``run`` (``h3.data_from``)."""
    if not (run / "data").is_dir():
        raise ConfigError(
            "h3.data_from", f"{run} has no data/ directory: record it with h3.save_data=true"
        )
    return load_dataset(run / "data" / f"{name}.npz")[0]


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


def train_spread(trials: Sequence[Trial]) -> float:
    """The training set's variability [rad]: the std across its trials of the joint positions
    at each step (trials cut to the shortest), averaged over the steps and the 7 joints; 0 for
    one trial."""
    n = min(len(tr["q"]) for tr in trials)
    q = np.stack([np.asarray(tr["q"])[:n] for tr in trials])
    return float(np.mean(np.std(q, axis=0)))


def _joint(tr: Trial) -> np.ndarray:
    return np.hstack([tr["q"], tr["dq"]])


def _task(tr: Trial) -> np.ndarray:
    return np.hstack([tr["force"], tr["velocity"]])


def _fit(
    pairs: tuple, h3: Mapping, seed: int, classifier: ModalGPDynamics | None = None, **kw: Any
) -> tuple[ModalGPDynamics, float]:
    """A :class:`ModalGPDynamics` fitted on ``pairs`` (:func:`_pairs`) and its fit time [s];
    ``kw`` override ``h3.baseline`` (e.g. ``predict_delta``)."""
    opts = dict(h3.get("baseline") or {}) | kw
    model = ModalGPDynamics(**opts, seed=seed, key="h3.baseline")
    t0 = time.perf_counter()
    model.fit(*pairs, classifier=classifier)
    return model, time.perf_counter() - t0


def _check_horizon(fm: Any, step_s: float) -> None:
    """The forward model predicts one H3 step ahead (``subsample`` control steps): its
    ``horizon_s`` must say so, or a saved model would state a wrong horizon."""
    if abs(fm.horizon_s - step_s) > 1e-6:
        raise ConfigError(
            "h3.forward_model.horizon_s",
            f"must be one H3 step, h3.subsample control periods = {step_s:g} s; "
            f"got {fm.horizon_s:g}",
        )


def _igmm_states(tr: Trial) -> np.ndarray:
    """The incremental model's states S = [‖ẋ‖, ‖ω‖ = 0, ‖F‖, ‖τ‖ = 0] (module docstring)."""
    s = np.zeros((len(tr["t"]), N_STATE))
    s[:, 0] = np.linalg.norm(tr["velocity"], axis=1)
    s[:, 2] = np.linalg.norm(tr["force"], axis=1)
    return s


def _igmm_train(train: Sequence[Trial], h3: Mapping) -> tuple[Any, float]:
    """The incremental model after streaming the training trials through it, and the time
    that took [s]."""
    fm = make_forward_model(dict(h3.get("forward_model") or {}), "h3.forward_model")
    _check_horizon(fm, float(np.median(np.diff(train[0]["t"]))))
    t0 = time.perf_counter()
    for tr in train:
        s = _igmm_states(tr)
        for k in range(1, len(s)):
            fm.update(s[k - 1], s[k, 2:])
    return fm, time.perf_counter() - t0


def _igmm_copy(trained: Any, h3: Mapping) -> Any:
    """A fresh incremental model holding ``trained``'s learned state (its ``state_dict``): the
    IGMM draws no random numbers, so it predicts what a model trained anew would
    (tests/test_h3.py checks this)."""
    fm = make_forward_model(dict(h3.get("forward_model") or {}), "h3.forward_model")
    fm.load_state_dict(trained.state_dict())
    return fm


def _igmm(fm: Any, test: Trial) -> tuple[np.ndarray, float]:
    """One-step ‖F‖ predictions of the trained incremental model ``fm`` on ``test``, revised
    online (``fm`` is changed): element k - 1 predicts ‖F_k‖, k = 1 .. n - 1; and the time [s]."""
    s = _igmm_states(test)
    pred = np.full(len(s) - 1, np.nan)
    t0 = time.perf_counter()
    for k in range(1, len(s)):
        pred[k - 1] = fm.predict(s[k - 1])[0]  # D̂_k from S_{k-1}, before D_k is seen
        fm.update(s[k - 1], s[k, 2:])  # then learn from it (incremental, seed A §3.1)
    return pred, time.perf_counter() - t0


@dataclass
class _Results:
    """What :func:`evaluate` returns: score rows, wall-clock times and figure curves."""

    rows: list[dict[str, Any]] = field(default_factory=list)
    times: dict[str, float] = field(default_factory=dict)
    curves: dict[str, dict[str, np.ndarray]] = field(default_factory=dict)

    def add_time(self, key: str, t0: float) -> None:
        self.times[key] = self.times.get(key, 0.0) + time.perf_counter() - t0

    def curve(self, name: str, tr: Trial, truth: np.ndarray, mean: np.ndarray, std=None) -> None:
        """The first test trial's curve of ``name`` (later trials are not plotted)."""
        if name not in self.curves:
            wall = np.flatnonzero(tr["mode"] == 2)
            self.curves[name] = {
                "t": tr["t"][1:], "truth": truth, "mean": mean,
                "std": np.full_like(mean, np.nan) if std is None else std,
                "contact_t": np.array(tr["t"][wall[0]] if wall.size else np.nan),
            }  # fmt: skip


#: joint-space variant -> (training set, test set), seed A §4.4.1
JOINT = {"joint_single": ("medium_single", "medium_test"),
         "joint_multi": ("medium_multi", "medium_test"),
         "joint_high": ("high_multi", "high_test")}  # fmt: skip
#: task-space GP -> ``predict_delta``: "" the absolute GP p(F_{t+1} | F_t, ẋ_t) of seed A
#: §4.4.2, "_delta" the increment GP (module docstring)
TASK = {"": False, "_delta": True}


def _joint_variants(
    d: Mapping[str, Sequence[Trial]], h3: Mapping, seed: int, res: _Results
) -> None:
    """Rows of the joint-space long-horizon variants (seed A §4.4.1, Figs 11-12)."""
    for name, (train, test) in JOINT.items():
        spread = train_spread(d[train])
        model, res.times[f"{name}_train_s"] = _fit(_pairs(d[train], _joint, 14), h3, seed)
        t0 = time.perf_counter()
        for i, tr in enumerate(d[test], start=1):
            x = _joint(tr)
            mean, std, _ = model.rollout(x[0], len(x) - 1)
            dt = float(np.median(np.diff(tr["t"])))
            scores = joint_scores(x[1:], mean, std, dt)
            res.rows.append({"condition": name, "trial": i, **scores, "train_spread_rad": spread})
            res.curve(name, tr, x[1:, 0], mean[:, 0], std[:, 0])  # joint 1 (seed A Fig. 11)
        res.add_time(f"{name}_predict_s", t0)


def _task_variants(d: Mapping[str, Sequence[Trial]], h3: Mapping, seed: int, res: _Results) -> None:
    """Rows of the task-space GPs, long horizon (§4.4.2, Fig. 13) and one step with feedback
    (§4.4.3, Fig. 14a), absolute and increment; the two GPs share one mode classifier."""
    pairs = _pairs(d["medium_multi"], _task, 3)
    shared = None
    for sfx, delta in TASK.items():
        model, res.times[f"task{sfx}_train_s"] = _fit(pairs, h3, seed, shared, predict_delta=delta)
        shared = shared or model
        for i, tr in enumerate(d["medium_test"], start=1):
            x = _task(tr)
            truth, wall = x[1:, :3], tr["mode"][1:] == 2  # wall: the unseen friction (0.9)
            t0 = time.perf_counter()
            mean, std, _ = model.rollout(x[0], len(x) - 1, exog=x[:, 3:])
            res.add_time(f"task_long{sfx}_predict_s", t0)
            t0 = time.perf_counter()
            mean1, std1 = model.predict_step(x[:-1])
            res.add_time(f"task_one_step{sfx}_predict_s", t0)
            for name, (m, s) in {"task_long": (mean, std), "task_one_step": (mean1, std1)}.items():
                res.rows.append(
                    {"condition": name + sfx, "trial": i, **gp_force_scores(truth, m, s, wall)}
                )
                res.curve(name + sfx, tr, truth[:, Y], m[:, Y], s[:, Y])  # F_y, Figs 13, 14a


def _incremental_variants(d: Mapping[str, Sequence[Trial]], h3: Mapping, res: _Results) -> None:
    """Rows of ccm's incremental model and of persistence (Fig. 14b), one step ahead. The
    model is trained once; each test trial starts from a copy of it (:func:`_igmm_copy`)."""
    trained, res.times["igmm_train_s"] = _igmm_train(d["medium_multi"], h3)
    for i, tr in enumerate(d["medium_test"], start=1):
        pred, t_pred = _igmm(_igmm_copy(trained, h3), tr)
        res.times["igmm_predict_s"] = res.times.get("igmm_predict_s", 0.0) + t_pred
        f, wall = tr["force"], tr["mode"][1:] == 2
        res.rows.append({"condition": "igmm", "trial": i, **norm_force_scores(pred, f, wall)})
        # naive reference: the next F equals the last one (what a one-step model must beat)
        persist = np.linalg.norm(f[:-1], axis=1)
        res.rows.append(
            {"condition": "persistence", "trial": i, **norm_force_scores(persist, f, wall)}
        )
        res.curve("igmm", tr, f[1:, Y], along_latest(pred, f[:-1])[:, Y])  # F_y (Fig. 14b)


def evaluate(
    data: Mapping[str, Sequence[Trial]], h3: Mapping, seed: int
) -> tuple[list[dict[str, Any]], dict[str, float], dict[str, dict[str, np.ndarray]]]:
    """Per-test-trial metrics of every variant, the wall-clock times, and the first test
    trial's curves for the figures (``t``, ``truth``, ``mean``, ``std``, ``contact_t``: the
    wall contact); see the module docstring."""
    k = h3["subsample"]
    d = {name: [_sub(tr, k) for tr in trials] for name, trials in data.items()}
    res = _Results()
    _joint_variants(d, h3, seed, res)
    _task_variants(d, h3, seed, res)
    _incremental_variants(d, h3, res)
    return res.rows, res.times, res.curves


def run_h3(cfg: DictConfig, compose: Callable, out_dir: Path) -> dict[str, Any]:
    """Run the H3 experiment and write its run directory (module docstring)."""
    from ccm.metrics.trial import aggregate

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
    cpu0 = time.process_time()
    if cfg.experiment.get("figures", True):
        from ccm.plots.h3 import write_h3_figures

        write_h3_figures(out_dir / "figures", curves)
    info = {"wall_time_s": time.perf_counter() - wall0, "collect_s": collect_s, **times,
            "cpu_s": {"figures": time.process_time() - cpu0}}  # fmt: skip
    write_json_atomic(out_dir / "run_info.json", info)
    write_json_atomic(out_dir / "summary.json", summary)
    return summary
