"""Seed B Table 2 by replay (ccm/analyses/mpc_table2.py, mpc_replay.py; issue #37 item 5)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from ccm.analyses import mpc_replay
from ccm.analyses.mpc_replay import Variant, block_bootstrap, rotation
from ccm.analyses.mpc_table2 import merged, mpc_ticks, parse_settings
from ccm.core.errors import ConfigError

ROWS = ("baseline", "two_modes", "joint_torque", "model_variance", "disturbance", "well_damped",
        "chance")  # fmt: skip


def test_rotation_interleaves_every_row_in_turn() -> None:
    assert rotation(3, 0) == [0, 1, 2]
    assert rotation(3, 1) == [1, 2, 0]
    assert rotation(3, 5) == [2, 0, 1]
    assert rotation(0, 4) == []
    orders = [rotation(7, k) for k in range(7)]
    for order in orders:
        assert sorted(order) == list(range(7))  # every row once per tick
    # over 7 ticks each row is solved first once and at every position once
    for pos in range(7):
        assert sorted(o[pos] for o in orders) == list(range(7))


def test_mpc_ticks_follow_the_controllers_rule() -> None:
    t = np.arange(100) * 1e-3  # 1 kHz steps; a solve every 40 ms from t = 0
    assert mpc_ticks(t, 0.04).tolist() == [0, 40, 80]
    assert mpc_ticks(t, 0.025).tolist() == [0, 25, 50, 75]


def test_block_bootstrap_on_known_input() -> None:
    rng = np.random.default_rng(0)
    b = np.linspace(1e-3, 3e-3, 40)
    # row a always takes twice as long as b at the same tick: a paired ratio is 0.5 in every
    # resample, so the interval has no width
    val, lo, hi = block_bootstrap([2 * b, b], mpc_replay.rate_ratio, rng, 200, 5)
    assert val == pytest.approx(0.5) and lo == pytest.approx(0.5) and hi == pytest.approx(0.5)
    # one block spanning all ticks: every resample is the data itself
    val, lo, hi = block_bootstrap([b], mpc_replay.rate_of, rng, 50, 40)
    assert lo == hi == val == pytest.approx(1.0 / np.median(b))
    # the mean of 1..10 resampled tick by tick: standard error 2.87 / sqrt(10) = 0.91, so the
    # 95 % percentile interval is about 5.5 -+ 1.8
    x = np.arange(1.0, 11.0)
    val, lo, hi = block_bootstrap([x], np.mean, np.random.default_rng(1), 4000, 1)
    assert val == 5.5
    assert 3.4 < lo < 4.1 and 6.9 < hi < 7.6
    # the same seed gives the same interval
    again = block_bootstrap([x], np.mean, np.random.default_rng(1), 4000, 1)
    assert again == (val, lo, hi)
    with pytest.raises(ValueError):
        block_bootstrap([x, x[:5]], np.mean, rng, 10, 1)


def test_config_composes_with_every_row(composer) -> None:
    cfg = composer(["experiment=mpc_table2"])
    assert cfg.experiment.kind == "mpc_table2"
    s = parse_settings(cfg)
    assert tuple(s["rows"]) == ROWS
    rows, rail = s["rows"], cfg.controller.mpc
    assert rows["baseline"]["mpc"]["weights"]["pos_var"] == 0.0
    assert rows["baseline"]["mpc"]["horizon"] == rail.horizon and rail.horizon == 10
    assert rows["model_variance"]["mpc"]["weights"]["pos_var"] == rail.weights.pos_var > 0
    assert rows["chance"]["mpc"]["chance"]["quantile"] == "paper_erfinv"
    assert rows["chance"]["mpc"]["weights"]["pos_var"] == 0.0  # each feature alone
    assert rows["two_modes"]["demo_modes"] == [0, 0, 1]
    assert s["ratios"] == [("well_damped", "chance")]
    assert merged({"a": {"b": 1, "c": 2}, "d": 3}, {"a": {"b": 5}, "d": None}) == {
        "a": {"b": 5, "c": 2},
        "d": None,
    }


@pytest.mark.parametrize(
    ("override", "key"),
    [
        ("table2.rows.chance.mpc.chance.epsilon=1.5", "table2.rows.chance.mpc.chance.epsilon"),
        ("+table2.rows.chance.speed=1", "table2.rows.chance.speed"),
        ("table2.rows.two_modes.demo_modes=[0,1]", "table2.rows.two_modes.demo_modes"),
        ("table2.rows.two_modes.belief=oracle", "table2.rows.two_modes.belief"),
        ("table2.bootstrap.block_ticks=0", "table2.bootstrap.block_ticks"),
        ("table2.ratios=[[well_damped,nope]]", "table2.ratios[0]"),
    ],
)
def test_bad_feature_setting_is_one_line_naming_the_key(composer, override: str, key: str) -> None:
    cfg = composer(["experiment=mpc_table2", override])
    with pytest.raises(ConfigError) as err:
        parse_settings(cfg)
    assert err.value.key == key
    assert "\n" not in str(err.value)


def test_tiny_replay_returns_every_row() -> None:
    """A few ticks on the bench's synthetic wall GP (3-D, horizon 3): every row solves at
    every tick, and the timing has a rate and an interval for every row and ratio."""
    from ccm.bench.mpc import build_problem, synthetic_gp

    gp, gp_far = synthetic_gp(0, n_points=12), synthetic_gp(1, wall=0.01, n_points=12)
    setups = {
        "baseline": ([gp], {"well_damped": False}),
        "two_modes": ([gp, gp_far], {"well_damped": False}),
        "well_damped": ([gp], {}),
        "chance": ([gp], {"well_damped": False,
                          "chance": {"f_max": 20.0, "epsilon": 0.5, "quantile": "paper_erfinv"}}),
    }  # fmt: skip
    ticks = 4
    states = np.zeros((ticks, 6))
    states[:, 0] = np.linspace(-0.02, -0.01, ticks)
    variants = []
    for name, (gps, kw) in setups.items():
        belief = np.full((ticks, len(gps)), 1.0 / len(gps))
        start = (np.full(3, 5.0), np.full(3, 500.0), np.zeros(3))
        variants.append(Variant(name, build_problem(gps, 3, **kw), belief, *start))
    mpc_replay.replay(variants, states)
    for v in variants:
        assert len(v.cpu_s) == len(v.wall_s) == len(v.iterations) == len(v.applied) == ticks
        assert all(s > 0 for s in v.wall_s) and all(i >= 0 for i in v.iterations)
        facts = mpc_replay.row_summary(v, 3)
        assert facts["ticks"] == ticks and facts["n_modes"] == v.beliefs.shape[1]
        # the applied impedance stays within the bench problem's bounds (5-60 kg, 500-6000 N s/m)
        assert 5.0 - 1e-6 <= facts["mass_x_min_kg"] <= facts["mass_x_max_kg"] <= 60.0 + 1e-6
        assert 500.0 - 1e-6 <= facts["damping_z_min_Nspm"] <= 6000.0 + 1e-6
    pairs = [(n, "baseline") for n in setups if n != "baseline"] + [("well_damped", "chance")]
    boot = {"resamples": 20, "block_ticks": 2, "level": 0.95}
    info = mpc_replay.timing_info(variants, pairs, {"baseline": 26.2, "chance": 13.0}, boot, 0)
    assert set(info["mpc_rate_hz"]) == set(setups)
    assert set(info["table2"]["rows"]) == set(setups)
    assert set(info["table2"]["ratios"]) == {f"{a}/{b}" for a, b in pairs}
    assert info["table2"]["ratios"]["chance/baseline"]["seed_b"] == pytest.approx(13.0 / 26.2)
    for r in info["table2"]["ratios"].values():
        assert r["cpu"][1] <= r["cpu"][2]


@pytest.mark.slow
def test_same_config_and_seed_give_a_byte_identical_summary(composer, tmp_path: Path) -> None:
    """Two short runs (0.3 s trials): the replayed row with the recording controller's own
    settings reproduces its M, D, f^r exactly, and summary.json is byte for byte the same."""
    from ccm.analyses.dispatch import run

    overrides = ["experiment=mpc_table2", "experiment.fast=true", "experiment.fast_time_s=0.3",
                 "experiment.figures=false", "table2.bootstrap.resamples=50"]  # fmt: skip
    cfg = composer(overrides)
    texts = []
    for i in range(2):
        out = tmp_path / f"run{i}"
        summary = run(cfg, lambda extra: composer([*overrides, *extra]), out)
        assert set(summary["conditions"]) == set(ROWS)
        texts.append((out / "summary.json").read_bytes())
    rec = summary["recording"]
    assert rec["ticks"] == rec["controller_solves"] > 0
    diff = rec["model_variance_vs_recording_max_abs_diff"]
    assert diff == {"mass_kg": 0.0, "damping_Nspm": 0.0, "f_ref_N": 0.0}
    assert texts[0] == texts[1]
