"""H3 data collection (seed A §4.4, issue #6): table_wall trials with joint encoders, saved
as NPZ without pickle and read back exactly."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from ccm.analyses.h3_data import FIELDS, collect, contact_modes, load_dataset, save_dataset
from ccm.core.errors import ConfigError

BASE = ["experiment=single", "sim=pybullet3d", "task=table_wall", "controller=fixed_impedance_high"]


@pytest.fixture(scope="module")
def trials(request) -> list[dict[str, np.ndarray]]:
    from hydra import compose, initialize_config_dir

    from ccm.cli import config_dir

    with initialize_config_dir(str(config_dir()), version_base="1.3", job_name="h3"):
        # 2.2 s: free-space approach, then the touch of the table (table_wall.yaml: ~1.6 s)
        return collect(lambda o: compose("config", overrides=list(o)), BASE, [0.2, 0.9], 1,
                       seed=0, max_time_s=2.2)  # fmt: skip


def test_trials_hold_joint_and_task_space_data_and_mode_labels(trials) -> None:
    assert len(trials) == 2
    for tr, mu in zip(trials, (0.2, 0.9), strict=True):
        n = len(tr["t"])
        assert n == 2200
        assert tr["q"].shape == tr["dq"].shape == (n, 7)
        assert tr["force"].shape == tr["velocity"].shape == tr["position"].shape == (n, 3)
        assert float(tr["wall_friction"]) == pytest.approx(mu)
        assert np.ptp(tr["q"], axis=0).max() > 0.01  # the arm moved (rad)
        # the first samples: free space; the last: resting on the table (mode 1)
        assert tr["mode"][0] == 0 and tr["mode"][-1] == 1
        # joint velocity is the derivative of the joint position (same time base)
        dq_fd = np.gradient(tr["q"][:, 0], tr["t"])
        assert np.abs(dq_fd - tr["dq"][:, 0])[10:-10].max() < 0.05


def test_contact_modes_from_true_normal_forces() -> None:
    np.testing.assert_array_equal(
        contact_modes(np.array([0.0, 3.0, 3.0, 0.0]), np.array([0.0, 0.0, 2.0, 2.0])),
        [0, 1, 2, 2],
    )


def test_dataset_round_trip_without_pickle(trials, tmp_path: Path) -> None:
    path = save_dataset(tmp_path / "data" / "train.npz", trials, {"controller": "high"})
    back, meta = load_dataset(path)
    assert meta == {"controller": "high"}
    assert len(back) == len(trials)
    for a, b in zip(trials, back, strict=True):
        for f in FIELDS:
            np.testing.assert_array_equal(a[f], b[f])
    with np.load(path, allow_pickle=False) as z:  # readable without pickle
        assert "trial_000/q" in z.files


def test_bad_datasets_name_the_key(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match="h3.data_from"):
        load_dataset(tmp_path / "missing.npz")
    bad = tmp_path / "bad.npz"
    bad.write_bytes(b"not an npz")
    with pytest.raises(ConfigError, match="h3.data_from"):
        load_dataset(bad)


def test_bad_collection_settings_name_the_key() -> None:
    with pytest.raises(ConfigError, match="h3.frictions"):
        collect(lambda o: None, BASE, [], 1, seed=0)  # type: ignore[arg-type,return-value]
    with pytest.raises(ConfigError, match="h3.trials_per_friction"):
        collect(lambda o: None, BASE, [0.1], 0, seed=0)  # type: ignore[arg-type,return-value]
