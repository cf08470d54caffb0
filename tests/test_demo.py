"""``ccm demo``: a demonstration recorded in simulation (seed B's simulated human guiding the
robot in admittance mode), read back as P and replayed (issue #22's round trip)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from hydra import compose, initialize_config_dir

from ccm.cli import config_dir, main
from ccm.core.errors import ConfigError
from ccm.experiment.components import build_components
from ccm.experiment.trial import run_trial
from ccm.sim.hand import Hand, HandSpec
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


def test_the_nd_hand_follows_its_goal_sequence_and_saturates() -> None:
    spec = HandSpec.from_mapping(
        {"goals": [[0, 0, 0], [0, 0, 1]], "goal_times": [0, 1.0], "stiffness": 100.0,
         "damping": 10.0, "max_force": 50.0}, "task.scene.human", 3,
    )  # fmt: skip
    hand = Hand(spec, 0.001)
    hand.reset(np.random.default_rng(0))
    p, v = np.array([0.1, 0.0, 0.0]), np.array([0.0, 0.0, 1.0])
    np.testing.assert_allclose(hand.force(p, v, 0.5), [-10.0, 0.0, -10.0])
    f = hand.force(p, np.zeros(3), 1.5)  # k (g - p) = (-10, 0, 100), scaled to 50 N
    np.testing.assert_allclose(f, np.array([-10.0, 0.0, 100.0]) * 50.0 / np.hypot(10, 100))
    with pytest.raises(ConfigError, match=r"human\.goal_times: needs one time per goal"):
        bad = {"goals": [[0, 0, 0]], "goal_times": [0, 1], "stiffness": 1.0, "max_force": 1.0}
        HandSpec.from_mapping(bad, "task.scene.human", 3)


def test_demo_refuses_bad_arguments(tmp_path: Path, capsys: object) -> None:
    assert main(["demo", "smoke"]) == 2
    assert main(["demo", "smoke", "--out", str(tmp_path / "d.txt")]) == 2
    assert main(["demo", "smoke", "--out", str(tmp_path / "d.csv"), "--bogus"]) == 2
    err = capsys.readouterr().err  # type: ignore[attr-defined]
    assert err.count("\n") == 3 and "d.txt: must end in .csv or .parquet" in err
    assert not list(tmp_path.iterdir())


def test_a_smoke_demonstration_is_deterministic_and_reads_back(tmp_path: Path) -> None:
    files = [tmp_path / "a.csv", tmp_path / "b.parquet"]
    for f in files:
        assert main(["demo", "smoke", "--out", str(f), "--seed", "4"]) == 0
    a, b = pd.read_csv(files[0]), pd.read_parquet(files[1])
    pd.testing.assert_frame_equal(a, b, check_dtype=False)  # CSV reads 0 columns as int
    assert list(a.columns) == ["t", "x", "y", "fx", "fy", "human_fx", "human_fy"]
    assert a["x"].iloc[-1] == pytest.approx(0.05, abs=0.01)  # guided to the plan's end
    assert a["human_fx"].abs().max() > 1.0  # the hand pushed


def _replay(file: Path, task: str, free_space: Sequence[str]) -> dict[str, np.ndarray]:
    """Replay ``file`` as ``task``'s P with fixed high stiffness, ``free_space`` overrides
    removing what the scene could push the tool with."""
    pattern = f"task.pattern=[{{type: recording, file: '{file}', use_force: false}}]"
    with initialize_config_dir(str(config_dir()), version_base="1.3", job_name="test"):
        cfg = compose("config", overrides=[
            "experiment=single", f"task={task}", "controller=fixed_impedance_high", pattern,
            *free_space,
        ])  # fmt: skip
    comp = build_components(cfg)
    try:
        rec = run_trial(comp, seed=0, duration_s=comp.task.duration)
    finally:
        comp.sim.close()
    return rec.arrays()


def _rms_to_recording(log: dict[str, np.ndarray], demo: pd.DataFrame, axes: str) -> float:
    """RMS distance of the replayed positions from the raw recorded ones [m]."""
    t = log["t"]
    ref = np.column_stack([np.interp(t, demo["t"], demo[a]) for a in axes])
    err = np.linalg.norm(np.column_stack([log[f"pos_{a}"] for a in axes]) - ref, axis=1)
    print(f"round trip: RMS {np.sqrt(np.mean(err**2)) * 1e3:.3f} mm, max {err.max() * 1e3:.3f} mm")
    return float(np.sqrt(np.mean(err**2)))


def test_round_trip_multi_spring_within_1_mm(tmp_path: Path) -> None:
    """Issue #22: a demonstration of multi_spring, replayed as P with fixed high stiffness in
    free space, tracks the *recording* (raw samples, not the smoothed P) within 1 mm RMS."""
    file = tmp_path / "ms.csv"
    assert main(["demo", "multi_spring", "--out", str(file)]) == 0
    demo = pd.read_csv(file)
    # a real guided demonstration: it went round the circle, not exactly along the plan
    angle = np.unwrap(np.arctan2(demo["y"], demo["x"]))
    assert angle[-1] - angle[0] == pytest.approx(2 * np.pi, abs=0.2)
    log = _replay(file, "multi_spring", ["task.scene.springs=[]"])
    assert 0.0 < _rms_to_recording(log, demo, "xy") <= 1e-3


def test_round_trip_h4_contact_learning_3d_within_1_mm(tmp_path: Path) -> None:
    """The same in 3D: the hand guides the Panda's tool down onto the table, into the wall and
    the obstacle (the contact forces are recorded), and the replay without table and boxes
    tracks the recording within 1 mm RMS."""
    file = tmp_path / "h4.parquet"
    assert main(["demo", "h4_contact_learning", "--out", str(file)]) == 0
    demo = pd.read_parquet(file)
    end = demo[["x", "y", "z"]].to_numpy()[-1]
    np.testing.assert_allclose(end, [0.60, 0.10, 0.10], atol=2e-3)  # pressed into the corner
    assert demo["fz"].min() < -5.0 and demo["fx"].max() > 5.0  # table and obstacle pushed on
    free = ["sim=pybullet3d", "task.scene.boxes=[]", "task.scene.table=null", "task.contacts=[]"]
    log = _replay(file, "h4_contact_learning", free)
    assert 0.0 < _rms_to_recording(log, demo, "xyz") <= 1e-3


def test_the_h4_demonstration_task_loads_with_named_windows() -> None:
    """task=h4_contact_learning_demo: P from the stored demonstration, cut into the plan's
    segment names so the contacts' annotations resolve; the file is small and C² across the
    window edges."""
    from ccm.tasks.task import load_task

    with initialize_config_dir(str(config_dir()), version_base="1.3", job_name="test"):
        cfg = compose("config", overrides=["sim=pybullet3d", "task=h4_contact_learning_demo"])
    task = load_task(cfg.task, 0.001)
    names = [s.name for s in task.pattern.segments]
    assert names == ["approach", "press", "slide_to_wall", "settle_on_wall",
                     "slide_along_wall", "settle_on_obstacle"]  # fmt: skip
    assert [n["segment_index"] for n in task.contact_annotations] == [0, 2, 4]
    assert task.pattern.duration == pytest.approx(8.7)
    assert (config_dir() / "demos" / "h4_contact_learning.csv").stat().st_size < 120_000
    edges = np.asarray(task.pattern.start_times[1:])
    left, right = (task.pattern.sample_many(edges + d) for d in (-1e-9, 1e-9))
    for name in ("position", "velocity", "acceleration"):
        np.testing.assert_allclose(left[name], right[name], atol=1e-6, err_msg=name)
    late = task.pattern.sample(8.0)  # pressing on table, wall and obstacle at the end
    assert late.force_mag > 10.0 and late.force_dir is not None and late.force_dir[2] < -0.5
