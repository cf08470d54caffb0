"""Seed B Table 3 / Fig. 9 (issue #18 item 2): the metrics and verdict rules behind the
polishing claims - damping far from the human, mass across the path, "unchanged" as
``ratio_within`` and a cost that must act (``changed_from``)."""

from __future__ import annotations

import numpy as np
import pytest

from ccm.core.errors import ConfigError
from ccm.metrics.mpc import gp_mpc_metrics
from ccm.reporting.claims import evaluate, parse_claim

SHOULDER = [0.0, -0.3, 0.3]  # m; the tool at (x, 0, 0) is sqrt(x^2 + 0.18) m away
FAR = {"human_shoulder": SHOULDER, "far_from_human_m": 0.5}  # far for x >= sqrt(0.07) = 0.2646


def _log(near_d: float, far_d: float) -> dict:
    t = np.arange(0.0, 1.0, 1e-3)
    x = 0.4 * t  # 0 -> 0.4 m along the path, away from the shoulder
    far = np.sqrt(x**2 + 0.18) >= 0.5
    dx = np.where(far, far_d, near_d)
    z = 0.0 * t
    return {
        "t": t, "pos_x": x, "pos_y": z, "vel_x": z + 0.4, "vel_y": z, "n_contacts": z,
        "contact_force_x": z, "contact_force_y": z, "damping_x_Nspm": dx,
        "damping_y_Nspm": dx + 200.0, "mass_x_kg": z + 5.0, "mass_y_kg": z + 12.0,
    }  # fmt: skip


def test_far_damping_is_the_mean_over_the_far_samples_and_both_axes() -> None:
    out = gp_mpc_metrics(_log(near_d=2000.0, far_d=600.0), 2, FAR)
    frac = np.mean(np.sqrt((0.4 * np.arange(0.0, 1.0, 1e-3)) ** 2 + 0.18) >= 0.5)
    assert out["far_from_human_frac"] == pytest.approx(frac) and 0.3 < frac < 0.4
    assert out["mean_damping_far_Nspm"] == pytest.approx(700.0)  # (600 + 800) / 2
    # the other answer: damping that rises away from the human reads high, not low
    assert gp_mpc_metrics(_log(600.0, 2000.0), 2, FAR)["mean_damping_far_Nspm"] == pytest.approx(
        2100.0
    )
    assert out["mean_mass_x_kg"] == 5.0 and out["mean_mass_y_kg"] == 12.0


def test_no_far_sample_gives_none_and_no_shoulder_no_metric() -> None:
    out = gp_mpc_metrics(_log(2000.0, 600.0), 2, {**FAR, "far_from_human_m": 0.9})
    assert out["mean_damping_far_Nspm"] is None and out["far_from_human_frac"] == 0.0
    assert "mean_damping_far_Nspm" not in gp_mpc_metrics(_log(2000.0, 600.0), 2, {})
    with pytest.raises(ConfigError, match="metrics.human_shoulder"):
        gp_mpc_metrics(_log(1.0, 1.0), 2, {**FAR, "human_shoulder": [0.0, 0.1]})
    with pytest.raises(ConfigError, match="metrics.far_from_human_m"):
        gp_mpc_metrics(_log(1.0, 1.0), 2, {**FAR, "far_from_human_m": None})


def _summary(a: float, b: float, act_a: float = 1000.0, act_b: float = 500.0) -> dict:
    return {
        "experiment": "e", "status": "ok", "trials": [],
        "conditions": {"x": {"m": a, "d": act_a}, "y": {"m": b, "d": act_b}},
    }  # fmt: skip


SAME = {
    "id": "c", "paper": "seed_b", "source": "Table 3", "statement": "x about equal to y",
    "paper_value": "4.2e-4 vs 4.2e-4", "experiment": "e", "compare": "ratio_within",
    "a": {"condition": "x", "metric": "m"}, "b": {"condition": "y", "metric": "m"},
    "value": 1.0, "tolerance": 0.05,
    "requires": [{"condition": "x", "metric": "d", "at_least": 0.05,
                  "changed_from": {"condition": "y", "metric": "d"}}],
}  # fmt: skip


@pytest.mark.parametrize(
    ("pairs", "verdict"),
    [
        ([(4.2, 4.2), (4.15, 4.2), (4.25, 4.2), (4.2, 4.2), (4.18, 4.2)], "reproduced"),
        ([(3.3, 4.2), (3.2, 4.1), (3.4, 4.3)], "not reproduced"),  # main's 22 % drop
        ([(5.0, 4.2), (5.1, 4.2), (4.9, 4.2)], "not reproduced"),  # a rise fails as well
    ],
)
def test_ratio_within_is_two_sided(pairs: list, verdict: str) -> None:
    v = evaluate(parse_claim(SAME, "claims[0]"), [_summary(a, b) for a, b in pairs])
    assert v.verdict == verdict
    assert "x.m / y.m" in v.ours


def test_unchanged_needs_the_cost_to_act() -> None:
    """An inert cost (damping within 5 % of the reference) leaves equal velocities by
    construction: not reproduced, whatever the velocities; a fall counts like a rise."""
    c = parse_claim(SAME, "claims[0]")
    inert = [_summary(4.2, 4.2, act_a=510.0, act_b=500.0) for _ in range(3)]
    v = evaluate(c, inert)
    assert v.verdict == "not reproduced" and "met in 0 of 3" in v.ours
    lower = [_summary(4.2, 4.2, act_a=400.0, act_b=500.0) for _ in range(3)]
    assert evaluate(c, lower).verdict == "reproduced"


@pytest.mark.parametrize(
    ("patch", "key"),
    [
        ({"tolerance": None}, "claims[0].tolerance"),
        ({"tolerance": -0.1}, "claims[0].tolerance"),
        ({"requires": [{"condition": "x", "metric": "d", "at_least": 0.05,
                        "changed_from": {"condition": "y"}}]},
         "claims[0].requires[0].changed_from.metric"),
    ],
)  # fmt: skip
def test_bad_ratio_within_names_the_key(patch: dict, key: str) -> None:
    with pytest.raises(ConfigError) as err:
        parse_claim({**SAME, **patch}, "claims[0]")
    assert key in str(err.value)
