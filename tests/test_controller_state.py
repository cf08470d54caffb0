"""Controllers' learned state (issue #5, point 4): each learning controller's ``state_dict``
is JSON that a fresh controller of the same config loads back into the same behaviour, and
a state that does not fit is refused with one line naming ``init_from``. The runner's and
the CLI's side (``state/<condition>.json``, ``init_from=<run dir>``) is in
``tests/test_learned_state.py``."""

from __future__ import annotations

import json
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
import pytest
from omegaconf import DictConfig

from ccm.control.base import Controller
from ccm.control.registry import make_controller
from ccm.core.errors import ConfigError, to_plain
from ccm.core.types import Observation, TargetSample

Composer = Callable[[Sequence[str]], DictConfig]
DOWN = np.array([0.0, -1.0])


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
