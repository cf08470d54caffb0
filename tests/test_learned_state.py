"""Learned state across trials and sessions (issue #5, point 4): controllers save what they
learned as JSON at the end of a run, and ``init_from=<run dir>`` starts a run from it."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from omegaconf import DictConfig

from ccm.control.base import Controller
from ccm.control.registry import make_controller
from ccm.core.errors import ConfigError, to_plain
from ccm.core.types import Observation, TargetSample
from ccm.experiment.components import plan_experiment, save_learned_states
from ccm.experiment.learned_state import STATE_FORMAT

Composer = Callable[[Sequence[str]], DictConfig]
DOWN = np.array([0.0, -1.0])
CCM = str(Path(sys.executable).parent / "ccm")


def build(composer: Composer, *overrides: str) -> Controller:
    c = make_controller(to_plain(composer(list(overrides)).controller))
    c.reset(2, 0.001)
    return c


def sliding(mu: float, rng: np.random.Generator, t: float) -> Observation:
    """Sliding along +x on a floor with 10 N normal force and friction coefficient ``mu``."""
    f = np.array([-mu * 10.0, 10.0]) + rng.normal(0.0, 0.3, 2)
    v = np.array([0.1, 0.0]) + rng.normal(0.0, 0.002, 2)
    return Observation(t, np.array([0.1 * t, 0.027]), np.zeros(1), v, np.zeros(1), f, np.zeros(1))


def pressing() -> TargetSample:
    z = np.zeros(2)
    return TargetSample(0.0, z, z, z, np.zeros(1), force_dir=DOWN, force_mag=10.0)


def feed(c: Controller, seed: int, segments: Sequence[tuple[float, int]]) -> list[np.ndarray]:
    """Run ``c`` over sliding segments (mu, steps); return the commands."""
    rng = np.random.default_rng(seed)
    steps = [mu for mu, n in segments for _ in range(n)]
    return [
        c.step(sliding(mu, rng, k * 1e-3), pressing()).force.copy() for k, mu in enumerate(steps)
    ]


def round_trip(c: Controller, fresh: Controller) -> dict[str, Any]:
    """Save ``c``'s state through JSON text (as the runner does) and load it into ``fresh``."""
    state = c.state_dict()
    assert state is not None
    fresh.load_state_dict(json.loads(json.dumps(state, allow_nan=False)))
    assert fresh.state_dict() == state  # floats round-trip exactly through JSON
    return state


# ----------------------------------------------------------------------------- controllers


FIXED_GMM = ["controller=avic", "controller.forward_model.kind=fixed_gmm"]


@pytest.mark.parametrize(
    "overrides",
    [
        ["controller=avic"],
        [*FIXED_GMM, "controller.forward_model.fixed_gmm.fit_steps=1000"],  # saved after its fit
        [*FIXED_GMM, "controller.forward_model.fixed_gmm.fit_steps=2000"],  # fit after the load
    ],
    ids=["igmm", "fixed_gmm", "fixed_gmm_unfit"],
)
def test_avic_forward_model_round_trip_and_resume(composer: Composer, overrides: list[str]) -> None:
    c = build(composer, *overrides)
    feed(c, 0, [(0.3, 800), (0.6, 800)])
    c.end_trial()
    fresh = build(composer, *overrides)
    state = round_trip(c, fresh)
    assert c.model.ready == ("1000" in overrides[-1] or state["forward_model"]["kind"] == "igmm")
    for s in ([0.1, 0.0, 5.0, 0.0], [0.05, 0.0, 3.0, 0.0], [0.0, 0.0, 0.0, 0.0]):
        np.testing.assert_array_equal(
            fresh.model.predict(np.array(s)), c.model.predict(np.array(s))
        )
    c.reset(2, 0.001)
    fresh.reset(2, 0.001)
    later = [(0.45, 600), (0.3, 600)]  # the next trial runs the same either way
    np.testing.assert_array_equal(feed(fresh, 1, later), feed(c, 1, later))
    assert fresh.state_dict() == c.state_dict()
    assert fresh.model.ready


