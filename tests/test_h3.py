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
]  # fmt: skip


def run(tmp_path: Path, name: str, *extra: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [CCM, "run", *SMALL, *extra, f"hydra.run.dir={tmp_path / name}"],
        cwd=tmp_path, capture_output=True, text=True, timeout=300, check=False,
    )  # fmt: skip


@pytest.fixture(scope="module")
def first(tmp_path_factory) -> Path:
    tmp = tmp_path_factory.mktemp("h3")
    res = run(tmp, "a")
    assert res.returncode == 0, res.stderr
    return tmp


def test_h3_writes_data_metrics_and_figures(first: Path) -> None:
    out = first / "a"
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "ok"
    conds = summary["conditions"]
    assert set(conds) == {
        "joint_single", "joint_multi", "joint_high", "task_long", "task_one_step", "igmm",
        "persistence",
    }  # fmt: skip
    assert conds["joint_multi"]["joint_pred_rmse_rad"] > 0.0
    assert 0.0 <= conds["task_long"]["coverage_95"] <= 1.0
    for n in ("task_long", "task_one_step", "igmm", "persistence"):
        assert conds[n]["force_pred_rmse_N"] >= 0.0
    for name in ("medium_multi", "medium_single", "high_multi", "medium_test", "high_test"):
        assert (out / "data" / f"{name}.npz").is_file()
    assert (out / "figures" / "h3_joint.png").is_file()
    assert (out / "figures" / "h3_force.png").is_file()
    info = json.loads((out / "run_info.json").read_text())
    assert info["joint_multi_train_s"] > 0.0  # wall-clock facts live outside the summary


def test_reused_data_give_the_identical_summary(first: Path) -> None:
    res = run(first, "b", f"h3.data_from={first / 'a'}")
    assert res.returncode == 0, res.stderr
    a = (first / "a" / "summary.json").read_bytes()
    assert (first / "b" / "summary.json").read_bytes() == a


def test_missing_data_from_is_one_line(tmp_path: Path) -> None:
    res = run(tmp_path, "c", f"h3.data_from={tmp_path / 'nowhere'}")
    assert res.returncode != 0
    line = res.stderr.strip().splitlines()[-1]
    assert "h3.data_from" in line and "Traceback" not in res.stderr


def test_lag_is_positive_when_the_truth_lags_the_prediction() -> None:
    import numpy as np

    from ccm.h3 import _lag

    t = np.arange(0.0, 8.0, 0.01)
    pred = np.tanh(t - 3.0)[:, None]
    truth = np.tanh(t - 3.5)[:, None]  # the same motion, 0.5 s later
    assert _lag(truth, pred, 0.01) == pytest.approx(0.5, abs=0.011)
    assert _lag(pred, truth, 0.01) == pytest.approx(-0.5, abs=0.011)


def test_single_friction_set_reuses_the_multi_friction_trials() -> None:
    """medium_single = medium_multi's first trials at single_friction (same controller), and
    is recorded anew when medium_multi has too few of them."""
    import numpy as np

    from ccm.h3 import _single_friction_subset

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
