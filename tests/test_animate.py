"""`ccm animate` and `experiment.animate` (issue #22, "Watching a run"): clips replayed from the
recorded time series of a 2D smoke run and a 3D h4_collisions run (fast mode, one condition)."""

from __future__ import annotations

import json
import math
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from ccm.cli import main
from ccm.core.timeseries import read_timeseries, trial_path
from ccm.plots import frames as frames_mod
from ccm.plots.animate import clip_path
from ccm.plots.frames import frame_steps
from ccm.reporting.report import main as report

CCM = str(Path(sys.executable).parent / "ccm")


def _run(tmp: Path, name: str, *overrides: str) -> Path:
    out = tmp / name
    res = subprocess.run(
        [CCM, "run", *overrides, f"hydra.run.dir={out}"], cwd=tmp, capture_output=True,
        text=True, timeout=180, check=False,
    )  # fmt: skip
    assert res.returncode == 0, res.stderr
    return out


@pytest.fixture(scope="module")
def smoke(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A smoke run (2 conditions x 2 trials of 0.6 s) that also writes its own clips, at a
    frame size and rate other than the defaults."""
    return _run(
        tmp_path_factory.mktemp("smoke"), "run", "experiment=smoke",
        "experiment.animate=first_last", "animate.width=320", "animate.height=240",
        "animate.fps=20", "experiment.figures=false",
    )  # fmt: skip


@pytest.fixture(scope="module")
def h4(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """h4_collisions in fast mode, 0.3 s of its `full` condition only."""
    return _run(
        tmp_path_factory.mktemp("h4"), "run", "experiment=h4_collisions", "experiment.fast=true",
        "experiment.fast_time_s=0.3", "~experiment.conditions.no_contact_handling",
        "~experiment.conditions.full_calibrated", "experiment.figures=false",
        "animate.width=160", "animate.height=120",
    )  # fmt: skip


def _gif(path: Path) -> tuple[int, tuple[int, int], list[np.ndarray]]:
    with Image.open(path) as im:
        frames = []
        for k in range(im.n_frames):
            im.seek(k)
            frames.append(np.asarray(im.convert("RGB")))
        return im.n_frames, im.size, frames


def _expected_frames(run: Path, cond: str, trial: int, fps: float) -> int:
    t = read_timeseries(trial_path(run, cond, trial))["t"]
    return math.ceil(len(t) * float(np.median(np.diff(t))) * fps - 1e-9)


def test_frame_steps_show_the_step_at_each_frame_time() -> None:
    t = np.arange(600) * 1e-3  # 0.6 s at 1 kHz
    idx = frame_steps(t, 25.0)
    assert len(idx) == 15
    assert idx.tolist() == [40 * k for k in range(15)]
    assert (
        len(frame_steps(t[:601], 25.0)) == 15 and len(frame_steps(np.arange(601) * 1e-3, 25)) == 16
    )


def test_2d_gif_without_ffmpeg(
    smoke: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture
) -> None:
    monkeypatch.setattr(frames_mod, "ffmpeg", lambda: None)  # neither imageio-ffmpeg nor PATH
    assert main(["animate", str(smoke)]) == 0  # defaults: first condition, last trial
    out = capsys.readouterr().out
    path = clip_path(smoke, "fixed_low", 2, ".gif")
    assert str(path) in out
    n, size, frames = _gif(path)
    assert n == _expected_frames(smoke, "fixed_low", 2, 20.0) == 12  # 0.6 s at 20 fps
    assert size == (320, 240)
    assert not np.array_equal(frames[0], frames[-1])  # the tool moved
    # --fps and --out; an .mp4 without ffmpeg is refused in one line
    assert main(["animate", str(smoke), "--trial", "1", "--fps", "10", "--out",
                 str(tmp_path / "a.gif")]) == 0  # fmt: skip
    assert _gif(tmp_path / "a.gif")[0] == 6
    assert main(["animate", str(smoke), "--out", str(tmp_path / "a.mp4")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "--out" in err and "ffmpeg" in err


def test_2d_mp4_without_a_system_ffmpeg(smoke: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The default clip is an MP4 through imageio-ffmpeg's binary, with no ffmpeg on PATH."""
    import imageio_ffmpeg

    monkeypatch.setattr(frames_mod.shutil, "which", lambda name: None)  # no system ffmpeg
    assert main(["animate", str(smoke), "--condition", "fixed_high", "--trial", "1"]) == 0
    path = clip_path(smoke, "fixed_high", 1, ".mp4")
    assert path.read_bytes()[4:8] == b"ftyp"  # an MP4 container
    frames = imageio_ffmpeg.read_frames(str(path))
    meta = next(frames)
    assert meta["codec"] == "h264" and tuple(meta["size"]) == (320, 240)
    count = sum(1 for _ in frames)
    assert count == _expected_frames(smoke, "fixed_high", 1, 20.0)


def test_experiment_animate_first_last_and_report(smoke: Path) -> None:
    """The run wrote a clip of both trials of each condition; the report embeds them."""
    suffix = ".mp4"  # imageio-ffmpeg is a dependency
    for cond in ("fixed_low", "fixed_high"):
        for trial in (1, 2):
            assert clip_path(smoke, cond, trial, suffix).stat().st_size > 1000
    assert "animate_wall_s" in json.loads((smoke / "run_info.json").read_text())
    assert "animate_wall_s" not in (smoke / "summary.json").read_text()
    assert report([str(smoke)]) == 0
    page = (smoke / "report.html").read_text()
    assert page.count("<video") == 4
    assert "data:video/mp4;base64," in page


def test_3d_replay_of_the_recorded_joints(h4: Path, tmp_path: Path) -> None:
    out = tmp_path / "h4.gif"
    assert main(["animate", str(h4), "--fps", "50", "--out", str(out)]) == 0
    n, size, frames = _gif(out)
    assert n == _expected_frames(h4, "full", 1, 50.0) == 15  # 0.3 s at 50 fps
    assert size == (160, 120)
    assert len(np.unique(frames[0].reshape(-1, 3), axis=0)) > 20  # a rendered scene, not blank


def test_recorded_joints_put_the_tool_where_it_was(h4: Path) -> None:
    """Forward kinematics of the recorded joint angles gives the recorded tool point."""
    import pybullet as p
    from omegaconf import OmegaConf

    from ccm.core.errors import to_plain
    from ccm.plots.animate3d import JOINT_COLUMNS
    from ccm.sim.pybullet.robot import load_robot, tool_point_state
    from ccm.sim.pybullet.scene import PyBullet3DConfig

    log = read_timeseries(trial_path(h4, "full", 1))
    config = PyBullet3DConfig.from_mapping(
        to_plain(OmegaConf.load(h4 / ".hydra" / "config.yaml").sim), "sim"
    )
    cid = p.connect(p.DIRECT)
    try:
        robot, tool = load_robot(p, cid, config)
        for k in (0, len(log["t"]) // 2, len(log["t"]) - 1):
            for j, col in enumerate(JOINT_COLUMNS):
                p.resetJointState(robot, j, float(log[col][k]), physicsClientId=cid)
            pos = tool_point_state(p, cid, robot, tool, (0, 0, config.tool.size[2] / 2), False)[0]
            recorded = [log[f"pos_{a}"][k] for a in "xyz"]
            assert np.allclose(pos, recorded, atol=2e-5)  # float32 at 18 bits: ~2 um at 1 m
    finally:
        p.disconnect(physicsClientId=cid)


def test_bad_arguments_one_line_each(
    smoke: Path, tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    bare = tmp_path / "no_series"  # a run made with experiment.timeseries=none has no files
    shutil.copytree(smoke, bare, ignore=shutil.ignore_patterns("timeseries", "animations"))
    cases = [
        ([str(tmp_path / "missing")], "RUN_DIR", "does not exist"),
        ([str(tmp_path)], "RUN_DIR", "no .hydra/config.yaml"),
        ([str(bare)], "RUN_DIR", "experiment.timeseries"),
        ([str(smoke), "--condition", "nope"], "--condition", "allowed: fixed_low, fixed_high"),
        ([str(smoke), "--trial", "7"], "--trial", "recorded: 1, 2"),
        ([str(smoke), "--trial", "x"], "animate", "invalid int value"),
        ([str(smoke), "--fps", "0"], "--fps", "must be in [1.0, 100.0], got 0.0"),
        ([str(smoke), "--out", "clip.avi"], "--out", ".mp4 or .gif"),
        ([str(smoke), "--bogus"], "animate", "unexpected '--bogus'"),
        ([], "animate", "RUN_DIR is required"),
    ]
    for args, key, text in cases:
        assert main(["animate", *args]) == 2, args
        err = capsys.readouterr().err.strip()
        assert err.count("\n") == 0 and err.startswith(f"ccm: error: {key}"), err
        assert text in err, err


def test_bad_experiment_animate_is_refused_before_the_run(tmp_path: Path) -> None:
    for override, key in (("experiment.animate=all", "experiment.animate"),
                          ("animate.width=641", "animate.width")):  # fmt: skip
        res = subprocess.run([CCM, "run", "experiment=smoke", override], cwd=tmp_path,
                             capture_output=True, text=True, timeout=120, check=False)  # fmt: skip
        assert res.returncode == 2
        assert res.stderr.strip().startswith(f"ccm: error: {key}:"), res.stderr
        assert not (tmp_path / "outputs").exists()