def test_avic_modes_round_trip(composer: Composer) -> None:
    c = build(composer, "controller=avic_modes")
    feed(c, 0, [(0.3, 800), (0.6, 800)])
    c.end_trial()
    assert c.modes.classifier.n_modes == 2
    fresh = build(composer, "controller=avic_modes")
    state = round_trip(c, fresh)
    assert [m["mode"] for m in state["modes"]] == [-1, 0, 1]
    assert fresh.modes.samples == c.modes.samples and fresh.modes.samples[0] > 0
    assert fresh.modes.classifier.mode_counts_ == c.modes.classifier.mode_counts_
    probe = np.linspace(0.0, 1.0, 101)[:, None]
    np.testing.assert_array_equal(
        fresh.modes.classifier.assign(probe), c.modes.classifier.assign(probe)
    )
    s = np.array([0.1, 0.0, 10.5, 0.0])
    for mode, model in c.modes.models.items():
        np.testing.assert_array_equal(fresh.modes.models[mode].predict(s), model.predict(s))
    # the next trial makes the same decisions and commands (the BIRCH trees are rebuilt from
    # their centres, so later centre updates may differ slightly: ModeClassifier.from_state_dict)
    c.reset(2, 0.001)
    fresh.reset(2, 0.001)
    later = [(0.6, 500), (0.3, 500)]
    np.testing.assert_array_equal(feed(fresh, 1, later), feed(c, 1, later))
    assert fresh.modes.samples == c.modes.samples and fresh.modes.classifier.n_modes == 2
    other = build(composer, "controller=avic_modes", "controller.modes.feature=torque_force_ratio")
    with pytest.raises(ConfigError, match="^init_from: .*1 features, .*torque_force_ratio has 2"):
        other.load_state_dict(state)


def test_anticipation_round_trip_keeps_the_contact_map(composer: Composer) -> None:
    from ccm.tasks.task import load_task

    pattern = load_task(composer(["task=slide_surfaces_2d"]).task, 0.001).pattern
    told = [
        {"name": "floor", "position": [0.0, 0.03], "kind": "collision"},
        {"name": "patch", "position": [0.35, 0.027], "kind": "impactless"},
    ]
    c = build(composer, "controller=avic_anticipation")
    assert c.state_dict()["contact_map"] is None  # no beliefs before the first trial
    c.prepare(pattern, told, np.random.default_rng(0))
    c.contact_map.observe([0.0, 0.027], "collision", v_used=0.05, f_measured=12.0)
    c.contact_map.observe([0.36, 0.027], "impactless")
    feed(c, 0, [(0.3, 600)])
    c.end_trial()
    fresh = build(composer, "controller=avic_anticipation")
    state = round_trip(c, fresh)
    assert (
        state["contact_map"]["trial"] == 1
        and fresh.base.modes.classifier.n_modes == c.base.modes.classifier.n_modes
    )
    (a, b) = (c.contact_map.contacts[0], fresh.contact_map.contacts[0])
    np.testing.assert_array_equal(b.belief.mean, a.belief.mean)
    np.testing.assert_array_equal(b.belief.cov, a.belief.cov)
    assert b.approach.next_velocity() == a.approach.next_velocity() != 0.05  # learned, not v_safe
    loaded = fresh.contact_map
    fresh.reset(2, 0.001)
    fresh.prepare(pattern, [], np.random.default_rng(5))  # prepare() keeps a loaded map
    assert fresh.contact_map is loaded
    assert fresh.contact_map.state_dict() == c.contact_map.state_dict()
    with pytest.raises(ConfigError, match=r"^init_from: .*contact_map"):  # not a ModalAVIC's
        build(composer, "controller=avic_modes").load_state_dict(state)


