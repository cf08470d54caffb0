"""``make bench``'s paper floor (ccm/bench/floor.py): the work each run recorded (physics
steps, resets, MPC solves, H3 fits), the floor's arithmetic and its wall-clock bound, and the
raw engine loop's CPU cost per physics step. Speeds are not asserted; the bookkeeping is."""

from __future__ import annotations

import json
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np
import pytest
from omegaconf import DictConfig, OmegaConf

from ccm.bench.floor import (
    RunWork,
    floor_rows,
    paper_floor,
    print_floor,
    run_work,
    scene_key,
    totals,
)

Composer = Callable[[Sequence[str]], DictConfig]


def _run_dir(root: Path, cfg: DictConfig, summary: dict, info: dict) -> Path:
    (root / ".hydra").mkdir(parents=True)
    OmegaConf.save(cfg, root / ".hydra" / "config.yaml")
    (root / "summary.json").write_text(json.dumps(summary))
    (root / "run_info.json").write_text(json.dumps(info))
    return root


def test_a_trial_run_counts_its_simulated_steps_trials_and_mpc_solves(
    tmp_path: Path, composer: Composer
) -> None:
    cfg = composer(["experiment=mpc_contact"])
    trials = [
        {"condition": "a", "mpc_solves": 100.0},
        {"condition": "a", "mpc_solves": 50.0},
        {"condition": "b", "mpc_solves": 30.0},
        {"condition": "c", "mpc_solves": 0.0},  # no MPC solve timing recorded for c
    ]
    info = {
        "sim_time_s": 12.345,
        "mpc_cpu_rate_hz": {"a": 200.0, "b": 60.0},
        "cpu_s": {"plan": 0.5, "trials": 9.0, "figures": 1.5},
    }
    w = run_work(_run_dir(tmp_path / "r", cfg, {"trials": trials}, info))
    assert cfg.sim.dt == 0.001
    assert w.physics_steps == 12345
    assert w.resets == 4
    assert w.mpc_s == pytest.approx(150 / 200.0 + 30 / 60.0, rel=1e-12)
    assert w.fits_s == 0.0
    assert w.cpu_parts == {"plan": 0.5, "trials": 9.0, "figures": 1.5}
    assert w.scene == scene_key(OmegaConf.to_container(cfg, resolve=True))


def test_an_h3_run_counts_the_trials_its_collection_records(
    tmp_path: Path, composer: Composer
) -> None:
    from ccm.analyses.h3_data import SETTLE_TIME_S
    from ccm.tasks.task import load_task

    cfg = composer(["experiment=h3_long_horizon"])
    info = {"collect_s": 300.0, "joint_single_train_s": 20.0, "task_long_predict_s": 5.0}
    w = run_work(_run_dir(tmp_path / "h3", cfg, {"trials": []}, info))
    h3 = cfg.h3
    trials = 2 * len(h3.train_frictions) * h3.trials_per_friction + 2 * h3.test_trials
    assert h3.single_friction in h3.train_frictions  # so medium_single is not recorded anew
    seconds = load_task(cfg.task, cfg.sim.dt).duration + SETTLE_TIME_S
    assert w.resets == trials
    assert w.physics_steps == trials * round(seconds / cfg.sim.dt)
    assert w.fits_s == 25.0 and w.mpc_s == 0.0


@pytest.mark.parametrize("single_friction", [0.6, 0.65])
def test_h3_collection_plan_is_what_the_datasets_record(
    monkeypatch: pytest.MonkeyPatch, composer: Composer, tmp_path: Path, single_friction: float
) -> None:
    """The plan the floor reads from the config equals the trials ``_datasets`` records,
    with medium_single reused (0.6 is a training friction) or recorded anew (0.65)."""
    import ccm.analyses.h3 as h3mod

    recorded: list[float] = []

    def fake_collect(compose, overrides, frictions, n, seed, **kw):  # noqa: ANN001, ANN003, ANN202, ARG001
        out = [{"wall_friction": np.array(float(f))} for f in frictions for _ in range(n)]
        recorded.extend(float(f) for f in frictions for _ in range(n))
        return out

    monkeypatch.setattr(h3mod, "collect", fake_collect)
    cfg = composer(["experiment=h3_long_horizon", f"h3.single_friction={single_friction}"])
    h3mod._datasets(h3mod._settings(cfg), cfg, None, tmp_path)
    trials, seconds = h3mod.collection_plan(cfg, 7.2)
    assert trials == len(recorded)
    assert seconds == pytest.approx(7.2 + h3mod.trial_duration_s(0.0), rel=1e-12)


