"""The 3D ``table_wall`` task (seed A Fig. 1b, §4.4): press on a table, slide into a wall,
slide along the wall.

Each trial is composed the way ``ccm run`` composes it (``sim=pybullet3d task=table_wall
controller=…``) and run for the full pattern plus the usual 0.5 s settle; the checks use
the simulator's ground truth (``true_force_*``, ``truth_table_normal_N``,
``truth_box_normal_N``, ``truth_box_friction_N``). A trial takes ~3 s, so the few trials
are run once per module and shared. Every assertion states its tolerance.
"""

from __future__ import annotations

import json
import math
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from omegaconf import OmegaConf

from ccm.core.timeseries import read_timeseries
from ccm.core.types import Command, Observation, StepInfo
from ccm.experiment.components import build_components
from ccm.experiment.trial import run_trial

pytest.importorskip("pybullet")

BASE = ["sim=pybullet3d", "task=table_wall", "experiment=single"]
WALL_FRICTION = "task.scene.boxes.0.friction"  # the one field H3 varies (seed A §4.4)
TABLE_TOP = 0.1  # m, task.scene.table.height
CONTACT_X = 0.58  # m, tool point x at wall contact: wall face 0.60 - half the 4 cm tool
INTO_WALL = 0.01  # m, the target's offset into the wall (task.pattern, slide_to_wall)
WALL_SLIDE = 0.2  # m, commanded y travel along the wall (-0.1 -> +0.1)
PRESS_N = 10.0  # N, the force target on the table
TABLE_MU = 0.3  # task.scene.table.friction
K_FIXED = 300.0  # N/m, configs/controller/fixed_impedance.yaml

_RUNS: dict[tuple[str, ...], dict[str, Any]] = {}


def trial(composer, *overrides: str) -> dict[str, Any]:
    """Compose, run the full pattern once (cached per override set) and return the log, the
    segment time spans, the worst normal force on a robot link other than the tool and the
    scene. ``run_trial`` raises ``SimulationDiverged`` on a non-finite state or a runaway."""
    key = tuple(overrides)
    if key in _RUNS:
        return _RUNS[key]
    cfg = composer([*BASE, *overrides])
    comp = build_components(cfg)
    sim = comp.sim
    worst_other = [0.0]
    step = sim.step

    def watched_step(cmd: Command) -> tuple[Observation, StepInfo]:
        out = step(cmd)
        if sim.physics_steps % 10 == 0:  # a hand/arm contact is invisible to the F/T sensor
            pts = sim._p.getContactPoints(bodyA=sim._robot, physicsClientId=sim._client)  # noqa: SLF001
            for c in pts:
                if c[3] != sim._tool_link:  # noqa: SLF001
                    worst_other[0] = max(worst_other[0], c[9])
        return out

    sim.step = watched_step  # type: ignore[method-assign]
    duration = comp.task.pattern.duration + 0.5  # experiment.settle_time_s default
    try:
        t0 = time.perf_counter()
        rec = run_trial(comp, seed=0, duration_s=duration)
        wall = time.perf_counter() - t0
    finally:
        sim.close()
    pattern = comp.task.pattern
    spans = {
        seg.name: (t0_, t0_ + seg.duration)
        for seg, t0_ in zip(pattern.segments, pattern.start_times, strict=True)
    }
    a = rec.arrays()
    run = {"a": a, "spans": spans, "other_contact_N": worst_other[0], "scene": sim.scene}
    force = np.stack([a["true_force_x"], a["true_force_y"], a["true_force_z"]], axis=1)
    peak = np.linalg.norm(force, axis=1)
    print(
        f"\n[table_wall] {' '.join(overrides)}: {duration:.1f} s simulated in {wall:.2f} s "
        f"({duration / wall:.1f}x real time); peak |F| {peak.max():.1f} N at "
        f"t={a['t'][peak.argmax()]:.2f} s"
    )
    _RUNS[key] = run
    return run


def phase(run: dict[str, Any], name: str, skip_s: float = 0.0) -> np.ndarray:
    """Mask of the samples in segment ``name`` from ``skip_s`` after its start
    (``slide_along_wall`` extends to the end of the log: the settle time)."""
    t = run["a"]["t"]
    t0, t1 = run["spans"][name]
    if name == "slide_along_wall":
        t1 = float(t[-1]) + 1e-9
    return (t >= t0 + skip_s) & (t < t1)


