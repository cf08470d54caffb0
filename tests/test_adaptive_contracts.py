"""The AVIC stack's contracts beside its equations (issue #39): Algorithm 1's learned state
refused piece by piece without a change, the logistic gate's calibration carried through
JSON, the settings' keys under a caller's prefix, the signals the metrics read, and the
re-planner's passes in plan order and within the plan's duration."""

from __future__ import annotations

import json
from collections.abc import Callable, Sequence
from functools import partial
from typing import Any

import numpy as np
import pytest
from omegaconf import DictConfig

from ccm.control.adaptive.avic import AVIC
from ccm.control.adaptive.contact_regions import Pass, speed_pieces
from ccm.control.adaptive.logistic import LogisticGate
from ccm.control.adaptive.replan import plan_passes
from ccm.core.errors import ConfigError
from ccm.learn.contact.belief import ContactBelief
from tests.refusals import refusal
from tests.test_controller_state import build, feed

Composer = Callable[[Sequence[str]], DictConfig]


_config_refusal = partial(refusal, ConfigError)


# ---------------------------------------------------------------- Algorithm 1's learned state


@pytest.fixture
def learned_modes(composer: Composer) -> tuple[AVIC, dict[str, Any]]:
    """An AVIC with Algorithm 1 after one trial over two friction patches (two modes)."""
    c = build(composer, "controller=avic_modes")
    feed(c, 0, [(0.3, 800), (0.6, 800)])
    c.end_trial()
    assert c.modes.classifier.n_modes == 2
    return c, json.loads(json.dumps(c.state_dict()))


def _with_modes(state: dict[str, Any], modes: list[dict[str, Any]]) -> dict[str, Any]:
    return {**state, "modes": modes}


def _bad_mode_states(state: dict[str, Any]) -> list[tuple[dict[str, Any], str]]:
    """(a malformed state, the end of the one line that refuses it)."""
    modes = state["modes"]
    first = modes[0]
    return [
        ({k: v for k, v in state.items() if k != "classifier"},
         "expected keys calibration, classifier, modes; missing ['classifier'], unknown none"),
        (_with_modes(state, [{k: v for k, v in first.items() if k != "samples"}, *modes[1:]]),
         "expected keys mode, samples, forward_model; missing ['samples'], unknown none"),
        (_with_modes(state, [{**first, "mode": True}, *modes[1:]]),
         "mode ids must be distinct integers, got True"),
        (_with_modes(state, [{**first, "mode": -1.0}, *modes[1:]]),
         "mode ids must be distinct integers, got -1.0"),
        (_with_modes(state, [*modes, modes[1]]), "mode ids must be distinct integers, got 0"),
        (_with_modes(state, modes[:2]),
         "modes [-1, 0] do not match the classifier's [-1, 0, 1] (-1 = free space)"),
        (_with_modes(state, [modes[0], {**modes[1], "samples": -3}, modes[2]]),
         "modes[0].samples"),
    ]  # fmt: skip


def test_a_malformed_mode_state_is_refused_and_changes_nothing(
    composer: Composer, learned_modes: tuple[AVIC, dict[str, Any]]
) -> None:
    c, state = learned_modes
    fresh = build(composer, "controller=avic_modes")
    before = fresh.state_dict()
    for bad, tail in _bad_mode_states(state):
        line = _config_refusal(fresh.load_state_dict, bad)
        assert line.startswith("init_from: ") and tail in line and "\n" not in line, line
        assert fresh.state_dict() == before  # nothing taken from a refused state
    fresh.load_state_dict(state)
    assert fresh.state_dict() == state
    assert fresh.modes.samples == c.modes.samples and fresh.signal("mode") == -1.0


def test_modal_signals_count_the_modes_and_the_components(
    learned_modes: tuple[AVIC, dict[str, Any]],
) -> None:
    """``n_modes`` (the classifier's) and ``n_components`` (the current model's) are what
    the mode metrics read; both are counts the learned state fixes."""
    c, _ = learned_modes
    feed(c, 1, [(0.6, 50)])
    sig = c.signals()
    assert sig["n_modes"] == 2.0
    assert sig["n_components"] == float(c.model.n_components) > 0


# ---------------------------------------------------------------- the logistic gate (Eq. 4c)


