"""Oracle tests of seed B's trial metrics (``ccm.metrics.mpc.gp_mpc_metrics``; issue #39 item 1).

A synthetic 2-D log whose every quantity is known by construction: the first contact at
0.2 s with a 5 N force (3, 4) after 50 ms at 8 N, a 10 ms loss of contact at 0.5 s and a 3 ms
one at 0.7 s, a damping that depends on the distance to the human's shoulder, a belief that
reaches the true goal, and a tool that moves toward the human's goal. Each metric is checked
against the value its definition (the module docstring) gives.
"""

from __future__ import annotations

import numpy as np
import pytest

from ccm.metrics.mpc import gp_mpc_metrics

DT = 0.001
N = 1000


def _log() -> dict[str, np.ndarray]:
    t = np.arange(N) * DT
    touching = (t >= 0.2 - 1e-9).astype(float)
    touching[500:510] = 0.0  # a 10 ms loss (counted: >= 5 ms)
    touching[700:703] = 0.0  # a 3 ms one (not counted)
    fx, fy = np.zeros(N), np.zeros(N)
    fx[200:], fy[200:] = 3.0, 4.0  # |f| = 5 N from 0.2 s
    fx[200:250], fy[200:250] = 4.8, 6.4  # |f| = 8 N for the first 50 ms: out of the band
    far = t >= 0.6  # the tool is 1 m from the shoulder from 0.6 s, 0.2 m before
    pos_x = np.where(far, 1.0, 0.2)
    belief_1 = np.clip(0.5 + t, 0.0, 1.0)  # 0.9 at t = 0.4 s
    return {
        "t": t, "n_contacts": touching, "contact_force_x": fx, "contact_force_y": fy,
        "vel_x": np.zeros(N), "vel_y": np.zeros(N), "pos_x": pos_x, "pos_y": np.zeros(N),
        "damping_x_Nspm": np.where(far, 500.0, 100.0), "damping_y_Nspm": np.full(N, 150.0),
        "belief_0": 1.0 - belief_1, "belief_1": belief_1, "truth_human_goal": np.ones(N),
        "truth_human_goal_x_m": np.full(N, 2.0), "truth_human_goal_y_m": np.zeros(N),
        "f_ref_x_N": np.full(N, -3.0), "f_ref_y_N": np.full(N, 7.0),
    }  # fmt: skip


PARAMS = {
    "press_force_N": 5.0, "press_tol_N": 1.5, "press_hold_s": 0.1,
    "human_shoulder": [0.0, 0.0, 0.0], "far_from_human_m": 0.5,
    "varied_axis": "x", "repeatable_axis": "y", "belief_level": 0.9,
    "controller_report": {"mpc_solves": 7, "mpc_infeasible": 2, "disturbance_alpha": 1.5},
}  # fmt: skip


def test_seed_b_trial_metrics_give_their_definitions_values() -> None:
    m = gp_mpc_metrics(_log(), 2, PARAMS)
    assert m["peak_force_N"] == pytest.approx(8.0) and m["contact_made"] == 1.0
    assert m["first_contact_s"] == pytest.approx(0.2)
    assert m["contact_losses"] == 1.0  # 10 ms counts, 3 ms does not (contact_loss_min_s 5 ms)
    # the force first stays within 5 ± 1.5 N for press_hold_s from 0.25 s on
    assert m["press_settle_time_s"] == pytest.approx(0.25)
    assert (m["mpc_solves"], m["mpc_infeasible"], m["disturbance_alpha_N"]) == (7.0, 2.0, 1.5)
    assert m["rms_vel_low_mps"] == 0.0 and m["rms_vel_high_mps"] == 0.0
    assert m["mean_damping_x_Nspm"] == pytest.approx(0.4 * 500 + 0.6 * 100)
    assert m["mean_damping_y_Nspm"] == pytest.approx(150.0)
    # far from the human (>= 0.5 m): 40 % of the samples, damping (500 + 150) / 2 there
    assert m["far_from_human_frac"] == pytest.approx(0.4)
    assert m["mean_damping_far_Nspm"] == pytest.approx(325.0)
    assert m["damping_ratio_varied_repeatable"] == pytest.approx(260.0 / 150.0)
    assert m["belief_correct_final"] == 1.0 and m["time_to_belief_s"] == pytest.approx(0.4)
    # the goal (2, 0): 1.8 m away at the start, 1.0 m at the end; ĝ = (1, 0), −f_ref·ĝ = 3 N
    assert m["goal_approach_m"] == pytest.approx(0.8)
    assert m["f_ref_toward_goal_N"] == pytest.approx(3.0)


def test_without_contact_or_settling_the_contact_metrics_are_none() -> None:
    """No contact: None for the contact metrics (not 0); a force that never settles: None."""
    log = _log()
    log["n_contacts"] = np.zeros(N)
    m = gp_mpc_metrics(log, 2, PARAMS)
    assert m["contact_made"] == 0.0 and m["first_contact_s"] is None
    assert m["contact_losses"] is None and m["press_settle_time_s"] is None
    log = _log()
    log["contact_force_x"] = np.where(log["t"] >= 0.2, 9.0, 0.0)
    assert gp_mpc_metrics(log, 2, PARAMS)["press_settle_time_s"] is None
    near = _log()
    near["pos_x"] = np.full(N, 0.2)
    m = gp_mpc_metrics(near, 2, PARAMS)
    assert m["far_from_human_frac"] == 0.0 and m["mean_damping_far_Nspm"] is None


