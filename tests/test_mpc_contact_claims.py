"""mpc_contact's seed B §6.1 statements and Table 2 as claims (issue #18 items 1, 3, 4): the
approach metrics (pull-back, pause, damping at contact), ``ratio_within``, the wall-clock rates
joined from run_info.json, and the two latency settings as two experiments."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from ccm.core.errors import ConfigError
from ccm.metrics.mpc import gp_mpc_metrics
from ccm.reporting.claims import evaluate, load_claims, parse_claim
from ccm.reporting.paper import PAPER_EXPERIMENTS
from ccm.reporting.report_runs import collect, with_run_info

CLAIMS = Path(__file__).resolve().parents[1] / "experiments" / "claims.yaml"
DT = 0.001


def _log(pos: np.ndarray, contact_from: float | None, damping: float = 500.0) -> dict:
    """A 2-D trial log moving along x with the given positions (1 kHz), touching from
    ``contact_from`` s on (never if None); velocity by differencing, damping constant."""
    t = np.arange(len(pos)) * DT
    vel = np.gradient(pos, DT)
    touch = np.zeros_like(t) if contact_from is None else (t >= contact_from) * 1.0
    zero = 0.0 * t
    return {
        "t": t, "pos_x": pos, "pos_y": zero, "vel_x": vel, "vel_y": zero,
        "contact_force_x": -15.0 * touch, "contact_force_y": zero, "n_contacts": touch,
        "damping_x_Nspm": zero + damping, "damping_y_Nspm": zero + 100.0,
    }  # fmt: skip


PARAMS = {"approach_dir": [1.0, 0.0], "pause_speed_frac": 0.5}


def _ramp(*segments: tuple[float, float]) -> np.ndarray:
    """Positions from (duration s, speed m/s) segments, starting at 0."""
    v = np.concatenate([np.full(int(round(d / DT)), s) for d, s in segments])
    return np.concatenate([[0.0], np.cumsum(v) * DT])


def test_a_steady_approach_neither_pulls_back_nor_pauses() -> None:
    out = gp_mpc_metrics(_log(_ramp((2.0, 0.03)), contact_from=1.5), 2, PARAMS)
    assert out["approach_pullback_m"] == pytest.approx(0.0, abs=1e-12)
    assert out["pre_contact_dwell_s"] == pytest.approx(0.0, abs=2 * DT)
    assert out["damping_at_contact_Nspm"] == pytest.approx(500.0)  # along x, not y's 100


def test_a_trial_without_contact_says_so_and_its_peak_is_no_lower_peak() -> None:
    """Issue #37: B-6.1-chance-peak requires contact in every trial; a robot that stopped short
    reads 0 N of peak force, which must not count as a lower peak."""
    touched = gp_mpc_metrics(_log(_ramp((2.0, 0.03)), contact_from=1.5), 2, PARAMS)
    short = gp_mpc_metrics(_log(_ramp((2.0, 0.01)), contact_from=None), 2, PARAMS)
    assert (touched["contact_made"], short["contact_made"]) == (1.0, 0.0)
    assert short["peak_force_N"] == 0.0 < touched["peak_force_N"]
    claims = {c.id: c for c in load_claims(CLAIMS)}
    peak = claims["B-6.1-chance-peak-no-latency"]

    def run(chance: dict) -> dict:
        none = {"peak_force_N": touched["peak_force_N"], "contact_made": 1.0}
        return {"experiment": "mpc_contact", "status": "ok",
                "conditions": {"variance_chance": chance, "variance_none": none}}  # fmt: skip

    stopped = {"peak_force_N": 0.0, "contact_made": 0.0}
    assert evaluate(peak, [run(stopped)] * 3).verdict == "not reproduced"
    lower = {"peak_force_N": 0.5 * touched["peak_force_N"], "contact_made": 1.0}
    assert evaluate(peak, [run(lower)] * 3).verdict == "reproduced"


def test_sigma_f_metrics_read_the_solves_and_skip_the_time_before_them() -> None:
    log = _log(_ramp((2.0, 0.03)), contact_from=1.5)
    sig = np.full(len(log["t"]), np.nan)
    sig[40:] = np.linspace(0.5, 2.0, len(sig) - 40)  # NaN until the first solve
    out = gp_mpc_metrics({**log, "sigma_f_x_N2": sig}, 2, PARAMS)
    assert out["max_sigma_f_x_N2"] == pytest.approx(2.0)
    assert out["mean_sigma_f_x_N2"] == pytest.approx(1.25, rel=1e-3)
    assert "mean_sigma_f_y_N2" not in out  # no signal, no metric


def test_a_retreat_before_contact_is_a_pull_back() -> None:
    # 3 cm/s for 1 s (30 mm), back 2 mm at 1 cm/s, then on into contact at 1.5 s
    pos = _ramp((1.0, 0.03), (0.2, -0.01), (1.0, 0.03))
    out = gp_mpc_metrics(_log(pos, contact_from=1.5), 2, PARAMS)
    assert out["approach_pullback_m"] == pytest.approx(0.002, rel=1e-6)
    # the same retreat *after* the first contact is not part of the approach
    late = gp_mpc_metrics(_log(pos, contact_from=0.9), 2, PARAMS)
    assert late["approach_pullback_m"] == pytest.approx(0.0, abs=1e-12)
    # without any contact the whole trial is the approach
    never = gp_mpc_metrics(_log(pos, contact_from=None), 2, PARAMS)
    assert never["approach_pullback_m"] == pytest.approx(0.002, rel=1e-6)
    assert never["pre_contact_dwell_s"] is None and never["damping_at_contact_Nspm"] is None


def test_a_slow_down_before_contact_is_a_pause_and_the_direction_matters() -> None:
    # 3 cm/s, then 0.4 s at 0.5 cm/s (below half the peak), then 3 cm/s into contact
    pos = _ramp((1.0, 0.03), (0.4, 0.005), (1.0, 0.03))
    out = gp_mpc_metrics(_log(pos, contact_from=1.6, damping=2000.0), 2, PARAMS)
    assert out["pre_contact_dwell_s"] == pytest.approx(0.4, abs=3 * DT)
    assert out["damping_at_contact_Nspm"] == pytest.approx(2000.0)
    # slowing to 60 % of the peak is not below half of it: no pause
    mild = _ramp((1.0, 0.03), (0.4, 0.018), (1.0, 0.03))
    assert gp_mpc_metrics(_log(mild, 1.6), 2, PARAMS)["pre_contact_dwell_s"] == pytest.approx(
        0.0, abs=2 * DT
    )
    # seen along -x the motion is a retreat all along: the pull-back is the whole path
    back = gp_mpc_metrics(_log(pos, 1.6), 2, {**PARAMS, "approach_dir": [-1.0, 0.0]})
    assert back["approach_pullback_m"] == pytest.approx(pos[1599], rel=1e-9)  # last before contact


def test_approach_metrics_are_off_without_a_direction_and_check_it() -> None:
    log = _log(_ramp((1.0, 0.03)), contact_from=0.5)
    assert "approach_pullback_m" not in gp_mpc_metrics(log, 2, {})
    for bad in ([1.0], [0.0, 0.0], 3.0, [1.0, float("nan")]):
        with pytest.raises(ConfigError, match="metrics.approach_dir"):
            gp_mpc_metrics(log, 2, {"approach_dir": bad})


RATIO = {
    "id": "r", "paper": "seed_b", "source": "Table 2", "statement": "x at 0.85 of y",
    "paper_value": "22.2 / 26.2", "experiment": "e", "compare": "ratio_within",
    "a": {"condition": "x", "metric": "mpc_rate_hz"},
    "b": {"condition": "y", "metric": "mpc_rate_hz"}, "value": 0.847, "tolerance": 0.25,
}  # fmt: skip


def _rates(a: float, b: float) -> dict:
    return {"experiment": "e", "status": "ok",
            "conditions": {"x": {"mpc_rate_hz": a}, "y": {"mpc_rate_hz": b}}}  # fmt: skip


def test_ratio_within_judges_a_ratio_against_the_papers() -> None:
    c = parse_claim(RATIO, "claims[0]")
    v = evaluate(c, [_rates(85.0, 100.0), _rates(90.0, 100.0), _rates(80.0, 100.0)])
    assert v.verdict == "reproduced" and v.mean == pytest.approx(0.85)
    assert "x.mpc_rate_hz = 85" in v.ours and "y.mpc_rate_hz = 100" in v.ours
    # too fast or too slow against the paper's ratio: not reproduced
    assert evaluate(c, [_rates(120.0, 100.0)] * 3).verdict == "not reproduced"
    assert evaluate(c, [_rates(50.0, 100.0)] * 3).verdict == "not reproduced"
    # at the edge of the band it holds (a bound); a zero denominator is not measured
    half = parse_claim({**RATIO, "value": 0.5}, "claims[0]")  # 0.625 = 0.5 x 1.25 exactly
    assert evaluate(half, [_rates(62.5, 100.0)] * 3).verdict == "reproduced"
    assert evaluate(half, [_rates(62.6, 100.0)] * 3).verdict == "not reproduced"
    assert evaluate(c, [_rates(50.0, 0.0)] * 3).verdict == "not measured"
    with pytest.raises(ConfigError, match="claims\\[0\\].tolerance"):
        parse_claim({**RATIO, "tolerance": None}, "claims[0]")
    with pytest.raises(ConfigError, match="claims\\[0\\].b"):
        parse_claim({**RATIO, "b": None}, "claims[0]")


def test_run_info_rates_join_the_summary_for_claims(tmp_path: Path) -> None:
    """A rate claim reads run_info.json's per-condition rates (one process per run)."""
    for seed, (a, b) in enumerate([(85.0, 100.0), (40.0, 100.0)]):
        run = tmp_path / str(seed)
        run.mkdir()
        summary = {"experiment": "e", "status": "ok", "seed": seed,
                   "conditions": {"x": {"m": 1.0}, "y": {"m": 1.0}}}  # fmt: skip
        (run / "summary.json").write_text(json.dumps(summary))
        info = {"mpc_rate_hz": {"x": a, "y": b, "gone": 1.0}, "mpc_iterations_median": {"x": 9}}
        (run / "run_info.json").write_text(json.dumps(info))
    runs = collect(tmp_path)
    assert runs[0][1]["conditions"]["x"] == {"m": 1.0, "mpc_rate_hz": 85.0,
                                             "mpc_iterations_median": 9}  # fmt: skip
    assert "gone" not in runs[0][1]["conditions"]  # a condition the summary lacks is not made
    v = evaluate(parse_claim(RATIO, "claims[0]"), [s for _, s in runs])
    assert v.n_seeds == 2 and v.mean == pytest.approx(0.625)
    # summary.json itself is untouched; no run_info.json: the summary as it is
    assert "mpc_rate_hz" not in json.loads((tmp_path / "0" / "summary.json").read_text())
    bare = {"conditions": {"x": {}}}
    assert with_run_info(tmp_path / "missing", bare) == {"conditions": {"x": {}}}