def test_the_gates_calibration_round_trips_mid_way() -> None:
    """Calibrating over two trials: after one, the kept errors travel through JSON, and both
    gates then set the same ε₀ (the errors' quantile) and r = shape / ε₀ from the second."""
    cal = {"trials": 2, "quantile": 0.5, "shape": 4.0}
    gate = LogisticGate(None, None, calibrate=cal)
    for e in (1.0, 3.0, 2.0):
        gate.keep(e)
    gate.end_trial(None, 1.0)
    assert gate.calibrating
    state = json.loads(json.dumps(gate.state_dict()))
    assert state == {"trials": 1, "eps0": None, "r": None, "errors": [1.0, 3.0, 2.0]}
    other = LogisticGate(None, None, calibrate=cal)
    other.load_state_dict(state)
    assert other.state_dict() == state
    for g in (gate, other):
        g.keep(5.0)
        g.end_trial(None, 1.0)
    assert gate.params() == other.params() == {"eps0": 2.5, "r": 4.0 / 2.5}
    plain = LogisticGate(2.0, 1.0)
    with pytest.raises(ValueError, match="the saved controller was calibrated; this config"):
        plain.load_state_dict(state)


def test_the_gates_fixed_parameters_and_calibration_exclude_each_other() -> None:
    cal = {"trials": 1}
    assert _config_refusal(LogisticGate, 2.0, None, calibrate=cal, key="arm") == (
        "arm.r: is set by arm.calibrate: give null, got 2.0"
    )
    assert _config_refusal(LogisticGate, None, 0.5, calibrate=cal, key="arm") == (
        "arm.eps0: is set by arm.calibrate: give null, got 0.5"
    )


# ---------------------------------------------------------------- settings under a prefix


@pytest.mark.parametrize(
    ("kwargs", "key"),
    [
        ({"forward_model": {"kind": "magic"}}, "arm.forward_model.kind"),
        ({"modes": {"bogus": 1}}, "arm.modes.bogus"),
    ],
)
def test_the_parts_name_their_keys_under_the_callers_prefix(kwargs: dict, key: str) -> None:
    with pytest.raises(ConfigError) as err:
        AVIC(**kwargs, key="arm")
    assert err.value.key == key


def test_a_modes_block_adds_algorithm_1_and_unknown_keys_are_refused() -> None:
    """``avic_modes`` is a preset (a config with a ``modes`` block), not a class alias."""
    assert AVIC.from_config({"type": "avic", "modes": {}}, "arm").modes is not None
    assert AVIC.from_config({"type": "avic"}, "arm").modes is None
    line = _config_refusal(AVIC.from_config, {"type": "avic", "colour": 1}, "arm")
    assert line.startswith("arm.colour: ")


# ---------------------------------------------------------------- the plan's passes (§3.5)


def test_speed_limits_begin_one_sample_before_the_plan_passes_v_a() -> None:
    """Eq. 11's piece runs from the sample before the speed first exceeds v_a to the sample
    after it last does; a pass that starts fast starts its piece at its first sample."""
    ts = np.arange(10) * 0.1
    speed = np.array([0.0, 0.02, 0.06, 0.1, 0.1, 0.1, 0.06, 0.02, 0.0, 0.0])
    seg = np.zeros(10, dtype=int)
    assert speed_pieces(ts, speed, seg, [Pass(0, 9)], 0.05) == [(ts[1], ts[7], 0.5)]
    assert speed_pieces(ts, speed, seg, [Pass(3, 9)], 0.05) == [(ts[3], ts[7], 0.5)]


class _Contact:
    """What :func:`plan_passes` reads of a map contact."""

    def __init__(self, position: list[float], std: float, kind: str = "impactless") -> None:
        cov, noise = np.eye(2) * std**2, np.eye(2) * 1e-8
        self.belief = ContactBelief(position, cov, np.zeros((2, 2)), noise)
        self.kind, self.source, self.lead, self.approach = kind, "config", None, None


def test_crossings_are_sorted_by_where_they_begin_and_end_within_the_plan(
    composer: Composer,
) -> None:
    """A wide region that begins before a narrow one inside it, and ends after it: the
    crossings come in the order the plan enters them. A region around the plan's end is left
    at the plan's last sample, not later."""
    from ccm.tasks.task import load_task

    pattern = load_task(composer(["task=slide_surfaces_2d"]).task, 0.001).pattern
    end = pattern.sample(pattern.duration).position
    contacts = [_Contact([0.0, 0.09], 0.002), _Contact([0.0, 0.09], 0.02),
                _Contact(list(end), 0.005)]  # fmt: skip
    _, crossings = plan_passes(contacts, pattern, 0.01, 2.0, 0.0)
    order = [i for i, *_ in crossings]
    assert order.index(1) < order.index(0)  # the wide one is entered first ...
    (wide,) = [c for c in crossings if c[0] == 1]
    (narrow,) = [c for c in crossings if c[0] == 0]
    assert wide[1] < narrow[1] and narrow[2] < wide[2]  # ... and left last
    (last,) = [c for c in crossings if c[0] == 2]
    assert last[2] == pytest.approx(pattern.duration, abs=0.01)