def _cos(f_hz: float, t: np.ndarray) -> np.ndarray:
    """A cosine sampled half a step late, so that its mirror image (``fft_split``'s even
    extension) is the same cosine: an exact FFT bin, split without leakage."""
    return np.cos(2 * np.pi * f_hz * (t + DT / 2))


def test_oscillation_and_velocity_bands_are_the_rms_of_their_parts() -> None:
    """force_oscillation_rms_N: the 20 Hz part of |f| after the first contact (amplitude 2 N,
    RMS √2 N; the 5 N mean is below 5 Hz); rms_vel_*: the parts of (vx, vy) below / above
    15 Hz over all axes: x = 0.3 + 0.2 cos(40 Hz), y = 0 gives 0.3 and 0.2/√2 m/s."""
    log = _log()
    t = log["t"]
    touch = t >= 0.2 - 1e-9
    log["n_contacts"] = touch.astype(float)
    log["contact_force_x"] = np.where(touch, 5.0 + 2.0 * _cos(20.0, t - 0.2), 0.0)
    log["contact_force_y"] = np.zeros(N)
    log["vel_x"] = 0.3 + 0.2 * _cos(40.0, t)
    m = gp_mpc_metrics(log, 2, {"oscillation_highpass_hz": 5.0, "vel_split_hz": 15.0})
    assert m["force_oscillation_rms_N"] == pytest.approx(np.sqrt(2.0), rel=1e-6)
    assert m["rms_vel_low_mps"] == pytest.approx(0.3, rel=1e-6)
    assert m["rms_vel_high_mps"] == pytest.approx(0.2 / np.sqrt(2.0), rel=1e-6)


def _approach_log() -> dict[str, np.ndarray]:
    """An approach along +x: 0.4 m/s, then the peak 1 m/s, a retreat at −0.3 m/s for 30 ms,
    5 ms at exactly half the peak, then 0.8 m/s to the first contact at 0.2 s; the tool
    drifts along y at 5 m/s throughout (not along the approach). The position is the
    velocity's running sum."""
    t = np.arange(N) * DT
    vx = np.select([t < 0.05, t < 0.1, t < 0.13, t < 0.135, t < 0.2], [0.4, 1.0, -0.3, 0.5, 0.8])
    vx = np.where(t < 0.2 - 1e-9, vx, 0.0)
    vy = np.full(N, 5.0)
    return {
        "t": t, "n_contacts": (t >= 0.2 - 1e-9).astype(float),
        "contact_force_x": np.zeros(N), "contact_force_y": np.zeros(N),
        "vel_x": vx, "vel_y": vy, "pos_x": np.cumsum(vx) * DT, "pos_y": np.cumsum(vy) * DT,
        "damping_x_Nspm": np.where(t >= 0.2 - 1e-9, 100.0, 1.0),
        "damping_y_Nspm": np.where(t >= 0.2 - 1e-9, 200.0, 2.0),
    }  # fmt: skip


def test_approach_metrics_give_their_definitions_values() -> None:
    """Pullback: the 30 ms retreat at 0.3 m/s, 9 mm (the y drift is not along dir = (1, 0),
    given unnormalised as (2, 0)). Dwell: the steps from the peak to contact with v_a below
    half the peak: the 30 ms retreat, not the 5 ms at exactly half. Damping at contact: D at
    the first touching step along dir."""
    params = {"approach_dir": [2.0, 0.0], "pause_speed_frac": 0.5}
    m = gp_mpc_metrics(_approach_log(), 2, params)
    assert m["approach_pullback_m"] == pytest.approx(0.009, abs=1e-9)
    assert m["pre_contact_dwell_s"] == pytest.approx(0.030, abs=1e-9)
    assert m["damping_at_contact_Nspm"] == pytest.approx(100.0)
    # along (3, 4)/5: dᵀ diag(D) d = 0.36 · 100 + 0.64 · 200
    diag = gp_mpc_metrics(_approach_log(), 2, {**params, "approach_dir": [3.0, 4.0]})
    assert diag["damping_at_contact_Nspm"] == pytest.approx(164.0)


def test_a_slower_pause_threshold_counts_fewer_steps_and_no_contact_gives_none() -> None:
    params = {"approach_dir": [1.0, 0.0], "pause_speed_frac": 0.6}  # 0.5 m/s now counts
    assert gp_mpc_metrics(_approach_log(), 2, params)["pre_contact_dwell_s"] == pytest.approx(
        0.035, abs=1e-9
    )
    log = _approach_log()
    log["n_contacts"] = np.zeros(N)  # never touches: the whole trial is the approach
    m = gp_mpc_metrics(log, 2, params)
    assert m["pre_contact_dwell_s"] is None and m["damping_at_contact_Nspm"] is None
    assert m["approach_pullback_m"] == pytest.approx(0.009, abs=1e-9)