@pytest.mark.parametrize(
    "name", ["fixed_impedance", "mrac", "aic", "bac", "avic", "avic_modes", "avic_anticipation"]
)
def test_learned_state_is_json_or_none(composer: Composer, name: str) -> None:
    """Every controller: None (does not learn) or JSON-safe data that loads back."""
    c = build(composer, f"controller={name}")
    state = c.state_dict()
    if state is None:
        with pytest.raises(ConfigError, match="^init_from: .* has no learned state"):
            c.load_state_dict({})
        return
    text = json.dumps(state, allow_nan=False)
    fresh = build(composer, f"controller={name}")
    fresh.load_state_dict(json.loads(text))
    assert fresh.state_dict() == state
    with pytest.raises(ConfigError, match="^init_from: invalid learned state"):
        fresh.load_state_dict({**state, "bogus": 1})


def test_mismatched_forward_model_is_rejected(composer: Composer) -> None:
    state = build(composer, "controller=avic").state_dict()
    other = build(composer, "controller=avic", "controller.forward_model.kind=fixed_gmm")
    with pytest.raises(
        ConfigError, match="^init_from: .*kind 'igmm', this config's is 'fixed_gmm'"
    ):
        other.load_state_dict(state)


# ----------------------------------------------------------------------------- runner


def plan_with(composer: Composer, init_from: Path | str, *overrides: str) -> list:
    """The runner's plan (what ``ccm run`` prechecks) with ``init_from``."""
    ov = ["experiment=single", "task=smoke", *overrides, f"init_from={init_from}"]
    return plan_experiment(composer(ov), lambda extra: composer([*ov, *extra]), 1)


def saved_run(composer: Composer, tmp_path: Path, controller: str = "avic") -> Path:
    """A run directory holding ``state/<controller>.json`` of a fresh controller."""
    ov = ["experiment=single", "task=smoke", f"controller={controller}"]
    plan = plan_experiment(composer(ov), lambda extra: composer([*ov, *extra]), 1)
    save_learned_states(tmp_path / "prev", plan, {controller: 5})
    return tmp_path / "prev"


def one_line_error(composer: Composer, init_from: Path | str, *overrides: str) -> str:
    with pytest.raises(ConfigError) as info:
        plan_with(composer, init_from, *overrides)
    assert info.value.key == "init_from"
    assert "\n" not in str(info.value)
    return str(info.value)


def test_runner_loads_the_condition_state(composer: Composer, tmp_path: Path) -> None:
    prev = saved_run(composer, tmp_path)
    record = json.loads((prev / "state" / "avic.json").read_text())
    assert {k: record[k] for k in ("format", "version", "controller_type", "condition")} == {
        "format": STATE_FORMAT, "version": 1, "controller_type": "avic", "condition": "avic"
    }  # fmt: skip
    ((cond, _),) = plan_with(composer, prev, "controller=avic")
    assert cond.prior_trials == 5  # the next save counts on from here
    # conditions whose controller does not learn need no file
    ((cond, _),) = plan_with(composer, prev, "controller=fixed_impedance")
    assert cond.prior_trials == 0


