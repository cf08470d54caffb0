"""The H3 experiment (seed A §4.4, issue #6) end to end through ``ccm run``, in a small
configuration: datasets recorded and reused, metrics, figures, clear errors."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

CCM = str(Path(sys.executable).parent / "ccm")
SMALL = [
    "experiment=h3_long_horizon", "h3.train_frictions=[0.1,0.7]", "h3.trials_per_friction=1",
    "h3.single_trials=1", "h3.test_trials=1", "h3.max_time_s=2.5", "h3.subsample=20",
    "h3.baseline.max_points_per_mode=60", "h3.baseline.n_particles=10",
    "h3.forward_model.horizon_s=0.02",  # one H3 step: subsample 20 x 1 ms
]  # fmt: skip
FORCE_ROWS = ("task_long", "task_one_step", "task_long_delta", "task_one_step_delta")


def run(tmp_path: Path, name: str, *extra: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [CCM, "run", *SMALL, *extra, f"hydra.run.dir={tmp_path / name}"],
        cwd=tmp_path, capture_output=True, text=True, timeout=300, check=False,
    )  # fmt: skip


@pytest.fixture(scope="module")
def first(tmp_path_factory) -> Path:
    tmp = tmp_path_factory.mktemp("h3")
    res = run(tmp, "a", "h3.save_data=true")
    assert res.returncode == 0, res.stderr
    return tmp


def test_h3_writes_data_metrics_and_figures(first: Path) -> None:
    out = first / "a"
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "ok"
    conds = summary["conditions"]
    assert set(conds) == {"joint_single", "joint_multi", "joint_high", *FORCE_ROWS, "igmm",
                          "persistence"}  # fmt: skip
    assert conds["joint_multi"]["joint_pred_rmse_rad"] > 0.0
    # the training runs differ (h3.variability's start jitter): their spread is measured
    assert conds["joint_single"]["train_spread_rad"] == 0.0  # one trial in this small run
    assert conds["joint_multi"]["train_spread_rad"] > 1e-4
    assert 0.0 <= conds["task_long"]["coverage_95"] <= 1.0
    for n in (*FORCE_ROWS, "igmm", "persistence"):
        assert conds[n]["force_pred_rmse_N"] >= 0.0
        assert conds[n]["force_y_pred_rmse_N"] >= 0.0
        assert "force_y_pred_rmse_wall_N" in conds[n]  # None here: 2.5 s do not reach the wall
    for n in FORCE_ROWS:
        assert {"coverage_95_y_wall", "band_width_y_wall_N"} <= set(conds[n])
    # the absolute and the increment GP are different models
    assert (
        conds["task_one_step"]["force_pred_rmse_N"]
        != conds["task_one_step_delta"]["force_pred_rmse_N"]
    )
    for name in ("medium_multi", "medium_single", "high_multi", "medium_test", "high_test"):
        assert (out / "data" / f"{name}.npz").is_file()
    assert (out / "figures" / "h3_joint.png").is_file()
    assert (out / "figures" / "h3_force.png").is_file()
    assert (out / "figures" / "h3_force_delta.png").is_file()
    info = json.loads((out / "run_info.json").read_text())
    assert info["cpu_s"]["figures"] > 0.0  # make bench's paper totals count it (issue #40)
    assert (
        info["joint_multi_train_s"] > 0.0 and info["task_delta_train_s"] > 0.0
    )  # wall-clock facts live outside the summary
    # the cost claims' pairs (issue #38): the baseline and the incremental model, same process
    assert min(info["task_train_s"], info["igmm_train_s"], info["task_long_predict_s"],
               info["igmm_predict_s"]) > 0.0  # fmt: skip


def test_reused_data_give_the_identical_summary(first: Path) -> None:
    res = run(first, "b", f"h3.data_from={first / 'a'}")
    assert res.returncode == 0, res.stderr
    a = (first / "a" / "summary.json").read_bytes()
    assert (first / "b" / "summary.json").read_bytes() == a
    assert not (first / "b" / "data").exists()  # h3.save_data defaults to false


def test_data_from_a_run_without_saved_data_is_one_line(tmp_path: Path) -> None:
    unsaved = tmp_path / "unsaved"  # a run directory without data/ (h3.save_data: false)
    unsaved.mkdir()
    res = run(tmp_path, "c", f"h3.data_from={unsaved}")
    assert res.returncode != 0
    line = res.stderr.strip().splitlines()[-1]
    assert "h3.data_from" in line and "h3.save_data=true" in line and "Traceback" not in res.stderr


def test_missing_data_from_is_one_line(tmp_path: Path) -> None:
    res = run(tmp_path, "c", f"h3.data_from={tmp_path / 'nowhere'}")
    assert res.returncode != 0
    line = res.stderr.strip().splitlines()[-1]
    assert "h3.data_from" in line and "Traceback" not in res.stderr


def test_lag_is_positive_when_the_truth_lags_the_prediction() -> None:
    import numpy as np

    from ccm.analyses.h3_scores import lag

    t = np.arange(0.0, 8.0, 0.01)
    pred = np.tanh(t - 3.0)[:, None]
    truth = np.tanh(t - 3.5)[:, None]  # the same motion, 0.5 s later
    assert lag(truth, pred, 0.01) == pytest.approx(0.5, abs=0.011)
    assert lag(pred, truth, 0.01) == pytest.approx(-0.5, abs=0.011)


def test_single_friction_set_reuses_the_multi_friction_trials() -> None:
    """medium_single = medium_multi's first trials at single_friction (same controller), and
    is recorded anew when medium_multi has too few of them."""
    import numpy as np

    from ccm.analyses.h3 import _single_friction_subset

    multi = [{"wall_friction": np.array(mu), "k": i} for i, mu in enumerate([0.1, 0.6, 0.6, 0.7])]
    h3 = {"single_friction": 0.6, "single_trials": 2}
    got = _single_friction_subset("medium_single", {"medium_multi": multi}, h3)
    assert got is not None and [tr["k"] for tr in got] == [1, 2]
    assert (
        _single_friction_subset("medium_single", {"medium_multi": multi}, h3 | {"single_trials": 3})
        is None
    )
    assert (
        _single_friction_subset(
            "medium_single", {"medium_multi": multi}, h3 | {"single_friction": 0.9}
        )
        is None
    )
    assert _single_friction_subset("high_multi", {"medium_multi": multi}, h3) is None


def test_a_magnitude_is_put_along_the_latest_force() -> None:
    """F̂ = ‖F̂‖ F_t / ‖F_t‖ (the igmm row's F_y, seed A Fig. 14b); no direction: zero."""
    import numpy as np

    from ccm.analyses.h3_scores import along_latest

    got = along_latest(np.array([10.0, 2.0]), np.array([[0.0, 3.0, 4.0], [0.0, 0.0, 0.0]]))
    assert got == pytest.approx(np.array([[0.0, 6.0, 8.0], [0.0, 0.0, 0.0]]))


def test_norm_scores_of_persistence_score_f_y_against_the_last_f_y() -> None:
    import numpy as np

    from ccm.analyses.h3_scores import norm_force_scores

    rng = np.random.default_rng(0)
    f = rng.normal(size=(50, 3)) + np.array([0.0, 5.0, -10.0])
    wall = np.arange(49) >= 30
    s = norm_force_scores(np.linalg.norm(f[:-1], axis=1), f, wall)
    dy = f[1:, 1] - f[:-1, 1]
    assert s["force_y_pred_rmse_N"] == pytest.approx(np.sqrt(np.mean(dy**2)))
    assert s["force_y_pred_rmse_wall_N"] == pytest.approx(np.sqrt(np.mean(dy[30:] ** 2)))
    assert norm_force_scores(np.ones(49), f, np.zeros(49, bool))["force_y_pred_rmse_wall_N"] is None


def test_gp_scores_of_f_y_after_the_wall_contact() -> None:
    """coverage_95_y_wall, band_width_y_wall_N and force_y_pred_rmse_wall_N look at F_y on the
    wall steps only (seed A Fig. 13)."""
    import numpy as np

    from ccm.analyses.h3_scores import gp_force_scores

    truth = np.zeros((10, 3))
    mean = np.zeros((10, 3))
    mean[5:, 1] = 3.0  # F_y wrong by 3 N on the wall steps, outside a 1 N std band
    std = np.ones((10, 3))
    wall = np.arange(10) >= 5
    s = gp_force_scores(truth, mean, std, wall)
    assert s["coverage_95_y_wall"] == 0.0 and s["coverage_95_wall"] == pytest.approx(2 / 3)
    assert s["force_y_pred_rmse_wall_N"] == pytest.approx(3.0)
    assert s["band_width_y_wall_N"] == pytest.approx(2 * 1.96)
    assert gp_force_scores(truth, mean, std, ~wall)["coverage_95_y_wall"] == 1.0


def test_forward_model_horizon_must_be_one_h3_step() -> None:
    from types import SimpleNamespace

    from ccm.analyses.h3_variants import _check_horizon
    from ccm.core.errors import ConfigError

    _check_horizon(SimpleNamespace(horizon_s=0.01), 0.01 + 1e-12)
    with pytest.raises(ConfigError, match="h3.forward_model.horizon_s"):
        _check_horizon(SimpleNamespace(horizon_s=0.001), 0.01)


def test_a_copy_of_the_trained_incremental_model_predicts_as_one_trained_anew() -> None:
    """The IGMM is trained once and copied for each test trial (issue #38: ``igmm_train_s`` is
    one training): the copy's predictions equal those of a model trained anew, bit for bit."""
    import numpy as np

    from ccm.analyses.h3_variants import _igmm, _igmm_copy, _igmm_train

    rng = np.random.default_rng(0)

    def trial(n: int = 300) -> dict:
        t = np.arange(n) * 0.01
        step = np.where(t[:, None] > 1.0, 0.5, 0.0)  # two regimes: several components
        force = rng.normal(size=(n, 3)) * 0.3 + np.where(t[:, None] > 2.0, 20.0, 0.0)
        return {"t": t, "velocity": rng.normal(size=(n, 3)) * 0.01 + step, "force": force}

    h3 = {"forward_model": {"kind": "igmm", "horizon_s": 0.01, "igmm": {"max_components": 20},
                            "feature_scale": [0.1, 1.0, 10.0, 1.0, 10.0, 1.0]}}  # fmt: skip
    train, tests = [trial() for _ in range(3)], [trial(), trial()]
    trained, t_train = _igmm_train(train, h3)
    assert trained.n_components >= 2 and t_train > 0.0
    for test in tests:
        anew = _igmm(_igmm_train(train, h3)[0], test)[0]
        copied = _igmm(_igmm_copy(trained, h3), test)[0]
        np.testing.assert_array_equal(copied, anew)


def test_train_spread_is_the_std_across_trials() -> None:
    import numpy as np

    from ccm.analyses.h3_variants import train_spread

    q = np.zeros((5, 7))
    trials = [{"q": q + 0.01}, {"q": q - 0.01}, {"q": np.zeros((6, 7))}]  # cut to 5 steps
    assert train_spread(trials) == pytest.approx(np.std([0.01, -0.01, 0.0]))
    assert train_spread(trials[:1]) == 0.0