def check_contacts(run: dict[str, Any], press_rel: float, wall_frac: float) -> None:
    """The table and wall contacts every controller must make on this task."""
    a = run["a"]
    # free-space approach: no contact at all
    assert np.all(a["n_contacts"][phase(run, "approach")] == 0)
    # the tool rests on the table during the press: normal force on the table near the 10 N
    # target over the press's second half (force loop settled), no wall contact yet
    press = phase(run, "press", skip_s=0.25)
    table_n = float(np.mean(a["truth_table_normal_N"][press]))
    assert table_n == pytest.approx(PRESS_N, rel=press_rel)
    assert np.all(a["truth_box_normal_N"][press] == 0.0)
    assert np.all(np.abs(a["pos_z"][press] - TABLE_TOP) < 5e-4)  # m: on the top, not above
    # sliding along the wall (after its first 0.5 s, when the tool is moving): the wall
    # pushes the tool back along -x (the wall normal, sign checked on the total truth force)
    # by more than 1 N in at least `wall_frac` of the samples
    wall = phase(run, "slide_along_wall", skip_s=0.5)
    assert np.mean(a["true_force_x"][wall] < -1.0) >= wall_frac
    assert np.mean(a["truth_box_normal_N"][wall] > 1.0) >= wall_frac


def check_no_divergence(run: dict[str, Any], max_speed: float) -> None:
    """Finite log, bounded speed, and no robot link but the tool presses on anything (a
    hand-on-wall contact would be invisible to the F/T sensor)."""
    a = run["a"]
    for col in ("pos_x", "pos_y", "pos_z", "true_force_x", "true_force_y", "true_force_z"):
        assert np.all(np.isfinite(a[col]))
    speed = np.sqrt(a["vel_x"] ** 2 + a["vel_y"] ** 2 + a["vel_z"] ** 2)
    assert speed.max() < max_speed
    assert run["other_contact_N"] == 0.0


def y_travel(run: dict[str, Any]) -> float:
    """y travelled from the start of the wall slide to the end of the log [m]."""
    a = run["a"]
    i0 = int(np.argmax(phase(run, "slide_along_wall")))
    return float(a["pos_y"][-1] - a["pos_y"][i0])


def test_fixed_impedance_presses_table_hits_wall_and_slides_along_it(composer) -> None:
    run = trial(composer, "controller=fixed_impedance")
    a = run["a"]
    check_contacts(run, press_rel=0.05, wall_frac=1.0)  # 10 N within 5 %; wall: every sample
    check_no_divergence(run, max_speed=0.3)  # m/s: the pattern peaks at 0.14 m/s
    wall = phase(run, "slide_along_wall", skip_s=0.5)
    # the tool stays against the wall's face (x = 0.58 m) within 1 mm, and while it slides
    # the truth split agrees with the total force (table friction is along y then): 0.2 N
    assert np.all(np.abs(a["pos_x"][wall] - CONTACT_X) < 1e-3)
    sliding = wall & (a["vel_y"] > 0.02)  # m/s
    assert np.max(np.abs(a["truth_box_normal_N"][sliding] + a["true_force_x"][sliding])) < 0.2
    # wall normal force = stiffness x the 1 cm offset into the wall = 3 N, within 0.3 N
    expected_wall_n = K_FIXED * INTO_WALL
    assert float(np.mean(a["truth_box_normal_N"][wall])) == pytest.approx(expected_wall_n, abs=0.3)
    # y travel: the 20 cm commanded, minus where the spring balances the sliding friction of
    # table and wall, (mu_t F_press + mu_w F_wall) / K = (3 + 1.8) / 300 = 1.6 cm; within 5 mm
    mu_w = run["scene"].boxes[0].friction
    lag = (TABLE_MU * PRESS_N + mu_w * expected_wall_n) / K_FIXED
    assert y_travel(run) == pytest.approx(WALL_SLIDE - lag, abs=0.005)
    # contacts happen at the slow ends of segments: the table touch stays below 50 N (35 N
    # measured) and the wall impact below 100 N (30 N measured), far from the ~300 N of a
    # force-controlled descent onto the table (press_slide_3d)
    f = np.linalg.norm(np.stack([a[f"true_force_{ax}"] for ax in "xyz"], axis=1), axis=1)
    touch = phase(run, "touch") | phase(run, "press")
    hit = phase(run, "slide_to_wall") | phase(run, "settle_on_wall")
    print(
        f"[table_wall] fixed_impedance: peak |F| table touch {f[touch].max():.1f} N, wall "
        f"impact {f[hit].max():.1f} N; wall slide: wall normal "
        f"{np.mean(a['truth_box_normal_N'][wall]):.2f} N, table normal "
        f"{np.mean(a['truth_table_normal_N'][wall]):.2f} N, F_y "
        f"{np.mean(a['true_force_y'][wall]):.2f} N; y travel {y_travel(run) * 100:.2f} cm"
    )
    assert f[touch].max() < 50.0
    assert f[hit].max() < 100.0
    assert f[phase(run, "slide_along_wall", skip_s=0.5)].max() < 20.0  # N: smooth sliding


