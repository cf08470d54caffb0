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
3. **Metrics** per variant (:mod:`ccm.analyses.h3_variants` fits and rolls out the variants),
   averaged over the test trials (:mod:`ccm.analyses.h3_scores`; "wall":
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
from dataclasses import asdict
from pathlib import Path
from typing import Any

from omegaconf import DictConfig

from ccm.analyses.h3_data import (
    Variability,
    collect,
    load_dataset,
    save_dataset,
    trial_duration_s,
)
from ccm.analyses.h3_variants import Trial, evaluate
from ccm.core.errors import ConfigError, check_bool, check_int_positive, config_block
from ccm.core.records import write_json_atomic

_KEYS = (
    "controllers", "train_frictions", "trials_per_friction", "single_friction", "single_trials",
    "test_friction", "test_trials", "subsample", "baseline", "forward_model", "data_from",
    "save_data", "max_time_s", "variability",
)  # fmt: skip


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
