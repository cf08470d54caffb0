"""Runner: phases carry the controller over, trials are numbered across phases, the summary
averages the last phase, and bad phase/metric specs are one-line config errors."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from ccm.core.errors import ConfigError
from ccm.experiment.components import (
    check_experiment,
    plan_experiment,
    resolve_conditions,
    trial_seed,
)
from ccm.experiment.runner import run_experiment
from ccm.metrics.trial import check_extra_metrics

PHASES = (
    "experiment.phases=[{name: train, trials: 2,"
    " overrides: ['task.scene.springs.0.stiffness=10.0']},"
    " {name: test, trials: 1, overrides: []}]"
)


def test_phases_share_the_controller_and_number_trials(composer, tmp_path: Path) -> None:
    overrides = [
        "experiment=single",
        "task=smoke",
        "controller=bac",
        "experiment.figures=false",
        "experiment.timeseries=all",
        PHASES,
    ]
    cfg = composer(overrides)
    plan = plan_experiment(cfg, lambda extra: composer([*overrides, *extra]), 1)
    ((cond, phases),) = plan
    assert [p.name for p, _ in phases] == ["train", "test"]
    train_scene = phases[0][1].sim.scene
    assert train_scene.springs[0].stiffness == 10.0
    assert phases[1][1].sim.scene.springs[0].stiffness == 40.0  # smoke's own spring

    summary = run_experiment(
        cfg, lambda extra: composer([*overrides, *extra]), tmp_path, show_progress=False
    )
    trials = summary["trials"]
    assert [(t["phase"], t["trial"]) for t in trials] == [("train", 1), ("train", 2), ("test", 3)]
    assert [t["seed"] for t in trials] == [trial_seed(0, k) for k in (1, 2, 3)]
    # the summary's condition figure is the test phase alone
    (name,) = summary["conditions"]
    assert summary["conditions"][name]["rms_tracking_error_m"] == pytest.approx(
        trials[-1]["rms_tracking_error_m"]
    )
    # BAC learned in the train phase: its test trial starts from a learned (stiffer) profile
    assert trials[-1]["mean_stiffness_Npm"] != trials[0]["mean_stiffness_Npm"]
    on_disk = json.loads((tmp_path / "summary.json").read_text())
    assert on_disk == summary
    assert len(list((tmp_path / "timeseries" / name).glob("trial_*.parquet"))) == 3


def test_a_condition_may_set_its_own_trial_count(composer, tmp_path: Path) -> None:
    overrides = ["experiment=smoke", "experiment.trials=3", "experiment.figures=false",
                 "experiment.max_time_s=0.2",
                 "experiment.conditions.fixed_high=['controller=fixed_impedance_high',"
                 "'experiment.trials=1']"]  # fmt: skip
    cfg = composer(overrides)
    summary = run_experiment(
        cfg, lambda extra: composer([*overrides, *extra]), tmp_path, show_progress=False
    )
    counts = {c: sum(t["condition"] == c for t in summary["trials"]) for c in summary["conditions"]}
    assert counts == {"fixed_low": 3, "fixed_high": 1}
    bad = [*overrides[:-1], "experiment.conditions.fixed_high=['experiment.trials=0']"]
    with pytest.raises(ConfigError, match="experiment.trials"):
        plan_experiment(composer(bad), lambda extra: composer([*bad, *extra]), 3)


def test_a_null_condition_is_left_out(composer) -> None:
    """An experiment built on another drops an inherited condition by setting it to null."""
    overrides = ["experiment=smoke", "experiment.conditions.fixed_high=null"]
    cfg = composer(overrides)
    assert "fixed_high" in cfg.experiment.conditions
    names = [c.name for c in resolve_conditions(cfg, lambda extra: composer([*overrides, *extra]))]
    assert names == [
        n for n in composer(["experiment=smoke"]).experiment.conditions if n != "fixed_high"
    ]


@pytest.mark.parametrize(
    ("override", "key"),
    [
        ("experiment.phases=[{name: a, trials: 0}]", "experiment.phases[0].trials"),
        ("experiment.phases=[{name: a, colour: red}]", "experiment.phases[0]"),
        ("experiment.phases=[{name: 'a b'}]", "experiment.phases[0].name"),
        ("experiment.metrics=[accuracy]", "experiment.metrics"),
    ],
)
def test_bad_phase_or_metric_specs(composer, override: str, key: str) -> None:
    overrides = ["experiment=single", override]
    cfg = composer(overrides)
    with pytest.raises(ConfigError) as err:
        check_extra_metrics(cfg)
        plan_experiment(
            cfg, lambda extra: composer([*overrides, *extra]), check_experiment(cfg)["trials"]
        )
    assert err.value.key == key


def test_controller_prepare_sets_the_pattern_the_trial_follows(composer) -> None:
    """``Controller.prepare`` may return a re-timed pattern (seed A §3.5.2): the runner samples
    it and lengthens the trial by the extra wall time; the default follows P as planned."""
    from ccm.control.impedance import FixedImpedance
    from ccm.experiment.components import build_components
    from ccm.experiment.trial import run_trial
    from ccm.tasks.retiming import RetimedPattern, TimeWarp

    class HalfSpeed(FixedImpedance):
        def prepare(self, pattern, contacts, rng):  # type: ignore[no-untyped-def]
            self.seen = (pattern, contacts)
            return RetimedPattern(pattern, TimeWarp(rate0=0.5))

    comp = build_components(composer(["task=smoke"]))
    planned = comp.task.pattern
    n_plain = len(run_trial(comp, seed=0, duration_s=planned.duration))
    slow = HalfSpeed(stiffness=300.0)
    comp_slow = type(comp)(sim=comp.sim, task=comp.task, controller=slow)
    rec = run_trial(comp_slow, seed=0, duration_s=planned.duration)
    assert slow.seen == (planned, comp.task.contacts)
    assert len(rec) == 2 * n_plain  # twice the wall time at half the rate (±0 steps)
    tgt = rec.arrays()
    mid = len(rec) // 2  # wall time T/2 at rate 0.5 is pattern time T/4
    expected = planned.sample(tgt["t"][mid] * 0.5).position
    assert abs(tgt["target_pos_x"][mid] - expected[0]) < 1e-12
    assert abs(tgt["target_pos_y"][mid] - expected[1]) < 1e-12


def test_progress_bar_expect_and_advance_never_pass_100_percent() -> None:
    """The bar's total follows the re-estimate after a trial but never drops below the steps
    done, and a trial running past the total grows it (re-timed trials)."""
    from ccm.experiment.runner import _progress_bar

    bar = _progress_bar(100, "test", True)
    try:
        bar.advance(60)
        bar.expect(150)  # a re-timed trial: the rest of the phase will be longer
        assert (bar.n, bar.total) == (60, 150)
        bar.expect(10)
        assert bar.total == 60
        bar.advance(30)
        assert (bar.n, bar.total) == (90, 90)
        bar.reserve = 50  # steps planned for later trials stay ahead of an overrunning one
        bar.advance(20)
        assert (bar.n, bar.total) == (110, 160)
        bar.trial_steps(400)  # a trial re-timed at its start to 400 steps, 50 after it
        assert bar.total == 110 + 400 + 50
    finally:
        bar.close()