def test_runner_errors_name_init_from(composer: Composer, tmp_path: Path) -> None:
    prev = saved_run(composer, tmp_path, "avic_modes")
    msg = one_line_error(composer, tmp_path / "nope", "controller=avic")
    assert "is not a directory" in msg
    msg = one_line_error(composer, prev, "controller=avic")
    assert "no learned state for condition 'avic'" in msg and "found: avic_modes" in msg
    path = prev / "state" / "avic_modes.json"
    good = path.read_text()
    record = json.loads(good)
    (prev / "state" / "avic.json").write_text(json.dumps(record))  # another type's state
    msg = one_line_error(composer, prev, "controller=avic")
    assert "controller type 'avic_modes', this condition's is 'avic'" in msg
    for text, expected in [
        (good[: len(good) // 2], "not a readable JSON file"),
        ("[1, 2]", "format None is not 'ccm-learned-state'"),
        (json.dumps({**record, "version": 7}), "version 7, this ccm reads 1"),
        (json.dumps({**record, "state": {"modes": []}}), "invalid learned state"),
        (json.dumps({**record, "trials": -1}), "needs 'trials'"),
        (json.dumps({**record, "state": {**record["state"], "x": [[1.0, 1e300]]}}),
         "state.x[0][1] = 1e+300: a learned state holds finite numbers within ±1e+12"),
    ]:  # fmt: skip
        path.write_text(text)
        msg = one_line_error(composer, prev, "controller=avic_modes")
        assert msg.startswith(f"init_from: {path}: ") and expected in msg, msg
    path.unlink()  # issue #39: a directory or a FIFO in a state file's place was "no state"
    path.mkdir()
    msg = one_line_error(composer, prev, "controller=avic_modes")
    assert msg == f"init_from: {path}: is a directory, not a file"
    path.rmdir()
    os.mkfifo(path)  # reading it would block: refused without opening it
    msg = one_line_error(composer, prev, "controller=avic_modes")
    assert msg == f"init_from: {path}: is not a regular file (a FIFO, socket or device)"


# ----------------------------------------------------------------------------- ccm run


def ccm(args: list[str], cwd: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [CCM, *args], cwd=cwd, capture_output=True, text=True, timeout=120, check=False
    )


RUN = [
    "run",
    "experiment=single",
    "controller=avic_modes",
    "task=slide_surfaces_2d",
    "experiment.fast=true",
    "experiment.fast_time_s=3.5",
    "experiment.figures=false",
]  # fmt: skip  (3.5 s: approach, press and a first stretch of sliding)


def test_ccm_run_continues_from_a_previous_run(tmp_path: Path) -> None:
    res = ccm([*RUN, "hydra.run.dir=first"], tmp_path)
    assert res.returncode == 0, res.stderr
    res = ccm([*RUN, "hydra.run.dir=second", "init_from=first"], tmp_path)
    assert res.returncode == 0, res.stderr
    one, two = (
        json.loads((tmp_path / run / "state" / "avic_modes.json").read_text())
        for run in ("first", "second")
    )
    assert one["format"] == two["format"] == STATE_FORMAT
    assert (one["trials"], two["trials"]) == (1, 2)
    n1, n2 = one["state"]["classifier"]["modes"], two["state"]["classifier"]["modes"]
    assert len(n1) >= 1 and len(n2) == len(n1)  # the same surface: a known mode, not a new one
    assert n2[0]["count"] > n1[0]["count"]
    for m1, m2 in zip(one["state"]["modes"], two["state"]["modes"], strict=True):
        seen = (m1["forward_model"]["igmm"]["n_seen"], m2["forward_model"]["igmm"]["n_seen"])
        assert 0 < seen[0] < seen[1] and m1["samples"] < m2["samples"]  # not reset
    summary = json.loads((tmp_path / "second" / "summary.json").read_text())
    assert summary["status"] == "ok" and summary["init_from"] == "first"
    assert [t["trial"] for t in summary["trials"]] == [1]  # numbered within the run
    assert "init_from" not in json.loads((tmp_path / "first" / "summary.json").read_text())


def test_ccm_run_bad_init_from_is_one_line(tmp_path: Path) -> None:
    bad = tmp_path / "bad" / "state"
    bad.mkdir(parents=True)
    (bad / "avic.json").write_text('{"format": "ccm-learned-state", "vers')
    for value, expected in [("nope", "init_from: 'nope' is not a directory"), ("bad", "JSON")]:
        res = ccm(["run", "experiment=single", "controller=avic", f"init_from={value}"], tmp_path)
        assert res.returncode == 2
        lines = res.stderr.strip().splitlines()
        assert len(lines) == 1 and expected in lines[0] and "init_from" in lines[0], res.stderr
        assert "Traceback" not in res.stderr
    assert not list(tmp_path.rglob("summary.json"))
