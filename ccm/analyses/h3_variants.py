"""H3's variants (seed A §4.4.1-4.4.3, Figs 11-14): fitting and rolling out each predictor on
the H3 datasets and scoring it per test trial (:func:`evaluate`).

The joint-space long-horizon GPs (Figs 11-12), the task-space GPs long horizon and one step
ahead, absolute and increment (Figs 13, 14a), ccm's incremental forward model (IGMM + GMR,
Eq. 2-6) revised online one step ahead and persistence (Fig. 14b). The variants, the datasets
and the metrics are described in :mod:`ccm.analyses.h3`, which records the data and runs this.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ccm.analyses.h3_scores import Y, along_latest, gp_force_scores, joint_scores, norm_force_scores
from ccm.core.errors import ConfigError
from ccm.learn.gp.svm_gp import ModalGPDynamics
from ccm.learn.mixtures.forward_model import N_STATE, make_forward_model

__all__ = ["JOINT", "TASK", "Trial", "evaluate", "train_spread"]

Trial = Mapping[str, np.ndarray]


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
    """The incremental model's states S = [‖ẋ‖, ‖ω‖ = 0, ‖F‖, ‖τ‖ = 0] (:mod:`ccm.analyses.h3`)."""
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
#: §4.4.2, "_delta" the increment GP (:mod:`ccm.analyses.h3`)
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
    wall contact); see :mod:`ccm.analyses.h3`."""
    k = h3["subsample"]
    d = {name: [_sub(tr, k) for tr in trials] for name, trials in data.items()}
    res = _Results()
    _joint_variants(d, h3, seed, res)
    _task_variants(d, h3, seed, res)
    _incremental_variants(d, h3, res)
    return res.rows, res.times, res.curves
