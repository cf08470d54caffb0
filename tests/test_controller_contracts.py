"""Contracts of the controller interface (``ccm.control.base``) and the fixed impedance
controller's logged gains (issue #39 item 1).

A learned state that does not fit is refused with one ``init_from`` line saying what is
missing and what is unknown; the gains a controller logs are the ones its law uses (Eq. 1
with the critical rule, for the end-effector mass or for the arm's Λ(q) each step).
"""

from __future__ import annotations

import dataclasses
from functools import partial

import numpy as np
import pytest

from ccm.control.base import check_state_keys, state_error
from ccm.control.impedance import FixedImpedance
from ccm.core.errors import ConfigError
from tests.refusals import refusal
from tests.test_impedance import make, obs, target

_line = partial(refusal, ConfigError)


@pytest.mark.parametrize(
    ("state", "line"),
    [
        ([1], "expected a mapping, got list"),
        ({"a": 1, "z": 2}, "expected keys a, b; missing ['b'], unknown ['z']"),
        ({"a": 1}, "expected keys a, b; missing ['b'], unknown none"),
        ({"a": 1, "b": 2, 3: 4}, "expected keys a, b; missing none, unknown ['3']"),
    ],
)
def test_a_state_with_other_keys_is_refused_in_one_line(state: object, line: str) -> None:
    assert _line(check_state_keys, state, ["a", "b"]) == f"init_from: invalid learned state: {line}"


def test_a_state_with_exactly_the_keys_passes() -> None:
    check_state_keys({"b": 1, "a": 2}, ["a", "b"])


def test_parse_errors_become_one_init_from_line() -> None:
    prefix = "init_from: invalid learned state: "
    assert str(state_error(KeyError("gmm"))) == prefix + "missing entry 'gmm'"
    assert str(state_error(ValueError("bad\n   shape  (3,)"))) == prefix + "bad shape (3,)"
    assert str(state_error(TypeError())) == prefix + "TypeError"
    own = ConfigError("init_from", "kept as it is")
    assert state_error(own) is own
    assert str(state_error(ConfigError("fm.kind", "other"))) == prefix + "fm.kind: other"


def test_a_controller_without_learned_state_says_so() -> None:
    c = make()
    assert c.state_dict() is None
    assert _line(c.load_state_dict, {}) == "init_from: FixedImpedance has no learned state to load"


def test_logged_gains_are_the_laws_gains() -> None:
    """Critical rule, m = 1 kg: K_d = 2 √(K_p m) per axis, logged as the axis mean."""
    c = make(stiffness=[100.0, 400.0], damping_rule="critical", mass_kg=1.0)
    assert c.signals()["stiffness_Npm"] == 250.0
    assert c.signals()["damping_Nspm"] == pytest.approx((20.0 + 40.0) / 2)
    u = c.step(obs(vel=(0.1, 0.1)), target())
    np.testing.assert_allclose(u.force, [-2.0, -4.0])  # K_d · (0 − v)


def test_with_the_arms_inertia_the_damping_follows_lambda_each_step() -> None:
    """inertia: model and Λ = diag(4, 1) kg: K_d = 2 √(Λ K_p) = diag(40, 40) N s/m for
    K_p = (100, 400), logged as the diagonal's mean; the next Λ changes it."""
    c = make(stiffness=[100.0, 400.0], damping_rule="critical", mass_kg=1.0, inertia="model")
    o = dataclasses.replace(obs(vel=(0.1, 0.1)), inertia=np.diag([4.0, 1.0]))
    u = c.step(o, target())
    assert c.signals()["damping_Nspm"] == pytest.approx(40.0)
    np.testing.assert_allclose(u.force, [-4.0, -4.0], rtol=1e-9)
    c.step(dataclasses.replace(o, inertia=np.diag([1.0, 1.0])), target())
    assert c.signals()["damping_Nspm"] == pytest.approx(30.0)


def test_stiffness_must_fit_the_task() -> None:
    c = FixedImpedance(stiffness=[1.0, 2.0, 3.0])
    assert _line(c.reset, 2, 0.001) == "controller.stiffness: needs 1 or 2 values, got 3"


def test_scalar_gains_take_the_same_rules_as_arrays() -> None:
    """The per-step float path of the damping rules (planar tasks): critical 2 ζ √(K_p m) for
    m = 4 kg, and the paper's √K_p / 4 (stated after Eq. 4c, seed A)."""
    from ccm.control.loop import HybridLoop

    crit = HybridLoop(damping_rule="critical", damping_ratio=1.0, mass_kg=4.0)
    assert crit.damping_for(100.0) == pytest.approx(40.0)
    assert crit.damping_for(np.array([100.0])) == pytest.approx([40.0])
    paper = HybridLoop(damping_rule="paper", mass_kg=4.0)
    assert paper.damping_for(400.0) == pytest.approx(5.0)
    assert _line(HybridLoop, damping_ratio=-1.0).startswith("controller.loop.damping_ratio: ")


def test_the_force_integral_winds_up_to_its_limit_over_the_gain() -> None:
    """u_fc = d (F_d + k_fp e + k_fi ∫e) − d k_fd (d·v) with the integral clipped to
    ±limit / k_fi: k_fi = 0.5 1/s and a limit of 1 N keep ∫e within ±2 N s, so a 10 N error
    held for 1 s gives k_fi ∫e = 1 N, not 5 N."""
    c = make(force_kp=0.0, force_ki=0.5, force_integral_limit_N=1.0, force_damping=0.0)
    assert c.signals()["force_control"] == 0.0
    press = target(fdir=(0.0, -1.0), fmag=10.0)
    for _ in range(1000):
        u = c.step(obs(), press)
    np.testing.assert_allclose(u.force, [0.0, -11.0])
    assert c.signals()["force_control"] == 1.0 and c.signals()["force_error_N"] == 10.0