def test_wall_friction_override_changes_the_friction_along_the_wall(composer) -> None:
    """Seed A §4.4 varies the wall friction (0.1-0.7 train, 0.9 test) with one config field."""
    runs = {
        mu: trial(composer, "controller=fixed_impedance", f"{WALL_FRICTION}={mu}")
        for mu in (0.1, 0.7)
    }
    stats = {}
    for mu, run in runs.items():
        a = run["a"]
        assert run["scene"].boxes[0].friction == mu  # the override reached the simulator
        wall = phase(run, "slide_along_wall", skip_s=0.5)
        sliding = wall & (a["vel_y"] > 0.02)  # m/s: kinetic friction only
        assert sliding.sum() > 500  # samples (> 0.5 s of sliding)
        ratio = a["truth_box_friction_N"][sliding] / a["truth_box_normal_N"][sliding]
        # the wall's friction/normal ratio is the configured coefficient, within 5 %
        assert float(np.median(ratio)) == pytest.approx(mu, rel=0.05)
        stats[mu] = (
            float(np.mean(-a["true_force_y"][sliding])),
            float(np.mean(a["truth_box_normal_N"][sliding])),
            y_travel(run),
        )
    (fy1, n1, y1), (fy7, n7, y7) = stats[0.1], stats[0.7]
    print(
        f"\n[table_wall] wall friction 0.1 vs 0.7 while sliding: -F_y {fy1:.2f} vs {fy7:.2f} N "
        f"(wall normal {n1:.2f} / {n7:.2f} N); y travel {y1 * 100:.2f} vs {y7 * 100:.2f} cm"
    )
    # the total friction along y (table + wall) grows by (0.7 - 0.1) x the ~3 N wall normal
    # force = 1.8 N; within 0.4 N
    assert fy7 - fy1 == pytest.approx((0.7 - 0.1) * 0.5 * (n1 + n7), abs=0.4)
    # ... so the controller ends further behind its target, by (0.7 - 0.1) K d / K = 6 mm,
    # within 2 mm
    assert y1 - y7 == pytest.approx((0.7 - 0.1) * INTO_WALL, abs=0.002)


def test_avic_runs_the_full_pattern(composer) -> None:
    """AVIC (Eq. 4a-4c) on the same task: contacts and wall slide as above, no divergence."""
    run = trial(composer, "controller=avic")
    # 10 N within 10 %; the wall pushes back in >= 80 % of the wall slide (97 % measured: the
    # feed-forward runaway, see below, throws the tool off the wall for a moment)
    check_contacts(run, press_rel=0.1, wall_frac=0.8)
    check_no_divergence(run, max_speed=1.5)  # m/s: 0.88 m/s measured when thrown off
    # the stiffer AVIC (K_p between 300 and 3000 N/m) follows the 20 cm more closely than
    # the fixed 300 N/m controller's 18.4 cm: within 2 cm of the command
    assert y_travel(run) == pytest.approx(WALL_SLIDE, abs=0.02)


def test_avic_contact_forces_stay_bounded(composer) -> None:
    """AVIC's default feed-forward direction (``along_motion``) cancels no constraint's
    reaction, so pressing into the table and the wall by position stays bounded. The fixed
    Eq. 4c values put the feed-forward to work from the first trial (the default calibration
    would hold K_max without feed-forward in trial 1). With ``measured`` the same trial peaked
    at 0.2-3 kN (F = K d / (1 - lambda), experiments/h4.md)."""
    run = trial(composer, "controller=avic", "controller.calibrate=null", "controller.r=2.0",
                "controller.eps0=5.0")  # fmt: skip
    a = run["a"]
    lam = a["lambda"][np.isfinite(a["lambda"])]
    assert np.mean(lam > 0.5) > 0.5, "the feed-forward acts on most steps"
    f = np.linalg.norm(np.stack([a[f"true_force_{ax}"] for ax in "xyz"], axis=1), axis=1)
    assert f.max() < 200.0  # N: twice the fixed controller's 100 N bound


def test_cli_run_with_wall_friction_override(tmp_path: Path) -> None:
    """``ccm run`` as a user types it, with the wall friction override (a 0.1 s trial)."""
    ccm = str(Path(sys.executable).parent / "ccm")
    res = subprocess.run(
        [
            ccm, "run", *BASE, "controller=fixed_impedance", f"{WALL_FRICTION}=0.9",
            "experiment.max_time_s=0.1", "experiment.figures=false",
        ],
        cwd=tmp_path, capture_output=True, text=True, timeout=120, check=False,
    )  # fmt: skip
    assert res.returncode == 0, res.stderr
    (cfg_file,) = list((tmp_path / "outputs").rglob(".hydra/config.yaml"))
    run_dir = cfg_file.parent.parent
    cfg = OmegaConf.load(cfg_file)
    assert cfg.task.name == "table_wall"
    assert math.isclose(cfg.task.scene.boxes[0].friction, 0.9)
    assert json.loads((run_dir / "summary.json").read_text())["status"] == "ok"
    (path,) = list((run_dir / "timeseries").rglob("trial_001.parquet"))
    header = read_timeseries(path)
    for col in ("truth_table_normal_N", "truth_box_normal_N", "truth_box_friction_N"):
        assert col in header
