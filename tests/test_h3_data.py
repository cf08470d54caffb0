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


# --------------------------------------------------------------- issue #38 item 8: variability
TABLE_WALL_START = np.array([0.48, -0.1, 0.15])  # configs/task/table_wall.yaml: task.start


@pytest.fixture(scope="module")
def composer():
    from hydra import compose, initialize_config_dir

    from ccm.cli import config_dir

    with initialize_config_dir(str(config_dir()), version_base="1.3", job_name="h3v"):
        yield lambda o: compose("config", overrides=list(o))


def _record(composer, variability=None, trials: int = 2) -> list[dict[str, np.ndarray]]:
    """``trials`` runs at wall friction 0.6, 60 ms each (free space: the start matters)."""
    return collect(composer, BASE, [0.6], trials, seed=0, max_time_s=0.06, variability=variability)


def test_start_jitter_moves_each_run_by_its_drawn_offset(composer) -> None:
    """Each run starts at task.start + its offset, the offset is start_jitter_m times a
    standard normal draw of the trial's own stream, and its spread over trials is the
    configured std (a value, not just 'differs')."""
    from ccm.analyses.h3_data import STREAM, Variability
    from ccm.experiment.components import trial_seed

    v = Variability(start_jitter_m=0.01)
    runs = _record(composer, v)
    for k, tr in enumerate(runs, start=1):
        s = trial_seed(0, k)
        offset = v.start_offset(s)
        np.testing.assert_array_equal(
            offset, 0.01 * np.random.default_rng((s, STREAM, 0)).standard_normal(3)
        )
        assert np.linalg.norm(offset) > 1e-3  # a draw this small would make the check vacuous
        np.testing.assert_allclose(tr["position"][0] - TABLE_WALL_START, offset, atol=2e-4)
    # the two runs start apart by the difference of their offsets, not by the F/T noise
    d = runs[1]["position"][0] - runs[0]["position"][0]
    expect = v.start_offset(trial_seed(0, 2)) - v.start_offset(trial_seed(0, 1))
    np.testing.assert_allclose(d, expect, atol=3e-4)
    assert np.abs(runs[1]["q"][0] - runs[0]["q"][0]).max() > 1e-3  # rad: another posture
    # the spread of the offsets over many trials is the configured std
    draws = np.array([v.start_offset(trial_seed(0, k)) for k in range(1, 2001)])
    assert draws.std() == pytest.approx(0.01, rel=0.05)
    assert np.abs(draws.mean()) < 0.001


def test_encoder_noise_adds_the_configured_std_to_the_recorded_joints_only(composer) -> None:
    from ccm.analyses.h3_data import Variability

    clean = _record(composer, None, trials=1)[0]
    noisy = _record(
        composer, Variability(encoder_noise_rad=1e-3, encoder_noise_rad_s=2e-2), trials=1
    )[0]
    dq, ddq = noisy["q"] - clean["q"], noisy["dq"] - clean["dq"]
    assert dq.std() == pytest.approx(1e-3, rel=0.1)  # 60 x 7 draws
    assert ddq.std() == pytest.approx(2e-2, rel=0.1)
    for f in ("position", "velocity", "force", "mode"):  # the run itself is unchanged
        np.testing.assert_array_equal(noisy[f], clean[f])


def test_zero_variability_records_identical_runs(composer) -> None:
    """Jitter 0 and noise 0: the runs start from the same state and are what the recorder gave
    before variability existed (record_trial on components built once per friction)."""
    from ccm.analyses.h3_data import WALL_FRICTION, Variability, record_trial
    from ccm.experiment.components import build_components, trial_seed

    runs = _record(composer, Variability())
    np.testing.assert_array_equal(runs[0]["q"][0], runs[1]["q"][0])
    np.testing.assert_array_equal(runs[0]["position"][0], runs[1]["position"][0])
    np.testing.assert_allclose(runs[0]["position"][0], TABLE_WALL_START, atol=2e-4)
    comp = build_components(composer([*BASE, f"{WALL_FRICTION}=0.6"]))
    try:
        for k, tr in enumerate(runs, start=1):
            ref = record_trial(comp, trial_seed(0, k), 0.06)
            for f in FIELDS:
                np.testing.assert_array_equal(tr[f], ref[f])
    finally:
        comp.sim.close()


def test_bad_variability_names_the_key() -> None:
    from ccm.analyses.h3_data import Variability

    with pytest.raises(ConfigError, match=r"h3.variability.start_jitter_m"):
        Variability.from_config({"start_jitter_m": -0.001})
    with pytest.raises(ConfigError, match=r"h3.variability.jitter"):
        Variability.from_config({"jitter": 0.01})
    assert Variability.from_config(None) == Variability()