def test_latency_is_its_own_experiment_and_the_claims_say_which(composer) -> None:
    """mpc_contact has no force latency (seed B states none); mpc_contact_latency is the same
    experiment with ccm's 4 ms. Every B-6.1 claim judged with latency has a twin without."""
    from omegaconf import OmegaConf

    plain = composer(["experiment=mpc_contact"])
    late = composer(["experiment=mpc_contact_latency"])
    assert plain.controller.force_delay_s == 0.0 and late.controller.force_delay_s == 0.004
    a, b = OmegaConf.to_container(plain, resolve=True), OmegaConf.to_container(late, resolve=True)
    for cfg in (a, b):
        cfg["controller"].pop("force_delay_s")
        cfg["experiment"].pop("name")
        cfg["experiment"].pop("description")
    assert a == b  # nothing else differs
    assert {"mpc_contact", "mpc_contact_latency"} <= set(PAPER_EXPERIMENTS)
    claims = {c.id: c for c in load_claims(CLAIMS)}
    for cid, c in claims.items():
        if c.experiment == "mpc_contact_latency":
            twin = claims[f"{cid}-no-latency"]
            assert twin.experiment == "mpc_contact" and (twin.a, twin.b) == (c.a, c.b)
            assert twin.statement == c.statement and twin.compare == c.compare