def test_floor_arithmetic_and_the_wall_clock_bound() -> None:
    runs = {
        "a": [RunWork("r1", "s1", 1000, 2, 3.0, 0.0), RunWork("r2", "s2", 500, 0, 0.0, 4.0)],
        "b": [RunWork("r3", "s1", 2000, 1, 0.0, 0.0)],
        "c": [RunWork("r4", "none", 0, 0, 1.0, 0.0)],  # no simulation: its scene is not timed
    }
    costs = {"s1": (1e-3, 0.5), "s2": (2e-3, 0.0)}
    rows = {r["sweep"]: r for r in floor_rows(runs, costs, {"a": 24.0, "b": 7.5})}
    a = rows["a"]
    assert (a["engine_s"], a["reset_s"], a["mpc_s"], a["fits_s"]) == (2.0, 1.0, 3.0, 4.0)
    assert a["floor_s"] == 10.0 and a["ratio"] == 2.4
    assert a["longest_run_floor_s"] == 1.0 + 1.0 + 3.0
    assert rows["b"]["floor_s"] == 2.5 and rows["b"]["ratio"] == 3.0
    assert rows["c"]["floor_s"] == 1.0 and rows["c"]["ratio"] is None  # not timed
    t = totals(list(rows.values()), cores=2)
    assert t["floor_cpu_s"] == 13.5 and t["engines_cpu_s"] == 2.0 + 1.0 + 2.0 + 0.5
    assert t["wall_floor_s"] == 13.5 / 2
    assert totals(list(rows.values()), cores=4)["wall_floor_s"] == 5.0  # the longest run


def test_the_target_budget_and_the_runs_cpu_parts() -> None:
    """The target's CPU (wall × cores) less the floor is ccm's own budget, also per physics
    step; the runs' recorded CPU parts add up over the runs that have them."""
    runs = {
        "a": [
            RunWork("r1", "s1", 1000, 0, 0.0, 0.0, {"plan": 1.0, "trials": 5.0, "figures": 2.0}),
            RunWork("r2", "s1", 3000, 0, 0.0, 0.0),  # an analysis, or recorded before cpu_s
        ],
        "b": [RunWork("r3", "s1", 1000, 0, 0.0, 0.0, {"plan": 0.5, "trials": 1.0})],
    }
    rows = floor_rows(runs, {"s1": (1e-3, 0.0)}, {"a": 30.0, "b": 4.0})
    assert rows[0]["cpu_parts_s"] == {"runs": 1.0, "plan": 1.0, "trials": 5.0, "figures": 2.0}
    t = totals(rows, cores=2, target_wall_s=10.0)  # floor 5 s of engine, 34 s measured
    assert t["budget_cpu_s"] == 20.0 and t["own_budget_s"] == 15.0
    assert t["own_budget_us_per_step"] == pytest.approx(15.0 / 5000 * 1e6)
    assert t["own_measured_s"] == 29.0
    assert t["own_measured_us_per_step"] == pytest.approx(29.0 / 5000 * 1e6)
    assert t["cpu_parts_s"] == {"runs": 2.0, "plan": 1.5, "trials": 6.0, "figures": 2.0}
    # the figures ccm paper draws after the sweeps (issue #40) count in the measured CPU
    after = totals(rows, cores=2, target_wall_s=10.0, figures_after_s=3.0)
    assert after["measured_cpu_s"] == 37.0 and after["own_measured_s"] == 32.0
    assert after["cpu_parts_s"]["figures"] == 5.0


def test_without_a_paper_run_the_floor_says_so(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert paper_floor(tmp_path) is None
    print_floor(None, tmp_path)
    assert "run make reproduce-paper for the floor" in capsys.readouterr().out


def test_raw_cpu_per_step_is_per_physics_step(
    composer: Composer, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Whole passes over the pattern until the budget is spent, divided by the physics steps
    (control steps × decimation); a clock that ticks 1 s per reading makes each pass 1 s."""
    import itertools

    import ccm.bench.engines as engines
    from ccm.experiment.components import build_components

    comp = build_components(composer(["task=smoke", "sim.control_decimation=2"]))
    try:
        assert engines.raw_reset_cpu(comp.sim) == 0.0  # pymunk: no engine reset to count
        ticks = itertools.count()
        monkeypatch.setattr(engines.time, "process_time", lambda: float(next(ticks)))
        step_s = engines.raw_cpu_per_step(comp.sim, comp.task.pattern, budget_s=3.0)
        steps = int(comp.task.pattern.duration / comp.sim.control_dt)
        assert step_s == pytest.approx(3.0 / (3 * steps * 2), rel=1e-12)
    finally:
        comp.sim.close()