def test_sigma_f_is_the_mean_and_max_over_the_solves_only() -> None:
    """NaN before the first solve does not count; no solve at all gives None."""
    log = _log()
    log["sigma_f_x_N2"] = np.full(N, np.nan)
    log["sigma_f_x_N2"][10:13] = [1.0, 3.0, 2.0]
    log["sigma_f_y_N2"] = np.full(N, np.nan)
    m = gp_mpc_metrics(log, 2, {})
    assert (m["mean_sigma_f_x_N2"], m["max_sigma_f_x_N2"]) == (2.0, 3.0)
    assert m["mean_sigma_f_y_N2"] is None and m["max_sigma_f_y_N2"] is None
    assert "mean_sigma_f_x_N2" not in gp_mpc_metrics(_log(), 2, {})


#: rail distances d (the rail at x = 0, outward normal +x, no tool extent: d = x) and the
#: damping along x and y at each: far (d > 0.2), the far boundary, between, the near boundary
#: (d <= 0.05, inclusive), near, and in contact (d < 0)
_RAIL = [  # (d [m], steps, D_x, D_y)
    (0.5, 100, 100.0, 50.0), (0.2, 10, 200.0, 80.0), (0.1, 50, 200.0, 80.0),
    (0.05, 10, 350.0, 400.0), (0.0, 10, 300.0, 400.0), (-0.002, 20, 300.0, 400.0),
]  # fmt: skip
_RAIL_PARAMS = {
    "rail_point": [0.0, 0.0], "rail_normal": [3.0, 0.0], "tool_half_extent_m": 0.0,
    "rail_contact_force_N": 2.0, "near_rail_m": 0.05, "far_rail_m": 0.2,
    "varied_axis": "x", "repeatable_axis": "y",
}  # fmt: skip


def _rail_log() -> dict[str, np.ndarray]:
    d, dx, dy = (np.repeat([r[i] for r in _RAIL], [r[1] for r in _RAIL]) for i in (0, 2, 3))
    n = len(d)
    touching = (d < 0).astype(float)
    fx = np.where(d < 0, 1.0, 0.0)
    fx[-15:] = 2.0  # the rail's push reaches 2 N (the threshold, inclusive) at step n − 15
    fx[5] = 9.0  # a push with no contact (n_contacts = 0) is no arrival
    return {
        "t": np.arange(n) * 0.01, "pos_x": d, "pos_y": np.zeros(n), "n_contacts": touching,
        "contact_force_x": fx, "contact_force_y": np.zeros(n),
        "vel_x": np.zeros(n), "vel_y": np.zeros(n), "damping_x_Nspm": dx, "damping_y_Nspm": dy,
    }  # fmt: skip


def test_rail_metrics_give_their_definitions_values() -> None:
    log = _rail_log()
    m = gp_mpc_metrics(log, 2, _RAIL_PARAMS)
    n = len(log["t"])
    assert m["task_success"] == 1.0
    assert m["time_to_rail_s"] == pytest.approx((n - 15) * 0.01)
    assert m["min_rail_distance_m"] == pytest.approx(-0.002)
    near_x = (10 * 350.0 + 30 * 300.0) / 40
    assert m["near_damping_x_Nspm"] == pytest.approx(near_x)
    assert m["near_damping_y_Nspm"] == pytest.approx(400.0)
    assert m["far_damping_x_Nspm"] == pytest.approx(100.0)  # d = 0.2 is not far (d > 0.2)
    assert m["far_damping_y_Nspm"] == pytest.approx(50.0)
    assert m["near_damping_ratio_varied_repeatable"] == pytest.approx(near_x / 400.0)
    assert m["damping_rise_repeatable_over_varied"] == pytest.approx((400 / 50) / (near_x / 100))


def test_rail_distance_subtracts_the_point_and_the_tool_extent() -> None:
    """d = (x − p)·n − h: the rail at x = 0.1 and a 10 mm half extent move every d by −0.11."""
    params = {**_RAIL_PARAMS, "rail_point": [0.1, 0.0], "tool_half_extent_m": 0.01}
    m = gp_mpc_metrics(_rail_log(), 2, params)
    assert m["min_rail_distance_m"] == pytest.approx(-0.112)
    log = _rail_log()
    log["contact_force_x"][:] = 1.9  # never pushes with 2 N: no success, no time
    m = gp_mpc_metrics(log, 2, _RAIL_PARAMS)
    assert m["task_success"] == 0.0 and m["time_to_rail_s"] is None


def test_far_from_human_is_measured_from_the_shoulder() -> None:
    """The shoulder at x = −0.5 m: the tool at x = 0.2 is 0.7 m from it and at 1.0 is 1.5 m,
    so every sample is far (≥ 0.5 m); measured from the origin only 40 % would be."""
    m = gp_mpc_metrics(_log(), 2, {**PARAMS, "human_shoulder": [-0.5, 0.0, 0.0]})
    assert m["far_from_human_frac"] == 1.0
    assert m["mean_damping_far_Nspm"] == pytest.approx((0.4 * 500 + 0.6 * 100 + 150.0) / 2)
