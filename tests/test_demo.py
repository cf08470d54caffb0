"""``ccm demo``: a demonstration recorded in simulation (seed B's simulated human guiding the
robot in admittance mode), read back as P and replayed (issue #22's round trip)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from hydra import compose, initialize_config_dir

from ccm.cli import config_dir, main
from ccm.core.errors import ConfigError
from ccm.experiment.components import build_components
from ccm.experiment.trial import run_trial
from ccm.sim.pymunk.hri import HumanSpec
from ccm.sim.pymunk.hri_forces import HumanHand


def test_a_goal_sequence_switches_goals_at_their_times() -> None:
    spec = HumanSpec.from_mapping(
        {"goals": [[0, 0], [1, 0], [1, 1]], "goal_times": [0.0, 0.5, 1.0], "stiffness": 10.0,
         "max_force": 100.0}, "task.scene.human",
    )  # fmt: skip
    hand = HumanHand(spec, 0.001)
    for _ in range(2):  # a reset starts the sequence again
        hand.reset(np.random.default_rng(0))
        seen = [(hand.force(0.0, 0.0, 0.0, 0.0, t), hand.goal_index) for t in (0.1, 0.6, 1.2)]
        assert seen == [((0.0, 0.0), 0), ((10.0, 0.0), 1), ((10.0, 10.0), 2)]
    two = {"goals": [[0, 0], [1, 0]], "stiffness": 1.0, "max_force": 1.0}
    with pytest.raises(ConfigError, match=r"human\.goal_times: needs one time per goal"):
        HumanSpec.from_mapping({**two, "goal_times": [0.0]}, "task.scene.human")
    with pytest.raises(ConfigError, match=r"goal_times: must increase strictly"):
        HumanSpec.from_mapping({**two, "goal_times": [0.0, 0.0]}, "task.scene.human")


def test_demo_refuses_3d_tasks_and_bad_arguments(tmp_path: Path, capsys: object) -> None:
    out = str(tmp_path / "d.csv")
    assert main(["demo", "h4_contact_learning", "--out", out]) == 2
    err = capsys.readouterr().err  # type: ignore[attr-defined]
    assert "3-D task; ccm demo records 2-D (pymunk) tasks only" in err
    assert err.count("\n") == 1
    assert main(["demo", "smoke"]) == 2
    assert main(["demo", "smoke", "--out", str(tmp_path / "d.txt")]) == 2
    assert not (tmp_path / "d.csv").exists()


def test_a_smoke_demonstration_is_deterministic_and_reads_back(tmp_path: Path) -> None:
    files = [tmp_path / "a.csv", tmp_path / "b.parquet"]
    for f in files:
        assert main(["demo", "smoke", "--out", str(f), "--seed", "4"]) == 0
    a, b = pd.read_csv(files[0]), pd.read_parquet(files[1])
    pd.testing.assert_frame_equal(a, b, check_dtype=False)  # CSV reads 0 columns as int
    assert list(a.columns) == ["t", "x", "y", "fx", "fy", "human_fx", "human_fy"]
    assert a["x"].iloc[-1] == pytest.approx(0.05, abs=0.01)  # guided to the plan's end
    assert a["human_fx"].abs().max() > 1.0  # the hand pushed


def _replay(file: Path) -> dict[str, np.ndarray]:
    """Replay ``file`` as multi_spring's P with fixed high stiffness, springs removed."""
    with initialize_config_dir(str(config_dir()), version_base="1.3", job_name="test"):
        cfg = compose("config", overrides=[
        "experiment=single", "task=multi_spring", "controller=fixed_impedance_high",
        f"task.pattern=[{{type: recording, file: '{file}'}}]",
        "task.scene.springs=[]",  # free space: the replay has nothing pushing on it
        ])  # fmt: skip
    comp = build_components(cfg)
    try:
        rec = run_trial(comp, seed=0, duration_s=comp.task.duration)
    finally:
        comp.sim.close()
    return rec.arrays()


def test_round_trip_multi_spring_within_1_mm(tmp_path: Path) -> None:
    """Issue #22: a demonstration of multi_spring, replayed as P with fixed high stiffness in
    free space, tracks the *recording* (raw samples, not the smoothed P) within 1 mm RMS."""
    file = tmp_path / "ms.csv"
    assert main(["demo", "multi_spring", "--out", str(file)]) == 0
    demo = pd.read_csv(file)
    # a real guided demonstration: it went round the circle, not exactly along the plan
    angle = np.unwrap(np.arctan2(demo["y"], demo["x"]))
    assert angle[-1] - angle[0] == pytest.approx(2 * np.pi, abs=0.2)
    log = _replay(file)
    t = log["t"]
    ref = np.column_stack([np.interp(t, demo["t"], demo[c]) for c in ("x", "y")])
    err = np.linalg.norm(np.column_stack([log["pos_x"], log["pos_y"]]) - ref, axis=1)
    rms = float(np.sqrt(np.mean(err**2)))
    print(f"round trip multi_spring: RMS {rms * 1e3:.3f} mm, max {err.max() * 1e3:.3f} mm")
    assert 0.0 < rms <= 1e-3
